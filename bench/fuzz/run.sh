#!/usr/bin/env bash
# Runs every libFuzzer target (tests/fuzz/fuzz_*.c) for a set number of
# executions, each from its committed corpus, and prints executions, time and
# findings per target. New inputs and crash artifacts go to a work folder,
# never into the repository's corpora (minimise and commit a find by hand).
#
#   bench/fuzz/run.sh [-n RUNS] [-t SECONDS] [-j JOBS] [-b BUILD] [-w WORK] [TARGET...]
#
#   -n RUNS     executions per target (default 10000000, the release target)
#   -t SECONDS  wall-clock cap per target (default 0: none); whichever comes first
#   -j JOBS     targets run side by side (default: half the cores, at least 1)
#   -b BUILD    fuzz build folder (default build-fuzz; configured and built if missing)
#   -w WORK     work folder (default /tmp/sylva-fuzz)
#
# Budget per input: -timeout=10 s and -rss_limit_mb=2048; an input past either
# is a finding like a crash or a sanitizer report (UBSan with
# float-cast-overflow, no recovery: see the SYLVA_FUZZ block of CMakeLists.txt).
# Exit status 1 when any target found something.
set -euo pipefail
cd "$(dirname "$0")/../.."
runs=10000000 secs=0 build=build-fuzz work=/tmp/sylva-fuzz
jobs=$(( $(nproc 2>/dev/null || echo 2) / 2 )); (( jobs >= 1 )) || jobs=1
while getopts "n:t:j:b:w:" opt; do
  case $opt in
    n) runs=$OPTARG ;; t) secs=$OPTARG ;; j) jobs=$OPTARG ;; b) build=$OPTARG ;; w) work=$OPTARG ;;
    *) sed -n '2,20p' "$0"; exit 1 ;;
  esac
done
shift $((OPTIND - 1))
if (( $# )); then targets=("$@"); else
  targets=(); for src in tests/fuzz/fuzz_*.c; do n=$(basename "$src" .c); targets+=("${n#fuzz_}"); done
fi
if [[ ! -f $build/CMakeCache.txt ]]; then
  CC=clang CXX=clang++ cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSYLVA_FUZZ=ON -DSYLVA_BENCH=OFF >/dev/null
fi
cmake --build "$build" -j"$jobs" --target $(printf 'fuzz_%s ' "${targets[@]}") >/dev/null
mkdir -p "$work"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" ASAN_OPTIONS="detect_leaks=1"
export LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp:print_suppressions=0"

one() {
  local t=$1 dir=$work/$1
  mkdir -p "$dir/corpus" "$dir/artifacts"
  cp -n tests/fuzz/corpus/"$t"/* "$dir/corpus/" 2>/dev/null || true
  local dict=() ; [[ -f tests/fuzz/$t.dict ]] && dict=(-dict=tests/fuzz/$t.dict)
  local start=$(date +%s)
  "$build"/tests/fuzz_"$t" -runs="$runs" -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="$dir/artifacts/" "${dict[@]}" "$dir/corpus" >"$dir/log" 2>&1
  local rc=$? end=$(date +%s)
  local execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$dir/log" | grep -o '[0-9]*$' | tail -1)
  local found=$(ls "$dir/artifacts" | wc -l)
  printf '%s %s %s %s %s\n' "$t" "${execs:-0}" $((end - start)) "$rc" "$found" >"$dir/result"
}

echo "fuzzing ${#targets[@]} targets, $runs executions each (cap ${secs}s), $jobs at a time; work in $work"
running=0
for t in "${targets[@]}"; do
  one "$t" &
  running=$((running + 1))
  if (( running >= jobs )); then wait -n || true; running=$((running - 1)); fi
done
wait || true

status=0
printf '\n| target | executions | seconds | exec/s | findings |\n|---|---:|---:|---:|---|\n'
for t in "${targets[@]}"; do
  read -r name execs s rc found <"$work/$t/result"
  rate=$(( s > 0 ? execs / s : execs ))
  verdict=none; if [[ $rc != 0 || $found != 0 ]]; then verdict="$found in $work/$t/artifacts (exit $rc)"; status=1; fi
  printf '| %s | %s | %s | %s | %s |\n' "$name" "$execs" "$s" "$rate" "$verdict"
done
exit $status
