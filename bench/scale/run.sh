#!/usr/bin/env bash
# Scale bench (docs/skeleton.md, "Dense scans"): everything the targets of
# "any scan, any size" name, printed side by side in one run. CPU time
# (user + sys of the whole process) throughout: the machine is shared.
#
#   bench/scale/run.sh SYLVA [ADTREE] [SCANS_DIR]
#
# ADTREE: an AdTree binary built outside this repository (tudelft3d/AdTree;
# its batch mode `AdTree IN.xyz OUT_DIR`), compared file by file on AdTree's
# own data, alternating runs. SCANS_DIR: black_oak scans oak100k.las,
# oak300k.las, oak1m.las, oak3m.las (made with `sylva scan black_oak
# --max-points N`, coarser --step for the small ones, when absent: minutes).
set -u
SYLVA=${1:?usage: run.sh SYLVA [ADTREE] [SCANS_DIR]}
ADTREE=${2:-}
SCANS=${3:-$(mktemp -d)}
DATA=${SYLVA_DATA_DIR:-$(cd "$(dirname "$0")/../../../shared/data" && pwd)}
REPS=${REPS:-3}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# cpu CMD...: prints "user+sys peak_kb" of one run.
cpu() {
  /usr/bin/time -f "%U %S %M" -o "$tmp/t" "$@" > /dev/null 2>&1
  # AdTree's batch mode exits 1 after writing its models: time then adds a status line first.
  tail -n 1 "$tmp/t" | awk '{ printf "%.3f %d\n", $1 + $2, $3 }'
}
median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }

echo "== sylva run vs AdTree on AdTree's files (CPU s, median of $REPS alternating runs)"
printf "%-14s %8s %10s %10s %8s\n" file points sylva adtree speedup
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
  printf "%-14s %8d %10.3f %10s %8s\n" "$f" "$(wc -l < "$in")" "$s" "$a" \
    "$(awk -v s="$s" -v a="$a" 'BEGIN { if (a == "nan") print "-"; else printf "%.2fx", a / s }')"
done

echo
echo "== scaling: black_oak terrestrial scans (one run each, nice -n 10)"
for n in 100k 300k 1m 3m; do
  [[ -f $SCANS/oak$n.las ]] && continue
  case $n in 100k) a="--step 0.16 --max-points 100000";; 300k) a="--step 0.12 --max-points 300000";;
    1m) a="--step 0.08 --max-points 1000000";; 3m) a="--max-points 3000000";; esac
  # shellcheck disable=SC2086
  nice -n 10 "$SYLVA" scan black_oak $a -o "$SCANS/oak$n.las" --truth "$SCANS/oak$n.json" > /dev/null 2>&1
done
printf "%-6s %9s %10s %10s %8s %12s %10s\n" scan points run_cpu_s skel_cpu_s nodes peak_B/pt raw_skel_s
prev_n=; prev_t=; prev_k=; prev_r=
for n in 100k 300k 1m 3m; do
  in="$SCANS/oak$n.las"
  [[ -f $in ]] || continue
  pts=$("$SYLVA" info "$in" | awk '/^  points/ { print $2 }')
  read -r t kb < <(cpu nice -n 10 "$SYLVA" run "$in" -o "$tmp/o.glb")
  read -r k _ < <(cpu nice -n 10 "$SYLVA" skeleton "$in" -o "$tmp/o.sylva")
  nodes=$("$SYLVA" skeleton "$in" -o "$tmp/o2.sylva" --json 2>/dev/null | python3 -c "import json,sys; print(json.load(sys.stdin)['nodes'])")
  # The graph steps without the point budget: the algorithm's own exponent.
  read -r raw _ < <(cpu nice -n 10 "$SYLVA" skeleton "$in" --max-points 0 -o "$tmp/o3.sylva")
  printf "%-6s %9d %10.2f %10.2f %8d %12.0f %10.2f\n" "$n" "$pts" "$t" "$k" "$nodes" "$(echo "$kb * 1024 / $pts" | bc -l)" "$raw"
  if [[ -n $prev_n ]]; then
    awk -v a="$prev_n" -v b="$pts" -v x="$prev_t" -v y="$t" -v p="$prev_k" -v q="$k" -v r="$prev_r" -v s="$raw" \
      'BEGIN { l = log(b / a); printf "       exponent run %.2f, skeleton %.2f, skeleton without budget %.2f\n", log(y / x) / l, log(q / p) / l, log(s / r) / l }'
  fi
  prev_n=$pts; prev_t=$t; prev_k=$k; prev_r=$raw
done

echo
echo "== threads on the 1 M scan (CPU s and wall s of sylva skeleton --max-points 0)"
if [[ -f $SCANS/oak1m.las ]]; then
  for th in 1 2; do
    /usr/bin/time -f "%U %S %e" -o "$tmp/t" nice -n 10 "$SYLVA" skeleton "$SCANS/oak1m.las" --max-points 0 --threads $th \
      -o "$tmp/th$th.sylva" > /dev/null 2>&1
    awk -v th=$th '{ printf "threads %d: cpu %.2f s, wall %.2f s\n", th, $1 + $2, $3 }' "$tmp/t"
  done
  cmp -s "$tmp/th1.sylva" "$tmp/th2.sylva" && echo "1 and 2 threads: same bytes" || echo "1 and 2 threads: DIFFERENT bytes"
fi

echo
echo "== fixed costs and ingest (CPU s, median of 5)"
for r in 1 2 3 4 5; do cpu "$SYLVA" --version | awk '{ print $1 }'; done | median | awk '{ printf "sylva --version            %.3f s\n", $1 }'
for f in "$SCANS/oak1m.las" "$DATA/real/adtree/tree7.xyz"; do
  [[ -f $f ]] || continue
  i=$(for r in 1 2 3 4 5; do cpu "$SYLVA" info "$f" | awk '{ print $1 }'; done | median)
  c=$(for r in 1 2 3 4 5; do cpu "$SYLVA" convert "$f" -o "$tmp/c.ply" | awk '{ print $1 }'; done | median)
  p=$(for r in 1 2 3 4 5; do cpu cat "$f" | awk '{ print $1 }'; done | median)
  printf "%-26s info %.3f s, convert (full decode) %.3f s, plain read %.3f s\n" "$(basename "$f")" "$i" "$c" "$p"
done
