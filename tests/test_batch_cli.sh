#!/usr/bin/env bash
# CLI test for `sylva batch`: a manifest of the bundled airborne samples plus
# a bad and a truncated file. Every tree gets its glb (valid glTF), .sylva,
# record, thumbnail (or a placeholder saying why) and metrics; failures are
# recorded with their error and never stop the batch; index.json, trees.csv
# and report.html agree; the report opens from file:// in headless Chromium
# with no error and its three.js preview draws each tree. Resume: a rerun
# keeps everything, a changed input is redone alone; a batch killed at random
# moments and resumed ends byte-identical to an uninterrupted run (the bench
# does 20 kills); a worker killed by SIGSEGV fails its tree only. Voting: with
# --ratio set so that one tree is confident, its neighbours take its vote.
set -u
source "$SYLVA_SOURCE_DIR/tests/glb_cli_common.sh"
src=$SYLVA_SOURCE_DIR
command -v jq > /dev/null || { echo "FAIL: jq missing (run scripts/install-deps.sh)"; exit 1; }
export SYLVA_VIEW=${SYLVA_BUILD_DIR:-}/sylva-view
[[ -x $SYLVA_VIEW ]] || unset SYLVA_VIEW

# Usage and bad input.
"$SYLVA" batch "$src/samples/aspen_als.las" 2> /dev/null; check "no -o is a usage error" "[[ $? == 1 ]]"
"$SYLVA" batch "$tmp/none.las" -o "$tmp/x" 2> "$tmp/err"; rc=$?
check "a missing input exits 2 naming it" "[[ $rc == 2 ]] && grep -q none.las '$tmp/err'"
printf 'file,species\n' > "$tmp/empty.csv"
printf 'path,x\nfoo.las,1\n' > "$tmp/halfpos.csv"
"$SYLVA" batch "$tmp/halfpos.csv" -o "$tmp/x" 2> "$tmp/err"; rc=$?
check "a manifest with x but no y exits 2 naming it" "[[ $rc == 2 ]] && grep -q 'halfpos.csv:1' '$tmp/err'"
check "nothing written for bad input" "[[ ! -e $tmp/x ]]"

# The batch: three samples (one with a species hint, one placed by the manifest), a bad file, a truncated LAS.
mkdir -p "$tmp/in"
cp "$src"/samples/{aspen,fir,palm}_als.las "$tmp/in/"
echo "not a scan" > "$tmp/in/bad.las"
head -c 2000 "$src/samples/fir_als.las" > "$tmp/in/cut.las"
cat > "$tmp/in/manifest.csv" << 'EOF'
# file, species hint, position, label
file,species,x,y,z,label
aspen_als.las,,,,,
fir_als.las,,10,4,0,balsam_fir
palm_als.las,palm,,,,
bad.las,,,,,
cut.las,,,,,
EOF
out=$tmp/out
"$SYLVA" batch "$tmp/in/manifest.csv" -o "$out" --workers 2 --json > "$tmp/events.jsonl" 2> "$tmp/batch.err"; rc=$?
check "the batch exits 0 with failures recorded ($(tail -1 "$tmp/batch.err"))" "[[ $rc == 0 ]]"
check "--json: inspections, a start, one event per tree, a done" \
    "[[ \$(jq -s '[.[] | select(.event != \"inspected\")] | [.[0].event, ([.[] | select(.event == \"tree\")] | length), .[-1].event, .[-1].failed] | join(\",\")' -r '$tmp/events.jsonl') == start,5,done,2 ]]"
idx=$out/index.json
check "index.json: 5 trees, 3 ok, 2 failed" "jq -e '.counts == {trees: 5, ok: 3, failed: 2, pending: 0}' '$idx' > /dev/null"
check "each failure carries its error" \
    "jq -e '[.failures[] | select(.error | test(\"bad.las|cut.las\"))] | length == 2' '$idx' > /dev/null"
for t in aspen_als fir_als palm_als; do
    check "$t: glb, sylva and record" "[[ -s $out/trees/$t.glb && -s $out/trees/$t.sylva && -s $out/trees/$t.json ]]"
    check "$t: metrics (DBH, height, crown, volume) and scores" \
        "jq -e '.metrics.height > 0.5 and .metrics.crown_width > 0.5 and .metrics.volume > 0 and (.eval.iou_mean | . > 0 and . <= 1) and .eval.coverage >= 0' '$out/trees/$t.json' > /dev/null"
    check "$t: a thumbnail or the reason there is none" \
        "[[ -s $out/trees/$t.png ]] || jq -e '.thumbnail_error | length > 10' '$out/trees/$t.json' > /dev/null"
done
node "$validator" "$out"/trees/*.glb > "$tmp/v.txt" 2>&1
check "the batch's glbs validate (glTF validator: no errors or warnings)" "[[ $? == 0 ]]"
check "aspen and fir measure as trees (height > 2 m, DBH 1-200 cm: sparse airborne samples)" \
    "jq -s -e 'all(.[]; .metrics.height > 2 and .metrics.dbh > 0.01 and .metrics.dbh < 2)' '$out/trees/aspen_als.json' '$out/trees/fir_als.json' > /dev/null"
check "the manifest's species hint is used" "jq -e '.classification.species == \"palm\" and .classification.source == \"manifest\"' '$out/trees/palm_als.json' > /dev/null"
check "the manifest's position and label" "jq -e '.position == [10,4,0] and .position_source == \"manifest\" and .label == \"balsam_fir\"' '$out/trees/fir_als.json' > /dev/null"
check "LAS coordinates place the others" "jq -e '.position_source == \"las\"' '$out/trees/aspen_als.json' > /dev/null"
check "trees.csv: header and one row per tree" "[[ \$(wc -l < '$out/trees.csv') == 6 ]] && head -1 '$out/trees.csv' | grep -q '^tree_id,x,y,z,species,probability,confident,voted,dbh_cm,height_m,crown_width_m,volume_m3'"
check "trees.csv: the failed rows say failed" "[[ \$(grep -c ',failed,' '$out/trees.csv') == 2 ]]"
check "the labels give a confusion matrix" "jq -e '.confusion.labels | length >= 1' '$idx' > /dev/null"
check "no temp file survives" "[[ -z \$(find '$out' -name '.tmp.*') ]]"

# The report in headless Chromium, opened from file://.
node --experimental-websocket "$src/tests/three/report_check.mjs" "$out/report.html" > "$tmp/report.json" 2> "$tmp/report.err"
check "report.html loads with no error ($(head -c 300 "$tmp/report.err"))" \
    "jq -e '.ready and (.errors | length) == 0 and (.sections | index(\"failures\")) and (.sections | index(\"confusion\")) and (.sections | index(\"timings\"))' '$tmp/report.json' > /dev/null"
check "every tree card shows its thumbnail or a placeholder ($(jq -c '[.thumbnails, .placeholders, .broken]' "$tmp/report.json"))" \
    "jq -e '.thumbnails + .placeholders == 5 and .broken == 0' '$tmp/report.json' > /dev/null"
check "the three.js preview draws each tree ($(jq -c '[.trees[] | .coverage]' "$tmp/report.json"))" \
    "jq -e '(.trees | length) == 3 and all(.trees[]; (.errors | length) == 0 and .triangles > 100 and .coverage > 0.01)' '$tmp/report.json' > /dev/null"

# Resume: nothing changed, nothing redone; a changed input is redone alone.
( cd "$out" && find trees -type f ! -name '*.log' | sort | xargs sha1sum ) > "$tmp/sums1"
"$SYLVA" batch "$tmp/in/manifest.csv" -o "$out" --json > "$tmp/events2.jsonl" 2> /dev/null
check "a rerun keeps every tree (failures too)" "jq -s -e '.[-1].kept == 5 and .[-1].made == 0' '$tmp/events2.jsonl' > /dev/null"
( cd "$out" && find trees -type f ! -name '*.log' | sort | xargs sha1sum ) > "$tmp/sums2"
check "a rerun changes no tree's files" "cmp -s '$tmp/sums1' '$tmp/sums2'"
cp "$src/samples/palm_als.las" "$tmp/in/bad.las"
"$SYLVA" batch "$tmp/in/manifest.csv" -o "$out" --json > "$tmp/events3.jsonl" 2> /dev/null
check "a changed input is redone alone" \
    "jq -s -e '.[-1].made == 1 and .[-1].kept == 4 and ([.[] | select(.event == \"tree\" and has(\"seconds\")) | .id] == [\"bad\"])' '$tmp/events3.jsonl' > /dev/null"
check "the redone tree is ok now" "jq -e '.status == \"ok\"' '$out/trees/bad.json' > /dev/null"

# Voting: with --ratio between the best and second-best confidence, one tree is confident and its neighbours vote.
cat > "$tmp/in/placed.json" << 'EOF'
[{"file": "aspen_als.las", "position": [0, 0, 0]}, {"file": "fir_als.las", "position": [5, 0, 0]},
 {"file": "bad.las", "position": [0, 5, 0]}]
EOF
"$SYLVA" batch "$tmp/in/placed.json" -o "$tmp/vote" --no-thumbnails --no-eval --quiet
r=$(jq -s '[.[] | .classification.probabilities | sort | reverse | .[0] / .[1]] | sort | reverse | (.[0] + .[1]) / 2' "$tmp"/vote/trees/*.json)
"$SYLVA" batch "$tmp/in/placed.json" -o "$tmp/vote" --no-thumbnails --no-eval --quiet --collect --ratio "$r"
check "spatial voting: one tree confident, the other two voted to its species (ratio $r)" \
    "jq -e '([.trees[] | select(.species_source == \"classifier\" and .confident)] | length) == 1 and ([.trees[] | select(.species_source == \"voted\")] | length) == 2 and ([.trees[].species] | unique | length) == 1' '$tmp/vote/index.json' > /dev/null"
check "trees.csv marks the voted trees" "[[ \$(awk -F, 'NR > 1 && \$8 == 1' '$tmp/vote/trees.csv' | wc -l) == 2 ]]"

# A species the scan's structure rules out (run_tree.c rule_out_by_crown_base)
# stays out of the report, which decides again from the probabilities:
# rTwig's leaf-off sapling, which the classifier calls a palm.
cloud=$SYLVA_DATA_DIR/real/rtwig/cloud.txt
if [[ -f $cloud ]]; then
  "$SYLVA" batch "$cloud" -o "$tmp/rule" --no-thumbnails --no-eval --quiet
  check "a ruled-out palm is not the batch's species (record, index.json, trees.csv)" \
      "jq -e '.classification.ruled_out == \"palm\" and .classification.species != \"palm\"' '$tmp'/rule/trees/*.json > /dev/null && jq -e '.trees[0].species != \"palm\"' '$tmp/rule/index.json' > /dev/null && ! grep -q ',palm,' '$tmp/rule/trees.csv'"
else
  echo "FAIL: $cloud missing"; fail=1
fi

# Kills at random moments, then a resume: the same bytes as an uninterrupted run.
mkdir -p "$tmp/kin"
cp "$src"/samples/{palm,fir}_als.las "$tmp/kin/"
# Every build runs this, sanitizer builds too: there the kills land in other
# phases, which is how a resume that started while the killed workers were
# still unreaped (kill(pid, 0) still finds a zombie) came to keep their temps.
opts=(--workers 2 --no-eval --quiet)
"$SYLVA" batch "$tmp/kin" -o "$tmp/ref" "${opts[@]}"
RANDOM=7
moments=()
for k in 1 2 3; do
    ms=$((200 + RANDOM % 2500))
    moments+=("$ms")
    "$SYLVA" batch "$tmp/kin" -o "$tmp/killed" "${opts[@]}" &
    pid=$!
    sleep "$(awk -v m="$ms" 'BEGIN { print m / 1000 }')"
    kill -9 "$pid" 2> /dev/null
    wait "$pid" 2> /dev/null
done
# Workers and their viewers die with the batch (PDEATHSIG). The resume
# starts at once, while they may still be exiting or unreaped.
"$SYLVA" batch "$tmp/kin" -o "$tmp/killed" "${opts[@]}"
same() { # the outputs minus timings
    ( cd "$1" && for f in $(find trees -type f \( -name '*.glb' -o -name '*.sylva' -o -name '*.png' -o -name '*.glb.js' \) | sort); do sha1sum "$f"; done
      for f in trees/*.json; do echo "$f"; jq -S 'del(.seconds, .peak_rss_kb)' "$f"; done
      jq -S 'del(.trees[].seconds)' index.json; cat trees.csv; sed 's/[0-9.]* s\b//g' report.html | sha1sum )
}
check "killed at ${moments[*]} ms and resumed: outputs identical to an uninterrupted run" \
    "diff <(same '$tmp/ref') <(same '$tmp/killed') > '$tmp/kill.diff'"
check "no temp file survives the kills" "[[ -z \$(find '$tmp/killed' -name '.tmp.*') ]]"

# A plot is segmented first (once) and its trees go through, placed at their stems.
"$SYLVA" batch "$src/samples/plot_tls.las" "$src/samples/palm_als.las" -o "$tmp/plot" --workers 2 --no-eval --no-thumbnails --quiet
check "the plot becomes its trees, the single tree stays one" \
    "jq -e '(.plots | length) == 1 and .plots[0].trees >= 3 and .counts.ok == .plots[0].trees + 1 and ([.trees[] | select(.id | startswith(\"plot_tls_t\"))] | length) == .plots[0].trees' '$tmp/plot/index.json' > /dev/null"
check "plot trees are placed at their stems" \
    "jq -s -e 'all(.[]; .position_source == \"stem\" and (.position | length) == 3)' '$tmp'/plot/trees/plot_tls_t*.json > /dev/null"
"$SYLVA" batch "$src/samples/plot_tls.las" "$src/samples/palm_als.las" -o "$tmp/plot" --workers 2 --no-eval --no-thumbnails --json > "$tmp/plot2.jsonl"
check "a rerun segments nothing and keeps every tree" \
    "jq -s -e '([.[] | select(.event == \"inspected\")] | length) == 0 and .[-1].made == 0' '$tmp/plot2.jsonl' > /dev/null"

# catch_worker BATCH_PID: stops one of the batch's tree workers and sets w to
# it. The batch first forks a short child per input that checks whether it
# is a plot (its stderr goes to logs/ID.segment.log); the target is a tree
# worker (stderr to logs/ID.log). It is stopped first and seen stopped
# (state T) before the caller's signal: one that was already finishing (a
# zombie) cannot be stopped, and the next is taken instead. A loaded machine
# may take a while.
catch_worker() {
    w=
    for i in $(seq 1200); do
        for c in $(pgrep -P "$1"); do
            log=$(readlink "/proc/$c/fd/2" 2> /dev/null)
            [[ $log == */logs/*.log && $log != *.segment.log ]] || continue
            kill -STOP "$c" 2> /dev/null || continue
            sleep 0.05
            if [[ $(sed 's/.*) //' "/proc/$c/stat" 2> /dev/null | cut -d' ' -f1) == T ]]; then w=$c; return; fi
            kill -CONT "$c" 2> /dev/null
        done
        sleep 0.05
    done
}

# A worker that crashes fails its tree only. (Sanitizer builds would turn the
# signal into their own report and exit 1: let it through as a crash.)
ASAN_OPTIONS=${ASAN_OPTIONS:+$ASAN_OPTIONS:}handle_segv=0 UBSAN_OPTIONS=${UBSAN_OPTIONS:+$UBSAN_OPTIONS:}handle_segv=0 \
"$SYLVA" batch "$tmp/kin" -o "$tmp/crash" --workers 1 --no-eval --no-thumbnails --quiet &
pid=$!
catch_worker "$pid"
[[ -n $w ]] && kill -SEGV "$w" && kill -CONT "$w"
wait "$pid"; rc=$?
check "a worker was caught and sent SIGSEGV" "[[ -n '$w' ]]"
check "the batch survives a worker's SIGSEGV (exit $rc)" "[[ $rc == 0 ]]"
check "the crashed tree is recorded with the signal, the other made" \
    "jq -e '.counts.ok == 1 and .counts.failed == 1 and (.failures[0].error | test(\"segmentation fault\"))' '$tmp/crash/index.json' > /dev/null"
"$SYLVA" batch "$tmp/kin" -o "$tmp/crash" --workers 1 --no-eval --no-thumbnails --quiet --retry-failed
check "--retry-failed redoes it" "jq -e '.counts.ok == 2' '$tmp/crash/index.json' > /dev/null"

# A stop is not a failure. Ctrl-C and scancel signal the batch and its
# workers alike, in either order: a worker ended by SIGTERM (here alone, as
# when it is signalled first) leaves its tree unrecorded, to be made by the
# next run, and the batch goes on.
"$SYLVA" batch "$tmp/kin" -o "$tmp/stop" "${opts[@]}" --workers 1 --json > "$tmp/stop.jsonl" &
pid=$!
catch_worker "$pid"
stopped=$(readlink "/proc/$w/fd/2" 2> /dev/null | sed 's,.*/,,; s,\.log$,,')
[[ -n $w ]] && kill -TERM "$w" && kill -CONT "$w"
wait "$pid"; rc=$?
check "a worker was caught and sent SIGTERM ($stopped)" "[[ -n '$w' && -n '$stopped' ]]"
check "the batch goes on (exit $rc): the other tree made, the stopped one pending and unrecorded" \
    "[[ $rc == 0 && ! -e '$tmp/stop/trees/$stopped.json' ]] && jq -e '.counts.ok == 1 and .counts.failed == 0 and .counts.pending == 1' '$tmp/stop/index.json' > /dev/null && jq -s -e '.[-1].interrupted == 1 and .[-1].failed == 0' '$tmp/stop.jsonl' > /dev/null"
# SIGTERM to the batch while a worker runs: passed on to it, the batch dies
# of it once the worker is reaped, and nothing is recorded as failed.
rm -rf "$tmp/stop"
"$SYLVA" batch "$tmp/kin" -o "$tmp/stop" "${opts[@]}" --workers 1 &
pid=$!
catch_worker "$pid"
[[ -n $w ]] && kill -TERM "$pid" && sleep 0.2
check "SIGTERM to the batch: it waits for its (stopped) worker before it dies" "kill -0 '$pid' 2> /dev/null"
[[ -n $w ]] && kill -CONT "$w"
wait "$pid"; rc=$?
check "SIGTERM to the batch: it dies of it (exit $rc), no failure recorded, no report" \
    "[[ -n '$w' && $rc == 143 && ! -e '$tmp/stop/index.json' ]] && ! grep -ls '\"failed\"' '$tmp'/stop/trees/*.json > /dev/null"
check "... and its worker is gone with it" "! kill -0 '$w' 2> /dev/null"
"$SYLVA" batch "$tmp/kin" -o "$tmp/stop" "${opts[@]}"
check "the same command again finishes it: outputs identical to an uninterrupted run" \
    "diff <(same '$tmp/ref') <(same '$tmp/stop') > '$tmp/stop.diff'"
# Under nohup (SIGHUP ignored) a hang-up leaves the batch running: Linux
# queues a blocked signal even when it is ignored, so the pool leaves ignored
# ones out of what it waits for.
rm -rf "$tmp/stop"
nohup "$SYLVA" batch "$tmp/kin" -o "$tmp/stop" "${opts[@]}" --workers 1 > /dev/null 2>&1 &
pid=$!
catch_worker "$pid"
[[ -n $w ]] && kill -HUP "$pid" && sleep 0.2 && kill -CONT "$w"
wait "$pid"; rc=$?
check "under nohup a SIGHUP does not stop the batch (exit $rc, every tree made)" \
    "[[ -n '$w' && $rc == 0 ]] && jq -e '.counts.ok == 2' '$tmp/stop/index.json' > /dev/null"
exit $fail
