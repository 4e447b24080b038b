#!/usr/bin/env bash
# `sylva batch --slurm` on a real Slurm: Debian's slurm-wlm and munge
# (scripts/install-deps.sh) started here as a single-node cluster on loopback
# (munged, slurmctld, slurmd in a temporary folder, their own ports and
# socket). A small batch submitted as a job array must end with outputs
# byte-identical to a local run's (timings aside); then an array task is
# cancelled midway (scancel) and a resubmission of the same command
# completes the batch with nothing lost. Where Slurm cannot start (no
# packages, not root, daemons refusing) the test says why and exits 77
# (ctest: skipped), never silently.
set -u
source "$SYLVA_SOURCE_DIR/tests/glb_cli_common.sh"
src=$SYLVA_SOURCE_DIR
skip() { echo "SKIP: Slurm cannot start here: $*"; exit 77; }
for exe in munged slurmctld slurmd sbatch squeue sinfo scancel; do
    command -v "$exe" > /dev/null || skip "$exe is not installed (scripts/install-deps.sh installs slurm-wlm and munge)"
done
[[ $(id -u) == 0 ]] || skip "slurmd must run as root to start jobs as their user, and this test is not root"
command -v jq > /dev/null || { echo "FAIL: jq missing"; exit 1; }
export SYLVA_VIEW=${SYLVA_BUILD_DIR:-}/sylva-view
[[ -x $SYLVA_VIEW ]] || unset SYLVA_VIEW

d=$tmp/slurm
mkdir -p "$d/state" "$d/spool"
chmod 700 "$tmp" "$d"
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2> /dev/null; done
    for p in "${pids[@]}"; do wait "$p" 2> /dev/null; done
    [[ -n ${KEEP:-} ]] && echo "kept $tmp" || rm -rf "$tmp"
}
trap cleanup EXIT
head -c 1024 /dev/urandom > "$d/munge.key"
chmod 400 "$d/munge.key"
munged --key-file="$d/munge.key" --socket="$d/munge.sock" --pid-file="$d/munged.pid" --log-file="$d/munged.log" \
    --seed-file="$d/munge.seed" --force --foreground 2> "$d/munged.err" &
pids+=($!)
for i in $(seq 50); do [[ -S $d/munge.sock ]] && break; sleep 0.1; done
[[ -S $d/munge.sock ]] || skip "munged did not start: $(tail -2 "$d/munged.err" "$d/munged.log" 2> /dev/null | tr '\n' ' ')"
host=$(hostname -s)
port=$((20000 + $$ % 20000))
cat > "$d/slurm.conf" << EOF
ClusterName=sylvatest
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
AuthType=auth/munge
AuthInfo=socket=$d/munge.sock
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$d/state
SlurmdSpoolDir=$d/spool
SlurmctldPidFile=$d/slurmctld.pid
SlurmdPidFile=$d/slurmd.pid
SlurmctldLogFile=$d/slurmctld.log
SlurmdLogFile=$d/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/builtin
ReturnToService=2
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
NodeName=localhost NodeHostname=$host NodeAddr=127.0.0.1 CPUs=2 RealMemory=1000 State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP OverSubscribe=YES
EOF
export SLURM_CONF=$d/slurm.conf
slurmctld -D -c -f "$SLURM_CONF" 2> "$d/slurmctld.err" &
pids+=($!)
slurmd -D -N localhost -f "$SLURM_CONF" 2> "$d/slurmd.err" &
pids+=($!)
up=0
for i in $(seq 150); do
    [[ $(sinfo -h -o %T 2> /dev/null) == idle* ]] && { up=1; break; }
    sleep 0.2
done
[[ $up == 1 ]] || skip "the single-node cluster did not come up: $(tail -3 "$d/slurmctld.log" "$d/slurmd.log" "$d/slurmctld.err" "$d/slurmd.err" 2> /dev/null | tr '\n' ' ' | cut -c1-600)"
echo "ok: slurmctld and slurmd up on 127.0.0.1:$port ($(sinfo -V))"

# wait_job ID SECONDS: until the array has left the queue.
wait_job() {
    for i in $(seq $(($2 * 5))); do
        [[ -z $(squeue -h -j "$1" 2> /dev/null) ]] && return 0
        sleep 0.2
    done
    return 1
}
mkdir -p "$tmp/in"
cp "$src"/samples/{aspen,fir,palm}_als.las "$tmp/in/"
opts=(--no-eval --quiet)
cd "$tmp"
"$SYLVA" batch in -o local --workers 2 "${opts[@]}"
same() { # the outputs minus timings
    ( cd "$1" && for f in $(find trees -type f \( -name '*.glb' -o -name '*.sylva' -o -name '*.png' -o -name '*.glb.js' \) | sort); do sha1sum "$f"; done
      for f in trees/*.json; do echo "$f"; jq -S 'del(.seconds, .peak_rss_kb)' "$f"; done
      jq -S 'del(.trees[].seconds)' index.json; cat trees.csv; sed 's/[0-9.]* s\b//g' report.html | sha1sum )
}

# The array: 3 trees over 2 tasks; the last task merges the report.
"$SYLVA" batch in -o out --slurm --array-size 2 --time 00:10:00 --json "${opts[@]}" > sub.json 2> sub.err
job=$(jq -r .job sub.json 2> /dev/null)
check "sbatch took the job array ($job; $(tail -1 sub.err))" "[[ $job =~ ^[0-9]+$ ]]"
check "the job script names the array and the options" \
    "grep -q '^#SBATCH --array=0-1' out/slurm/batch.sbatch && grep -q '^#SBATCH --time=00:10:00' out/slurm/batch.sbatch && grep -q -- \"--slurm-tasks 2\" out/slurm/batch.sbatch"
wait_job "$job" 240 || echo "FAIL: the array did not finish in 240 s: $(squeue -h)"
check "the last task merged the report" "[[ -s out/index.json && -s out/report.html && -s out/trees.csv ]]"
check "every tree made on Slurm" "jq -e '.counts.ok == 3' out/index.json > /dev/null"
check "Slurm outputs byte-identical to the local run's (timings aside)" "diff <(same local) <(same out) > slurm.diff"
[[ -s slurm.diff ]] && head -20 slurm.diff

# Cancel a task midway (after its first tree), then resubmit: nothing lost.
# Task 0 makes aspen_als, then palm_als (0.3 s). So that the cancel lands
# between the two on any machine, task 0's batch is held (SIGSTOP) once its
# first tree's worker runs (stderr to logs/aspen_als.log): the worker
# finishes its tree, the held batch cannot start the next. scancel sends
# SIGCONT and SIGTERM; the batch takes the SIGTERM before it reaps.
"$SYLVA" batch in -o out2 --slurm --array-size 2 --json "${opts[@]}" > sub2.json 2> sub2.err
job=$(jq -r .job sub2.json)
held=
for i in $(seq 1200); do
    b=$(pgrep -o -f -- "--slurm-task 0 --slurm-tasks 2")
    for c in $(pgrep -P "${b:-0}"); do
        [[ $(readlink "/proc/$c/fd/2" 2> /dev/null) == */logs/aspen_als.log ]] && kill -STOP "$b" && held=$b && break 2
    done
    sleep 0.1
done
check "task 0's batch held while its first tree's worker runs" "[[ -n '$held' ]]"
for i in $(seq 600); do [[ -s out2/trees/aspen_als.json ]] && break; sleep 0.2; done
scancel "${job}_0"
wait_job "$job" 120
check "task 0 was cancelled midway: its second tree is missing, no report yet" \
    "[[ -s out2/trees/aspen_als.json && ! -e out2/trees/palm_als.json && ! -e out2/index.json ]]"
kept=$(sha1sum < out2/trees/aspen_als.json)
"$SYLVA" batch in -o out2 --slurm --array-size 2 --json "${opts[@]}" > sub3.json 2> sub3.err
job=$(jq -r .job sub3.json)
wait_job "$job" 240 || echo "FAIL: the resubmission did not finish in 240 s"
check "the resubmission completes the batch with nothing lost" "jq -e '.counts.ok == 3' out2/index.json > /dev/null"
check "... byte-identical to the local run's" "diff <(same local) <(same out2) > slurm2.diff"
check "the resubmission kept the tree finished before the cancel (its record untouched)" "[[ \$(sha1sum < out2/trees/aspen_als.json) == '$kept' ]]"
exit $fail
