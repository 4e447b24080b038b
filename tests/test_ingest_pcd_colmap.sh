#!/usr/bin/env bash
# `sylva info` on PCD files and a COLMAP workspace: --json point counts, and
# truncated copies exit 2 with exactly one stderr line naming the file.
set -euo pipefail
: "${SYLVA:?}" "${SYLVA_SOURCE_DIR:?}"
data="$SYLVA_SOURCE_DIR/tests/data"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

fail() { echo "FAIL: $*" >&2; exit 1; }

point_count() {
    "$SYLVA" info --json "$1" | grep -o '"point_count":[0-9]*' | cut -d: -f2
}

expect_count() {
    local got
    got=$(point_count "$1") || fail "sylva info --json $1 failed"
    [ "$got" = "$2" ] || fail "$1: point_count $got, want $2"
}

expect_input_error() {
    local rc=0
    "$SYLVA" info "$1" >"$tmp/out" 2>"$tmp/err" || rc=$?
    [ "$rc" = 2 ] || fail "$1: exit $rc, want 2"
    [ "$(wc -l <"$tmp/err")" = 1 ] || fail "$1: stderr is not one line: $(cat "$tmp/err")"
    grep -qF "$2" "$tmp/err" || fail "$1: stderr does not name $2: $(cat "$tmp/err")"
}

expect_count "$data/pcd/xyzrgbnormal_ascii.pcd" 12
expect_count "$data/pcd/xyzrgbnormal_compressed.pcd" 12
expect_count "$data/pcd/organized_nan_compressed.pcd" 9
"$SYLVA" info --json "$data/pcd/organized_nan_compressed.pcd" | grep -q '"vlrs":"organized 4x3 grid\\nskipped 3 NaN points"' ||
    fail "organized cloud does not report its skipped NaN points"

mkdir -p "$tmp/ws/sparse/0"
cp "$data"/colmap/bin/*.bin "$tmp/ws/sparse/0/"
expect_count "$tmp/ws" 20
"$SYLVA" info --json "$tmp/ws" | grep -q '"format":"COLMAP","version":"sparse binary"' || fail "workspace format"

head -c 400 "$data/pcd/xyzrgbnormal_binary.pcd" >"$tmp/cut.pcd"
expect_input_error "$tmp/cut.pcd" "cut.pcd"

head -c 1000 "$data/colmap/bin/points3D.bin" >"$tmp/ws/sparse/0/points3D.bin"
expect_input_error "$tmp/ws" "points3D.bin"
echo "ok"
