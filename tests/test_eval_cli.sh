#!/usr/bin/env bash
# CLI checks for `sylva eval`: truth vs itself, skeleton vs truth, points vs
# model, segmentation on MixedConifer, species with a PNG, and bad inputs
# exiting 2 with one stderr line.
set -u
fail() { echo "FAIL: $*" >&2; exit 1; }
: "${SYLVA:?SYLVA must point at the sylva binary}"
: "${SYLVA_DATA_DIR:?}"
MC="$SYLVA_DATA_DIR/real/lidr/MixedConifer.las"
TMP=$(mktemp -d "${TMPDIR:-/tmp}/sylva-eval-XXXXXX")
trap 'rm -rf "$TMP"' EXIT

cat >"$TMP/truth.json" <<'JSON'
{"format": "sylva-truth", "version": 1, "scanner": {"kind": "terrestrial", "positions": 4, "seed": 7},
 "trees": [{"tree_id": 1, "species": "black_oak", "species_id": 2, "seed": 7, "position": [10, 20, 0],
  "height": 3.2, "dbh": 0.36, "crown_width": 2.0, "leaf_count": 0,
  "nodes": [
   {"id": 0, "parent": -1, "x": 10, "y": 20, "z": 0, "radius": 0.2, "order": 0, "branch": 0},
   {"id": 1, "parent": 0, "x": 10, "y": 20, "z": 1.5, "radius": 0.16, "order": 0, "branch": 0},
   {"id": 2, "parent": 1, "x": 10, "y": 20, "z": 3, "radius": 0.1, "order": 0, "branch": 0},
   {"id": 3, "parent": 1, "x": 11, "y": 20, "z": 2.5, "radius": 0.05, "order": 1, "branch": 1},
   {"id": 4, "parent": 3, "x": 11.5, "y": 20.2, "z": 3, "radius": 0.01, "order": 1, "branch": 1},
   {"id": 5, "parent": 4, "x": 11.6, "y": 20.2, "z": 3.3, "radius": 0.005, "order": 2, "branch": 2}
  ]}]}
JSON

# Truth vs itself: every skeleton key, recall and precision 1.
json=$("$SYLVA" eval --json --truth "$TMP/truth.json" "$TMP/truth.json") || fail "truth vs itself exited $?"
for key in recall precision recall_r2cm precision_r2cm recall_order0 recall_order1 radius_error_median \
           bifurcation_error_mean dbh_error height_error; do
  echo "$json" | grep -q "\"$key\":" || fail "key $key missing: $json"
done
echo "$json" | grep -q '"recall":1,' || fail "recall is not 1: $json"
echo "$json" | grep -q '"precision":1,' || fail "precision is not 1: $json"
echo "$json" | grep -q '"dbh_error":0,' || fail "dbh_error is not 0: $json"
echo "$json" | grep -q '"mean_distance"' && fail "surface keys in a skeleton report: $json"
echo "$json" | grep -q '"recall_order3"' && fail "recall_order3 reported without order-3 branches: $json"

# A skeleton JSON shifted by 1 m in x finds nothing.
sed 's/"x": 1\([01]\)/"x": 2\1/g; s/"x": 11.\([56]\)/"x": 21.\1/g' "$TMP/truth.json" | \
  sed 's/"format": "sylva-truth", //' >"$TMP/far.json"
json=$("$SYLVA" eval --json --truth "$TMP/truth.json" "$TMP/far.json") || fail "far skeleton exited $?"
echo "$json" | grep -q '"recall":0,' || fail "far skeleton recall is not 0: $json"

# Human summary fits one screen.
"$SYLVA" eval --truth "$TMP/truth.json" "$TMP/truth.json" >"$TMP/summary" || fail "summary exited $?"
grep -q 'recall' "$TMP/summary" || fail "summary lacks recall"
[ "$(wc -l <"$TMP/summary")" -le 25 ] || fail "summary longer than a screen"

# Points vs a skeleton model (the cones of the truth skeleton): every surface key present.
json=$("$SYLVA" eval --json --points "$MC" "$TMP/truth.json") || fail "points vs skeleton exited $?"
for key in mean_distance rms_distance p95_distance coverage coverage_eps hausdorff hausdorff_model_to_points; do
  echo "$json" | grep -q "\"$key\":" || fail "key $key missing: $json"
done

# Segmentation of MixedConifer against itself.
json=$("$SYLVA" eval --json --segmentation "$MC" "$MC") || fail "segmentation exited $?"
echo "$json" | grep -q '"f1":1,' || fail "segmentation F1 is not 1: $json"
echo "$json" | grep -q '"truth_instances":205' || fail "205 trees expected: $json"
# Standard LAS fields name labels too: MixedConifer's classes 1, 2 and 11 are
# three instances; none overlaps one tree by IoU > 0.5 (class 1 holds 31,832
# of the 37,657 points).
json=$("$SYLVA" eval --json --segmentation "$MC" "$MC" --truth-attr classification --pred-attr classification) ||
  fail "segmentation by classification exited $?"
echo "$json" | grep -q '"truth_instances":3,"pred_instances":3,"matched_instances":3' || fail "classes: $json"
json=$("$SYLVA" eval --json --segmentation "$MC" "$MC" --pred-attr classification) || fail "treeID vs classification exited $?"
echo "$json" | grep -q '"truth_instances":205,"pred_instances":3,"matched_instances":0' || fail "treeID vs classes: $json"

# Species: CSV against CSV, with the PNG.
printf 'id,species\n1,oak\n2,oak\n3,pine\n4,pine\n' >"$TMP/t.csv"
printf 'id,species\n1,oak\n2,pine\n3,pine\n4,pine\n' >"$TMP/p.csv"
json=$("$SYLVA" eval --json --species "$TMP/t.csv" "$TMP/p.csv" --png "$TMP/c.png") || fail "species exited $?"
echo "$json" | grep -q '"accuracy":0.75' || fail "accuracy 0.75 expected: $json"
echo "$json" | grep -q '"macro_f1":0.733' || fail "macro_f1 0.733 expected: $json"
echo "$json" | grep -q '"confusion":\[\[1,1\],\[0,2\]\]' || fail "confusion matrix: $json"
[ "$(head -c 8 "$TMP/c.png" | od -An -c | tr -d ' ')" = "211PNG\r\n032\n" ] || fail "c.png is not a PNG"
json=$("$SYLVA" eval --json --species "$TMP/truth.json" "$TMP/truth.json") || fail "species from truth exited $?"
echo "$json" | grep -q '"accuracy":1,' || fail "truth vs itself species accuracy: $json"

# Bad inputs: exit 2, one stderr line naming the file, nothing on stdout.
printf '{"trees": [' >"$TMP/cut.json"
printf 'not a model' >"$TMP/model.obj"
printf 'glTF\2\0\0\0' >"$TMP/bad.glb"
printf 'id,species\n1,a,b\n' >"$TMP/bad.csv"
check_bad() {
  local name=$1; shift
  "$SYLVA" eval "$@" >"$TMP/out" 2>"$TMP/err"
  local rc=$?
  [ "$rc" -eq 2 ] || fail "$name: exit $rc, want 2 ($(cat "$TMP/err"))"
  [ "$(wc -l <"$TMP/err")" -eq 1 ] || fail "$name: want one stderr line, got: $(cat "$TMP/err")"
  [ -s "$TMP/out" ] && fail "$name: wrote to stdout: $(cat "$TMP/out")"
  return 0
}
check_bad "truncated truth" --truth "$TMP/cut.json" "$TMP/truth.json"
grep -q 'cut.json:1:' "$TMP/err" || fail "truncated truth message lacks file:line: $(cat "$TMP/err")"
check_bad "missing model" --truth "$TMP/truth.json" "$TMP/none.json"
check_bad "unknown model kind" --truth "$TMP/truth.json" "$TMP/model.obj"
check_bad "broken glb" --points "$MC" "$TMP/bad.glb"
grep -q 'bad.glb' "$TMP/err" || fail "glb message does not name the file"
check_bad "bad csv" --species "$TMP/bad.csv" "$TMP/t.csv"
check_bad "missing attribute" --segmentation "$MC" "$MC" --pred-attr nope
grep -q "no attribute 'nope'" "$TMP/err" || fail "attribute message: $(cat "$TMP/err")"

# Usage errors exit 1.
"$SYLVA" eval "$TMP/truth.json" 2>/dev/null; [ $? -eq 1 ] || fail "no mode: want exit 1"
"$SYLVA" eval --truth "$TMP/truth.json" --points "$MC" x 2>/dev/null; [ $? -eq 1 ] || fail "two modes: want exit 1"
echo "ok"
