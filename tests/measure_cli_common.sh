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
