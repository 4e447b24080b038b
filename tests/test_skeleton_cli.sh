#!/usr/bin/env bash
# CLI test for `sylva skeleton` and `sylva decode`: exit codes, one-line
# errors naming the file, --json output, determinism, the 40 kB budget.
set -u
fail() { echo "FAIL: $*"; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
corpus="$SYLVA_SOURCE_DIR/tests/fuzz/corpus/sylva"

# The fuzz corpus holds real .sylva files behind a one-byte mode prefix.
tail -c +2 "$corpus/tree7-asis" > "$tmp/tree7.sylva"
out=$("$SYLVA" decode --json "$tmp/tree7.sylva") || fail "decode exit $?"
echo "$out" | grep -q '"nodes":[1-9]' || fail "decode json: $out"
echo "$out" | grep -q '"clusters":[1-9]' || fail "decode json: $out"
"$SYLVA" decode "$tmp/tree7.sylva" | grep -q 'skeleton' || fail "decode text"

# Damaged files: exit 2, one line on stderr naming the file.
head -c 100 "$tmp/tree7.sylva" > "$tmp/cut.sylva"
"$SYLVA" decode "$tmp/cut.sylva" 2> "$tmp/err"; rc=$?
[[ $rc == 2 ]] || fail "truncated file exit $rc"
[[ $(wc -l < "$tmp/err") == 1 ]] && grep -q 'cut.sylva' "$tmp/err" || fail "truncated message: $(cat "$tmp/err")"
"$SYLVA" decode "$tmp/missing.sylva" 2>/dev/null; [[ $? == 2 ]] || fail "missing file"

# Usage errors exit 1; a missing scan exits 2.
"$SYLVA" skeleton "$tmp/x.xyz" 2>/dev/null; [[ $? == 1 ]] || fail "no -o"
"$SYLVA" skeleton "$tmp/x.xyz" -o "$tmp/x.sylva" --fs 2 2>/dev/null; [[ $? == 1 ]] || fail "--fs 2"
"$SYLVA" skeleton "$tmp/x.xyz" -o "$tmp/x.sylva" 2>/dev/null; [[ $? == 2 ]] || fail "missing scan"
[[ ! -e "$tmp/x.sylva" ]] || fail "output written on failure"

# End to end on the bundled sample, when the XYZ reader is present.
if "$SYLVA" info "$SYLVA_SOURCE_DIR/samples/tree1.xyz" >/dev/null 2>&1; then
  "$SYLVA" skeleton --json "$SYLVA_SOURCE_DIR/samples/tree1.xyz" -o "$tmp/a.sylva" > "$tmp/a.json" || fail "skeleton exit $?"
  grep -q '"dbh":0\.[0-9]' "$tmp/a.json" || fail "skeleton json: $(cat "$tmp/a.json")"
  "$SYLVA" skeleton --quiet "$SYLVA_SOURCE_DIR/samples/tree1.xyz" -o "$tmp/b.sylva" >/dev/null || fail "second run"
  cmp -s "$tmp/a.sylva" "$tmp/b.sylva" || fail "two runs differ"
  size=$(stat -c %s "$tmp/a.sylva")
  (( size < 40000 )) || fail "tree1.sylva is $size bytes"
  "$SYLVA" decode "$tmp/a.sylva" >/dev/null || fail "decode of fresh output"
  "$SYLVA" skeleton "$SYLVA_SOURCE_DIR/samples/tree1.xyz" -o "$tmp/no/such/dir.sylva" 2>/dev/null && fail "bad output dir"
else
  echo "XYZ reader not in this build: end-to-end part skipped"
fi
echo "all skeleton CLI checks passed"
