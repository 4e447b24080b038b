#!/usr/bin/env bash
# The README's test command: installs dependencies, builds Sylva twice (release
# with warnings as errors, and AddressSanitizer + UBSan), runs the whole ctest
# suite in both, then replays every fuzz target over its committed corpus.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)
start=$(date +%s)

bash scripts/install-deps.sh

echo "== release build"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DSYLVA_WERROR=ON >/dev/null
cmake --build build -j"$jobs"
(cd build && ctest --output-on-failure -j"$jobs")

echo "== AddressSanitizer + UBSan build"
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSYLVA_WERROR=ON -DSYLVA_SANITIZE=ON \
  -DSYLVA_BENCH=OFF >/dev/null
cmake --build build-asan -j"$jobs"
# Third-party leaks (OpenMP thread pools in PCL) are suppressed by name only.
export LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
(cd build-asan && ctest --output-on-failure -j"$jobs")

echo "== fuzz targets over their corpora (regression replay)"
CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSYLVA_FUZZ=ON \
  -DSYLVA_BENCH=OFF >/dev/null
cmake --build build-fuzz -j"$jobs" --target $(cd tests/fuzz && ls fuzz_*.c | sed 's/\.c$//' | tr '\n' ' ')
fuzz_failed=0
for src in tests/fuzz/fuzz_*.c; do
  name=$(basename "$src" .c)
  corpus=tests/fuzz/corpus/${name#fuzz_}
  if ! build-fuzz/tests/"$name" -runs=0 "$corpus" >/tmp/sylva-"$name".log 2>&1; then
    echo "FAILED: $name over $corpus"; tail -20 /tmp/sylva-"$name".log; fuzz_failed=1
  else
    echo "ok: $name ($(ls "$corpus" | wc -l) inputs)"
  fi
done
[[ $fuzz_failed == 0 ]] || exit 1

echo "== all suites passed in $(( $(date +%s) - start )) s"
