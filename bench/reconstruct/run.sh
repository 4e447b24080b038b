#!/usr/bin/env bash
# Reconstruction benchmark: `sylva run` end to end, scored by `sylva eval`,
# printed as a table with a comparison against the reconstruction targets below.
#  (a) simulated terrestrial scans of every library species, scored against
#      their exact truth: recall_r2cm >= 0.90, precision >= 0.90, median
#      radius error <= 20 %, DBH error <= 1 cm;
#  (b) real scans (../shared/data/real), scored against their own points after
#      the same preprocessing `sylva run` does: mean distance <= 3 cm and
#      coverage (within 2 cm) >= 90 %, model = branch cones + cluster hulls;
#  (c) skeleton + clusters time and memory (bench_skeleton, one thread).
# Usage: bench/reconstruct/run.sh [a] [b] [c]   (default: all three)
# Env: SYLVA (default build/sylva), BENCH_SKELETON (default build/bench/bench_skeleton),
#      BENCH_VISIBILITY (default build/bench/bench_visibility),
#      SYLVA_DATA_DIR (default ../shared/data), SEED (default 1), KEEP=DIR keeps the files,
#      SPECIES="a b" limits part (a) to those species, RUN_ARGS adds options to every `sylva run`,
#      SCAN_ARGS to every `sylva scan` of part (a) (SCAN_ARGS=--no-leaves: leaf-off scans).
set -u
cd "$(dirname "$0")/../.."
sylva=${SYLVA:-build/sylva}
bench_skeleton=${BENCH_SKELETON:-build/bench/bench_skeleton}
bench_visibility=${BENCH_VISIBILITY:-build/bench/bench_visibility}
data=${SYLVA_DATA_DIR:-../shared/data}
seed=${SEED:-1}
parts=${*:-a b c}
if [[ -n ${KEEP:-} ]]; then tmp=$KEEP; mkdir -p "$tmp"; else tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT; fi

# Value of a flat numeric JSON key ("nan" when absent).
key() { local v; v=$(grep -o "\"$1\":[^,}]*" <<< "$2" | head -1 | cut -d: -f2); echo "${v:-nan}"; }
# Scores targets: ok(value, op, limit) prints "ok" or "MISS".
ok() { awk -v v="$1" -v op="$2" -v t="$3" 'BEGIN { if (v == "nan" || v == "null") { print "MISS"; exit }
  p = (op == ">=") ? (v + 0 >= t) : (v + 0 <= t); print p ? "ok" : "MISS" }'; }
misses=0
note() { [[ $1 == ok ]] || misses=$((misses + 1)); }

# Terrestrial scan of one species, 100k-300k points: a first scan at 0.15
# degrees, rescanned at a coarser step when the tree is large.
scan_species() {
  local sp=$1 step=0.15 out n
  out=$("$sylva" scan "$sp" --seed "$seed" --scanner terrestrial --step $step ${SCAN_ARGS:-} -o "$tmp/$sp.las" \
        --truth "$tmp/$sp.json" --quiet --json) || return 1
  n=$(key point_count "$out")
  if (( n > 300000 )); then
    step=$(awk -v s=$step -v n="$n" 'BEGIN { printf "%.3f", s * sqrt(n / 250000) }')
    out=$("$sylva" scan "$sp" --seed "$seed" --scanner terrestrial --step "$step" ${SCAN_ARGS:-} -o "$tmp/$sp.las" \
          --truth "$tmp/$sp.json" --quiet --json) || return 1
  fi
  echo "$(key point_count "$out") $step"
}

if [[ $parts == *a* ]]; then
  echo "(a) simulated terrestrial scans, seed $seed: sylva run --species S, eval --truth"
  echo "(vis: share of the thick-stem length with a wood return within eval's tolerance, bench_visibility;"
  echo " the ceiling leaf occlusion puts on r2cm for a skeleton placed on evidence)"
  printf '%-16s %8s %6s %6s %6s %5s %6s %6s %6s %6s %7s %7s %6s %s\n' species points step nodes clust \
    secs vis r2cm recall prec rad_err dbh_err h_err targets
  for ini in species/*.ini; do
    sp=$(basename "$ini" .ini)
    [[ -z ${SPECIES:-} || " $SPECIES " == *" $sp "* ]] || continue
    read -r n step < <(scan_species "$sp") || { echo "$sp: scan failed"; misses=$((misses + 1)); continue; }
    t0=$(date +%s.%N)
    run=$("$sylva" run "$tmp/$sp.las" --species "$sp" ${RUN_ARGS:-} -o "$tmp/$sp.glb" --sylva "$tmp/$sp.sylva" --quiet --json) ||
      { echo "$sp: run failed"; misses=$((misses + 1)); continue; }
    secs=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
    ev=$("$sylva" eval --truth "$tmp/$sp.json" "$tmp/$sp.sylva" --json)
    r2=$(key recall_r2cm "$ev"); pr=$(key precision "$ev"); re=$(key radius_error_median "$ev")
    de=$(key dbh_error "$ev"); he=$(key height_error "$ev")
    t1=$(ok "$r2" ">=" 0.90); t2=$(ok "$pr" ">=" 0.90); t3=$(ok "$re" "<=" 0.20); t4=$(ok "$de" "<=" 0.01)
    for t in $t1 $t2 $t3 $t4; do note "$t"; done
    vis=$("$bench_visibility" "$tmp/$sp.las" "$tmp/$sp.json" | sed -n 's/.*of a wood return \([0-9.]*\),.*/\1/p')
    printf '%-16s %8d %6s %6d %6d %5s %6.3f %6.3f %6.3f %6.3f %7.3f %7.4f %6.2f %s/%s/%s/%s\n' "$sp" "$n" "$step" \
      "$(key nodes "$run")" "$(key clusters "$run")" "$secs" "${vis:-nan}" "$r2" "$(key recall "$ev")" "$pr" "$re" \
      "$de" "$he" "$t1" "$t2" "$t3" "$t4"
  done
  echo "targets (r2cm/prec/rad_err/dbh_err): recall_r2cm >= 0.90, precision >= 0.90, median radius error <= 0.20, DBH error <= 0.01 m"
  echo
fi

if [[ $parts == *b* ]]; then
  echo "(b) real scans: sylva run, eval --points (preprocessed points) against branch cones + hulls"
  printf '%-18s %8s %8s %6s %6s %5s %8s %8s %8s %s\n' tree points clean nodes clust secs mean_cm cover p95_cm targets
  for f in adtree/tree1.xyz adtree/tree7.xyz adtree/tree13.xyz adtree/tree33.xyz adtree/Lille_11.xyz \
           treels/pine.las pytlidar/tree_1.las; do
    in=$data/real/$f
    name=$(basename "$(dirname "$f")")/$(basename "$f")
    [[ -f $in ]] || { echo "$name: missing ($in)"; misses=$((misses + 1)); continue; }
    stem=$tmp/real_$(basename "$f" | tr . _)
    t0=$(date +%s.%N)
    run=$("$sylva" run "$in" ${RUN_ARGS:-} -o "$stem.glb" --sylva "$stem.sylva" --quiet --json) ||
      { echo "$name: run failed"; misses=$((misses + 1)); continue; }
    secs=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
    # The points the model was built from: the same preprocessing as `sylva run`.
    "$sylva" preprocess "$in" -o "$stem.ply" --remove-ground --no-normals --quiet > /dev/null ||
      { echo "$name: preprocess failed"; misses=$((misses + 1)); continue; }
    ev=$("$sylva" eval --points "$stem.ply" "$stem.sylva" --json)
    md=$(key mean_distance "$ev"); cv=$(key coverage "$ev")
    t1=$(ok "$md" "<=" 0.03); t2=$(ok "$cv" ">=" 0.90)
    note "$t1"; note "$t2"
    printf '%-18s %8d %8d %6d %6d %5s %8.2f %8.3f %8.2f %s/%s\n' "$name" "$(key points_in "$run")" \
      "$(key points_preprocessed "$run")" "$(key nodes "$run")" "$(key clusters "$run")" "$secs" \
      "$(awk -v v="$md" 'BEGIN { print 100 * v }')" "$cv" "$(awk -v v="$(key p95_distance "$ev")" 'BEGIN { print 100 * v }')" \
      "$t1" "$t2"
  done
  echo "targets (mean/cover): mean point->model distance <= 3 cm, coverage within 2 cm >= 0.90"
  echo
fi

if [[ $parts == *c* ]]; then
  echo "(c) skeleton + clusters, one thread (bench_skeleton, synthetic tree, 40% foliage)"
  if [[ -x $bench_skeleton ]]; then
    for n in 100000 1000000; do
      out=$(/usr/bin/time -f "rss_kb %M" "$bench_skeleton" "$n" 2>&1) || { echo "$out"; misses=$((misses + 1)); continue; }
      line=$(grep 'points:' <<< "$out")
      total=$(sed -n 's/.*total *\([0-9.]*\) s.*/\1/p' <<< "$line")
      rss=$(sed -n 's/rss_kb \([0-9]*\)/\1/p' <<< "$out")
      limit=$([[ $n == 100000 ]] && echo 1 || echo 10)
      t1=$(ok "$total" "<=" "$limit"); t2=$(ok "$rss" "<=" 2097152)
      note "$t1"; note "$t2"
      echo "$line"
      printf '  -> %s s (target <= %s s: %s), peak RSS %d MB (target <= 2 GB: %s)\n' "$total" "$limit" "$t1" \
        $((rss / 1024)) "$t2"
    done
  else
    echo "$bench_skeleton not built"; misses=$((misses + 1))
  fi
  echo
fi
echo "targets missed: $misses"
