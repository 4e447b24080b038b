# Sourced by the CLI tests that measure a reconstruction against numbers: a
# temporary folder removed on exit, fail=0, and check MESSAGE CONDITION,
# where CONDITION is an awk expression (prints ok/FAIL, sets fail=1).
set -u
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0
check() {
  if awk "BEGIN { exit !($2) }"; then echo "ok: $1"; else echo "FAIL: $1"; fail=1; fi
}
# check_bad_run SCAN FLAG VALUE NAME: `sylva run SCAN FLAG VALUE` is a usage
# error (exit 1) whose message names NAME, and it leaves no output file.
check_bad_run() {
  "$SYLVA" run "$1" -o "$tmp/bad.glb" "$2" "$3" --quiet 2> "$tmp/bad.err"
  local rc=$?
  check "$2 $3: exit $rc (1), says $4, no file" \
    "$rc == 1 && $(grep -c "$4" "$tmp/bad.err") >= 1 && $([ -e "$tmp/bad.glb" ] && echo 1 || echo 0) == 0"
}
