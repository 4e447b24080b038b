#!/usr/bin/env bash
# CLI checks for the LAS reader/writer: info, LAZ reading, convert round trip,
# and no output left behind by a failing convert.
set -u
fail() { echo "FAIL: $*" >&2; exit 1; }
: "${SYLVA:?SYLVA must point at the sylva binary}"
: "${SYLVA_DATA_DIR:?}"
MC="$SYLVA_DATA_DIR/real/lidr/MixedConifer.las"
LAZ="$SYLVA_DATA_DIR/real/lidr/MixedConifer.laz"
TMP=$(mktemp -d "${TMPDIR:-/tmp}/sylva-las-XXXXXX")
trap 'rm -rf "$TMP"' EXIT

json=$("$SYLVA" info --json "$MC") || fail "info on MixedConifer.las exited $?"
echo "$json" | grep -q '"point_count":37657' || fail "point_count 37657 missing: $json"
echo "$json" | grep -q '"attributes":\[[^]]*"treeID"' || fail "treeID missing from attributes: $json"
echo "$json" | grep -q '"crs":"EPSG:26912"' || fail "crs EPSG:26912 missing: $json"

json=$("$SYLVA" info --json "$LAZ") || fail "info on .laz exited $?"
echo "$json" | grep -q '"point_count":37657' || fail "LAZ point_count 37657 missing: $json"
echo "$json" | grep -q '"format":"LAZ"' || fail "LAZ format missing: $json"
echo "$json" | grep -q '"attributes":\[[^]]*"treeID"' || fail "treeID missing from LAZ attributes: $json"

"$SYLVA" convert "$MC" -o "$TMP/X.las" 2>"$TMP/err" || fail "convert exited $?: $(cat "$TMP/err")"
json=$("$SYLVA" info --json "$TMP/X.las") || fail "info on converted file exited $?"
echo "$json" | grep -q '"point_count":37657' || fail "converted point_count: $json"
echo "$json" | grep -q '"attributes":\[[^]]*"treeID"' || fail "converted treeID: $json"
echo "$json" | grep -q '"version":"1.4"' || fail "converted version: $json"
# GeoTIFF keys only go with legacy point formats, so the CRS keeps format 1.
echo "$json" | grep -q '"point_format":1,"global_encoding":0,' || fail "converted format/encoding: $json"
echo "$json" | grep -q '"crs":"EPSG:26912"' || fail "converted crs: $json"

# dbh.las: global encoding 17 (adjusted standard GPS time + WKT) survives.
DBH="$SYLVA_DATA_DIR/real/lidr/dbh.las"
"$SYLVA" info --json "$DBH" | grep -q '"global_encoding":17,' || fail "dbh.las global_encoding is not 17"
"$SYLVA" convert "$DBH" -o "$TMP/dbh.las" 2>"$TMP/err" || fail "convert dbh exited $?: $(cat "$TMP/err")"
json=$("$SYLVA" info --json "$TMP/dbh.las") || fail "info on converted dbh exited $?"
echo "$json" | grep -q '"point_format":6,"global_encoding":17,' || fail "converted dbh format/encoding: $json"

# Normals from preprocess survive a LAS file (float extra bytes NormalX/Y/Z).
"$SYLVA" preprocess "$SYLVA_DATA_DIR/real/adtree/tree1.xyz" -o "$TMP/pp.las" >/dev/null 2>"$TMP/err" \
    || fail "preprocess to .las exited $?: $(cat "$TMP/err")"
json=$("$SYLVA" info --json "$TMP/pp.las") || fail "info on preprocessed .las exited $?"
echo "$json" | grep -q '"attributes":\["xyz","normal",' || fail "normals lost in .las: $json"
echo "$json" | grep -q 'NormalX' && fail "normals read back as attributes: $json"

# A failing convert (a truncated LAZ; then a truncated LAS) leaves nothing behind.
mkdir "$TMP/out_dir"
head -c 100000 "$LAZ" >"$TMP/cut.laz"
"$SYLVA" convert "$TMP/cut.laz" -o "$TMP/out_dir/Y.las" 2>/dev/null && fail "convert of a truncated .laz succeeded"
"$SYLVA" convert "$TMP/cut.laz" -o "$TMP/out_dir/Y.ply" 2>/dev/null && fail "convert of a truncated .laz succeeded"
head -c 4000 "$MC" >"$TMP/cut.las"
"$SYLVA" convert "$TMP/cut.las" -o "$TMP/out_dir/Z.las" 2>"$TMP/err"
rc=$?
[ "$rc" -eq 2 ] || fail "convert of truncated LAS exited $rc, want 2"
grep -q "cut.las" "$TMP/err" || fail "truncated message does not name the file: $(cat "$TMP/err")"
[ -z "$(ls -A "$TMP/out_dir")" ] || fail "failing convert left files: $(ls -A "$TMP/out_dir")"
echo "ok"
