#!/usr/bin/env bash
# The committed simulated scans in samples/ are what samples/regenerate.sh
# makes with this build, byte for byte (LAS and truth): a change to growth,
# the BVH or the scanner that moves a point shows up here, not as samples
# that quietly stop matching their commands. All seven take about 2 s.
set -u
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
samples="$SYLVA_SOURCE_DIR/samples"
bash "$samples/regenerate.sh" "$SYLVA" "$tmp" > /dev/null 2> "$tmp/log" || { echo "FAIL: regenerate.sh: $(tail -3 "$tmp/log")"; exit 1; }
fail=0
n=0
for f in "$samples"/*_tls.las "$samples"/*_als.las; do
  for g in "$f" "${f%.las}.json"; do
    n=$((n + 1))
    if cmp -s "$g" "$tmp/$(basename "$g")"; then echo "ok: $(basename "$g") reproduced"
    else echo "FAIL: $(basename "$g") differs from what regenerate.sh makes (rerun it and commit)"; fail=1; fi
  done
done
(( n == 14 )) || { echo "FAIL: expected 7 scans with truth, found $((n / 2))"; fail=1; }
exit $fail
