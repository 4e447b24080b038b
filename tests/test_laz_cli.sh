#!/usr/bin/env bash
# CLI checks for LAZ: LAS -> LAZ -> LAS through `sylva convert` returns the
# input byte for byte; the writers that take .las take .laz (convert through
# the cloud, preprocess, scan) and laz-perf decodes what they write to the
# records of the .las the same command writes; the thread count changes no
# byte; a truncated LAZ fails with one line and leaves nothing behind.
set -u
fail() { echo "FAIL: $*" >&2; exit 1; }
: "${SYLVA:?SYLVA must point at the sylva binary}"
: "${SYLVA_DATA_DIR:?}"
: "${SYLVA_SOURCE_DIR:?}"
REAL="$SYLVA_DATA_DIR/real"
TMP=$(mktemp -d "${TMPDIR:-/tmp}/sylva-laz-XXXXXX")
trap 'rm -rf "$TMP"' EXIT
check() { # check LAZ LAS: laz-perf's records of LAZ equal LAS's
    (cd "$SYLVA_SOURCE_DIR" && node tests/laz_perf_check.mjs "$1" "$2") >"$TMP/check" 2>&1 ||
        fail "laz-perf disagrees on $1: $(cat "$TMP/check")"
}

# Lossless transcoding of the real scans, both ways.
for f in treels/pine lidr/MixedConifer lidr/dbh; do
    b=$(basename "$f")
    "$SYLVA" convert "$REAL/$f.las" -o "$TMP/$b.laz" --quiet || fail "convert $b.las -> .laz exited $?"
    check "$TMP/$b.laz" "$REAL/$f.las"
    "$SYLVA" convert "$TMP/$b.laz" -o "$TMP/$b.las" --quiet || fail "convert $b.laz -> .las exited $?"
    cmp -s "$TMP/$b.las" "$REAL/$f.las" || fail "$b: LAS -> LAZ -> LAS is not the input"
    "$SYLVA" convert "$REAL/$f.laz" -o "$TMP/$b.from-laszip.las" --quiet || fail "convert $b.laz exited $?"
    cmp -s "$TMP/$b.from-laszip.las" "$REAL/$f.las" || fail "$b: LASzip's .laz does not decode to its .las"
done
echo "ok: LAS -> LAZ -> LAS exact, laz-perf agrees"

# Through the cloud: the .laz and .las a command writes hold the same records.
"$SYLVA" convert "$REAL/lidr/dbh.laz" -o "$TMP/dbh.ply" --quiet || fail "convert .laz -> .ply exited $?"
"$SYLVA" convert "$TMP/dbh.ply" -o "$TMP/c.laz" --quiet || fail "convert .ply -> .laz exited $?"
"$SYLVA" convert "$TMP/dbh.ply" -o "$TMP/c.las" --quiet || fail "convert .ply -> .las exited $?"
check "$TMP/c.laz" "$TMP/c.las"
json=$("$SYLVA" info --json "$TMP/c.laz") || fail "info on written .laz exited $?"
echo "$json" | grep -q '"point_count":1369' || fail "written .laz point count: $json"
echo "$json" | grep -q '"format":"LAZ"' || fail "written .laz format: $json"
"$SYLVA" preprocess "$REAL/treels/pine.laz" --no-ground -o "$TMP/pp.laz" >/dev/null 2>"$TMP/err" ||
    fail "preprocess -o .laz exited $?: $(cat "$TMP/err")"
"$SYLVA" preprocess "$REAL/treels/pine.laz" --no-ground -o "$TMP/pp.las" >/dev/null 2>&1 ||
    fail "preprocess -o .las exited $?"
check "$TMP/pp.laz" "$TMP/pp.las"
"$SYLVA" scan quaking_aspen --step 0.5 -o "$TMP/scan.laz" --seed 3 >/dev/null 2>"$TMP/err" || fail "scan -o .laz exited $?: $(cat "$TMP/err")"
"$SYLVA" scan quaking_aspen --step 0.5 -o "$TMP/scan.las" --seed 3 >/dev/null 2>&1 || fail "scan -o .las exited $?"
check "$TMP/scan.laz" "$TMP/scan.las"
echo "ok: convert, preprocess and scan write .laz that laz-perf reads"

# One thread or two: the same bytes out.
"$SYLVA" convert "$REAL/treels/pine_plot.las" -o "$TMP/t1.laz" --threads 1 --quiet || fail "--threads 1 exited $?"
"$SYLVA" convert "$REAL/treels/pine_plot.las" -o "$TMP/t2.laz" --threads 2 --quiet || fail "--threads 2 exited $?"
cmp -s "$TMP/t1.laz" "$TMP/t2.laz" || fail "LAZ bytes depend on the thread count"
"$SYLVA" convert "$TMP/t1.laz" -o "$TMP/t1.ply" --threads 1 --quiet || fail "decode --threads 1 exited $?"
"$SYLVA" convert "$TMP/t1.laz" -o "$TMP/t2.ply" --threads 2 --quiet || fail "decode --threads 2 exited $?"
cmp -s "$TMP/t1.ply" "$TMP/t2.ply" || fail "decoded points depend on the thread count"
echo "ok: thread count independent"

# A truncated LAZ: exit 2, one line naming the file, no output left.
head -c 150000 "$REAL/treels/pine_plot.laz" >"$TMP/cut.laz"
mkdir "$TMP/out"
for o in x.las x.ply; do
    "$SYLVA" convert "$TMP/cut.laz" -o "$TMP/out/$o" 2>"$TMP/err"
    rc=$?
    [ "$rc" -eq 2 ] || fail "truncated LAZ -> $o exited $rc, want 2"
    [ "$(wc -l <"$TMP/err")" -eq 1 ] || fail "truncated LAZ: want one stderr line, got: $(cat "$TMP/err")"
    grep -q "cut.laz" "$TMP/err" || fail "truncated LAZ message does not name the file: $(cat "$TMP/err")"
done
[ -z "$(ls -A "$TMP/out")" ] || fail "failing convert left files: $(ls -A "$TMP/out")"
echo "ok: truncated LAZ rejected cleanly"
