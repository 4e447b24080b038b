#!/usr/bin/env bash
# Scale bench (docs/skeleton.md, "Dense scans"): every target of "any scan,
# any size" measured in one run and printed side by side at the end, with
# the load average. CPU time (user + sys of the whole process) throughout:
# the machine is shared.
#
#   bench/scale/run.sh SYLVA [ADTREE] [SCANS_DIR]
#
# ADTREE: an AdTree binary built outside this repository (tudelft3d/AdTree;
# its batch mode `AdTree IN.xyz OUT_DIR`), compared file by file on AdTree's
# own data, alternating runs. SCANS_DIR: where the simulated scans are kept
# between runs (oak100k.las ... and SPECIES_N.las, made with `sylva scan`
# when absent: minutes).
#
# Environment: REPS (AdTree comparison, default 3); SPECIES (default: every
# species of the library); SIZES (species sweep sizes, default "100k"; the
# whole target is SIZES="100k 300k 1m 3m", hours on 2 cores); SKIP_* = 1
# skips a section (ADTREE, REAL, SCALE, THREADS, SPECIES, FIXED).
set -u
SYLVA=${1:?usage: run.sh SYLVA [ADTREE] [SCANS_DIR]}
ADTREE=${2:-}
SCANS=${3:-$(mktemp -d)}
mkdir -p "$SCANS"
DATA=${SYLVA_DATA_DIR:-$(cd "$(dirname "$0")/../../../shared/data" && pwd)}
REPS=${REPS:-3}
SIZES=${SIZES:-100k}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
summary=$tmp/summary
: > "$summary"
# target NAME MEASURED MET: one row of the closing table.
target() { printf "%-46s %-34s %s\n" "$1" "$2" "$3" >> "$summary"; }
load() { cut -d' ' -f1-3 /proc/loadavg; }

# cpu CMD...: prints "user+sys peak_kb wall exit" of one run.
cpu() {
  /usr/bin/time -f "%U %S %M %e %x" -o "$tmp/t" "$@" > "$tmp/out" 2> "$tmp/err"
  # AdTree's batch mode exits 1 after writing its models: time then adds a status line first.
  tail -n 1 "$tmp/t" | awk '{ printf "%.3f %d %.2f %d\n", $1 + $2, $3, $4, $5 }'
}
median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }
jnum() { python3 -c "import json,sys
try: d=json.load(open(sys.argv[1]))
except Exception: print('nan'); sys.exit()
for k in sys.argv[2].split('.'):
    d = d[int(k)] if k.isdigit() else d.get(k, 'nan') if isinstance(d, dict) else 'nan'
print(d)" "$1" "$2"; }
pct() { awk -v a="$1" -v t="$2" 'BEGIN { if (a == "nan" || t == 0) print "nan"; else printf "%+.1f", 100 * (a - t) / t }'; }
within() { awk -v e="$1" -v lim="$2" 'BEGIN { if (e == "nan") exit 1; if (e < 0) e = -e; exit !(e <= lim) }'; }
size_n() { case $1 in 100k) echo 100000;; 300k) echo 300000;; 1m) echo 1000000;; 3m) echo 3000000;; esac; }
scan_args() { case $1 in 100k) echo "--step 0.16 --max-points 100000";; 300k) echo "--step 0.12 --max-points 300000";;
  1m) echo "--step 0.08 --max-points 1000000";; 3m) echo "--max-points 3000000";; esac; }
# make_scan SPECIES SIZE OUT.las: a simulated terrestrial scan and its truth (OUT.json).
make_scan() {
  [[ -f $3 ]] && return
  # shellcheck disable=SC2046
  nice -n 10 "$SYLVA" scan "$1" $(scan_args "$2") -o "$3" --truth "${3%.las}.json" > /dev/null 2>&1
}

echo "load at start: $(load)"

if [[ ${SKIP_ADTREE:-0} != 1 ]]; then
  echo "== sylva run vs AdTree on AdTree's files (CPU s, median of $REPS alternating runs)"
  printf "%-14s %8s %10s %10s %8s\n" file points sylva adtree speedup
  worst=
  for f in tree1 tree7 tree13 tree33 Lille_11 ahn3_delft; do
    in="$DATA/real/adtree/$f.xyz"
    [[ -f $in ]] || continue
    : > "$tmp/s"; : > "$tmp/a"
    for r in $(seq "$REPS"); do
      cpu "$SYLVA" run "$in" -o "$tmp/$f.glb" | awk '{ print $1 }' >> "$tmp/s"
      if [[ -n $ADTREE ]]; then
        rm -rf "$tmp/adt"; mkdir "$tmp/adt"
        cpu "$ADTREE" "$in" "$tmp/adt" | awk '{ print $1 }' >> "$tmp/a"
      fi
    done
    s=$(median < "$tmp/s"); a=$([[ -s $tmp/a ]] && median < "$tmp/a" || echo nan)
    sp=$(awk -v s="$s" -v a="$a" 'BEGIN { if (a == "nan") print "nan"; else printf "%.2f", a / s }')
    printf "%-14s %8d %10.3f %10s %8s\n" "$f" "$(wc -l < "$in")" "$s" "$a" "${sp}x"
    [[ $sp != nan ]] && worst=$(awk -v w="${worst:-1e9}" -v s="$sp" 'BEGIN { print (s < w ? s : w) }')
  done
  if [[ -n $worst ]]; then
    target "run >= 5x faster than AdTree, each file" "worst ${worst}x" "$(awk -v w="$worst" 'BEGIN { print (w >= 5 ? "met" : "NOT met") }')"
  else
    target "run >= 5x faster than AdTree, each file" "no AdTree binary given" "not measured"
  fi
  echo
fi

if [[ ${SKIP_REAL:-0} != 1 ]]; then
  # A failed tree is a handful of nodes from thousands of points (issue 12:
  # ahn3_delft as a 2-node tree). The main skeleton plus the lobes hung from
  # it is the tree synthesis makes: ahn3_delft's 10 main nodes carry 16
  # lobes (IoU 0.859 against its scan), which the nodes-only rule counted as
  # failed until stop 25.
  echo "== no failed tree on the real scans (sylva run --json; exit, main nodes + lobes >= 12, height)"
  printf "%-22s %5s %6s %6s %8s %8s %9s\n" scan exit nodes lobes height dbh cpu_s
  fails=0; count=0
  for in in "$DATA"/real/adtree/{tree1,tree7,tree13,tree33,Lille_11,ahn3_delft}.xyz "$DATA/real/treels/pine.las" \
      "$DATA/real/pytlidar/tree_1.las" "$DATA/real/rtwig/cloud.txt"; do
    [[ -f $in ]] || continue
    read -r t _ _ x < <(cpu nice -n 10 "$SYLVA" run "$in" -o "$tmp/r.glb" --json)
    cp "$tmp/out" "$tmp/r.json"
    nodes=$(jnum "$tmp/r.json" nodes); lobes=$(jnum "$tmp/r.json" clusters)
    printf "%-22s %5d %6s %6s %8s %8s %9.2f\n" "$(basename "$(dirname "$in")")/$(basename "$in")" "$x" "$nodes" "$lobes" \
      "$(jnum "$tmp/r.json" height)" "$(jnum "$tmp/r.json" dbh)" "$t"
    count=$((count + 1))
    [[ $x == 0 && $nodes != nan && $lobes != nan && $((nodes + lobes)) -ge 12 ]] || fails=$((fails + 1))
  done
  target "no failed tree, real scans" "$fails failed of $count" "$([[ $fails == 0 ]] && echo met || echo "NOT met")"
  echo
fi

if [[ ${SKIP_SCALE:-0} != 1 ]]; then
  echo "== scaling: black_oak terrestrial scans (sylva run, nice -n 10; load $(load))"
  for n in 100k 300k 1m 3m; do make_scan black_oak $n "$SCANS/oak$n.las"; done
  printf "%-6s %9s %10s %9s %11s %5s %6s %8s %8s %10s\n" scan points run_cpu_s wall_s peak_B/pt exit nodes H_err% DBH_err% skel_cpu_s
  first_n=; first_t=; prev_n=; prev_t=; sfails=0; scount=0
  for n in 100k 300k 1m 3m; do
    in="$SCANS/oak$n.las"
    [[ -f $in ]] || continue
    pts=$("$SYLVA" info "$in" | awk '/^  points/ { print $2 }')
    read -r t kb wall x < <(cpu nice -n 10 "$SYLVA" run "$in" -o "$tmp/o.glb" --json)
    cp "$tmp/out" "$tmp/o.json"
    [[ $x != 0 ]] && echo "       run failed: $(tail -n 1 "$tmp/err")"
    scount=$((scount + 1)); [[ $x == 0 ]] || sfails=$((sfails + 1))
    read -r k _ _ _ < <(cpu nice -n 10 "$SYLVA" skeleton "$in" -o "$tmp/o.sylva")
    th=$(jnum "${in%.las}.json" trees.0.height); td=$(jnum "${in%.las}.json" trees.0.dbh)
    he=$(pct "$(jnum "$tmp/o.json" height)" "$th"); de=$(pct "$(jnum "$tmp/o.json" dbh)" "$td")
    bpp=$(echo "$kb * 1024 / $pts" | bc -l)
    printf "%-6s %9d %10.2f %9.2f %11.0f %5d %6s %8s %8s %10.2f\n" "$n" "$pts" "$t" "$wall" "$bpp" "$x" \
      "$(jnum "$tmp/o.json" nodes)" "$he" "$de" "$k"
    if [[ -n $prev_n ]]; then
      awk -v a="$prev_n" -v b="$pts" -v x="$prev_t" -v y="$t" 'BEGIN { printf "       exponent of run from the previous size %.2f\n", log(y / x) / log(b / a) }'
    fi
    [[ -z $first_n ]] && first_n=$pts first_t=$t
    prev_n=$pts; prev_t=$t
    case $n in
      1m) target "1 M-point run <= 10 s CPU" "$t s" "$(awk -v t="$t" 'BEGIN { print (t <= 10 ? "met" : "NOT met") }')";;
      3m) target "3 M-point run <= 30 s CPU" "$t s" "$(awk -v t="$t" 'BEGIN { print (t <= 30 ? "met" : "NOT met") }')"
          target "peak <= 150 bytes/point (3 M run)" "$(printf %.0f "$bpp") B/pt" "$(awk -v b="$bpp" 'BEGIN { print (b <= 150 ? "met" : "NOT met") }')";;
    esac
  done
  target "no failed tree, black_oak 100k..3M raw" "$sfails failed of $scount" "$([[ $sfails == 0 ]] && echo met || echo "NOT met")"
  if [[ -n $prev_n && $prev_n != "$first_n" ]]; then
    e=$(awk -v a="$first_n" -v b="$prev_n" -v x="$first_t" -v y="$prev_t" 'BEGIN { printf "%.2f", log(y / x) / log(b / a) }')
    echo "       exponent of run 100k -> 3M: $e"
    target "run CPU exponent 100k -> 3M <= 1.1" "$e" "$(awk -v e="$e" 'BEGIN { print (e <= 1.1 ? "met" : "NOT met") }')"
  fi
  echo
fi

if [[ ${SKIP_THREADS:-0} != 1 && -f $SCANS/oak1m.las ]]; then
  echo "== threads: sylva run on the 1 M scan (load $(load))"
  for th in 1 2; do
    read -r t _ w _ < <(cpu nice -n 10 "$SYLVA" run "$SCANS/oak1m.las" --threads $th -o "$tmp/th$th.glb")
    echo "threads $th: cpu $t s, wall $w s"
    eval "w$th=$w"
  done
  # shellcheck disable=SC2154
  r=$(awk -v a="$w1" -v b="$w2" 'BEGIN { printf "%.2f", a / b }')
  cmp -s "$tmp/th1.glb" "$tmp/th2.glb" && same="same bytes" || same="DIFFERENT bytes"
  echo "wall ratio 1/2 threads: ${r}x; 1 and 2 threads: $same"
  target "2 threads >= 1.7x faster than 1 (1 M run)" "${r}x wall at load $(load | cut -d' ' -f1), $same" \
    "$(awk -v r="$r" 'BEGIN { print (r >= 1.7 ? "met" : "NOT met") }')"
  echo
fi

if [[ ${SKIP_SPECIES:-0} != 1 ]]; then
  species=${SPECIES:-$("$SYLVA" library list 2>/dev/null | awk 'NR > 1 && $1 ~ /^[0-9]+$/ { print $2 }')}
  echo "== every species, simulated terrestrial scans, sizes: $SIZES (run raw and preprocessed; load $(load))"
  printf "%-16s %5s %4s %5s %6s %8s %8s %8s\n" species size kind exit nodes H_err% DBH_err% cpu_s
  fails=0; count=0; off=0
  for sp in $species; do
    for n in $SIZES; do
      raw="$SCANS/${sp}_$n.las"
      make_scan "$sp" "$n" "$raw"
      [[ -f $raw ]] || { echo "$sp $n: scan failed"; fails=$((fails + 1)); continue; }
      pp="$SCANS/${sp}_${n}_pp.las"
      [[ -f $pp ]] || nice -n 10 "$SYLVA" preprocess "$raw" -o "$pp" > /dev/null 2>&1
      th=$(jnum "${raw%.las}.json" trees.0.height); td=$(jnum "${raw%.las}.json" trees.0.dbh)
      for kind in raw pp; do
        f=$raw; [[ $kind == pp ]] && f=$pp
        read -r t _ _ x < <(cpu nice -n 10 "$SYLVA" run "$f" -o "$tmp/s.glb" --json)
        cp "$tmp/out" "$tmp/s.json"
        nodes=$(jnum "$tmp/s.json" nodes)
        he=$(pct "$(jnum "$tmp/s.json" height)" "$th"); de=$(pct "$(jnum "$tmp/s.json" dbh)" "$td")
        printf "%-16s %5s %4s %5d %6s %8s %8s %8.2f\n" "$sp" "$n" "$kind" "$x" "$nodes" "$he" "$de" "$t"
        count=$((count + 1))
        [[ $x == 0 && $nodes != nan && $nodes -ge 12 ]] || fails=$((fails + 1))
        within "$he" 5 && within "$de" 5 || off=$((off + 1))
      done
    done
  done
  target "no failed tree, simulated scans ($SIZES)" "$fails failed of $count" "$([[ $fails == 0 ]] && echo met || echo "NOT met")"
  target "height and DBH within 5% (simulated)" "$((count - off)) of $count within" "$([[ $off == 0 ]] && echo met || echo "NOT met")"
  echo
fi

if [[ ${SKIP_FIXED:-0} != 1 ]]; then
  echo "== fixed costs and ingest (CPU ms: perf stat task-clock, 20 runs; load $(load))"
  # task-clock of CMD in ms, mean of 20 runs.
  ms() { perf stat -x, -e task-clock -r 20 "$@" 2>&1 > /dev/null | awk -F, '/task-clock/ { printf "%.1f", $1 }'; }
  v=$(ms "$SYLVA" --version)
  libs=$(ldd "$SYLVA" | wc -l)
  echo "sylva --version            $v ms CPU, $libs shared libraries"
  target "sylva --version <= 10 ms" "$v ms CPU, $libs libraries" "$(awk -v v="$v" 'BEGIN { print (v <= 10 ? "met" : "NOT met") }')"
  worst=
  for f in "$SCANS/oak1m.las" "$SCANS/oak3m.las" "$DATA/real/treels/pine.las" "$DATA/real/adtree/tree7.xyz"; do
    [[ -f $f ]] || continue
    i=$(ms "$SYLVA" info "$f"); p=$(ms cat "$f")
    read -r _ kb _ _ < <(cpu "$SYLVA" info "$f")
    r=$(awk -v i="$i" -v p="$p" 'BEGIN { printf "%.1f", i / p }')
    printf "%-26s info %8.1f ms (peak %d kB), plain read (cat) %6.1f ms: %sx\n" "$(basename "$f")" "$i" "$kb" "$p" "$r"
    [[ $f == *.las ]] && worst=$(awk -v w="${worst:-0}" -v r="$r" 'BEGIN { print (r > w ? r : w) }')
  done
  [[ -n $worst ]] && target "sylva info <= 2x a plain read (LAS)" "worst ${worst}x" \
    "$(awk -v w="$worst" 'BEGIN { print (w <= 2 ? "met" : "NOT met") }')"
  echo
fi

echo "== targets (load at end: $(load))"
printf "%-46s %-34s %s\n" target measured verdict
cat "$summary"
