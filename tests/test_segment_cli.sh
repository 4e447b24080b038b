#!/usr/bin/env bash
# `sylva segment` end to end: a simulated plot (`sylva scan --plot`) goes in,
# a LAS with treeID comes out that `sylva eval --segmentation` scores against
# the scan's own treeID; --split writes one file per tree and the table,
# atomically; --json accounts for every point; hostile inputs exit 2 and leave
# nothing behind; lidR's MixedConifer (airborne) segments by the canopy.
set -u
: "${SYLVA:?SYLVA must name the sylva binary}"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
num() { sed -E "s/.*\"$1\":(-?[0-9.eE+-]+).*/\1/" "$2"; }

"$SYLVA" scan --plot 14 --trees 5 --species quaking_aspen,european_pine --seed 11 --step 0.3 --subrays 1 \
  --divergence 0 -o "$tmp/plot.las" --quiet || fail "sylva scan failed"

# Usage errors exit 1 and write nothing.
"$SYLVA" segment "$tmp/plot.las" 2>/dev/null
[ $? -eq 1 ] || fail "a missing -o must exit 1"
"$SYLVA" segment "$tmp/plot.las" -o "$tmp/bad.las" --method lidar 2>/dev/null
[ $? -eq 1 ] || fail "--method lidar must exit 1"
"$SYLVA" segment "$tmp/plot.las" -o "$tmp/bad.las" --voxel 0 2>"$tmp/err"
[ $? -eq 1 ] || fail "--voxel 0 must exit 1"
grep -q voxel "$tmp/err" || fail "the message must name the option: $(cat "$tmp/err")"
[ ! -e "$tmp/bad.las" ] || fail "a usage error left an output"

# The labelled plot, scored against the truth.
"$SYLVA" segment "$tmp/plot.las" -o "$tmp/pred.las" --json >"$tmp/seg.json" 2>"$tmp/err" || fail "segment failed: $(cat "$tmp/err")"
n=$(num point_count "$tmp/seg.json"); g=$(num ground_points "$tmp/seg.json"); u=$(num unassigned_points "$tmp/seg.json")
t=$(num tree_points "$tmp/seg.json"); trees=$(num tree_count "$tmp/seg.json")
[ $((t + g + u)) -eq "$n" ] || fail "points do not add up: $t + $g + $u != $n"
[ "$trees" -ge 4 ] && [ "$trees" -le 6 ] || fail "expected about 5 trees, got $trees"
grep -q '"method":"terrestrial"' "$tmp/seg.json" || fail "a TLS plot must take the terrestrial method"
sum=$(grep -o '"points":[0-9]*' "$tmp/seg.json" | awk -F: '{s += $2} END {print s}')
[ "$sum" -eq "$t" ] || fail "the trees' points ($sum) are not the tree points ($t)"
"$SYLVA" info "$tmp/pred.las" | grep -q treeID || fail "the output has no treeID"
"$SYLVA" eval --segmentation "$tmp/plot.las" "$tmp/pred.las" --json >"$tmp/eval.json" || fail "eval failed"
f1=$(num f1 "$tmp/eval.json")
awk -v f="$f1" 'BEGIN {exit !(f >= 0.8)}' || fail "F1 $f1 < 0.8 on a simulated TLS plot"
grep -q '"over_segmented"' "$tmp/eval.json" || fail "eval must count over-segmentation"

# Deterministic: the same bytes again, on one thread.
"$SYLVA" segment "$tmp/plot.las" -o "$tmp/pred1.las" --threads 1 --quiet >/dev/null || fail "second run failed"
cmp -s "$tmp/pred.las" "$tmp/pred1.las" || fail "two runs differ"

# --split: one LAS per tree and the table, in a folder made atomically.
"$SYLVA" segment "$tmp/plot.las" -o "$tmp/trees" --split >"$tmp/table.txt" || fail "--split failed"
[ -f "$tmp/trees/trees.csv" ] || fail "no trees.csv"
[ "$(ls "$tmp/trees" | grep -c '^tree_.*\.las$')" -eq "$trees" ] || fail "not one file per tree: $(ls "$tmp/trees")"
[ "$(($(wc -l <"$tmp/trees/trees.csv") - 1))" -eq "$trees" ] || fail "trees.csv rows != trees"
head -1 "$tmp/trees/trees.csv" | grep -q '^id,x,y,z,height,dbh,crown_width,points,file$' || fail "trees.csv header"
grep -q "dbh" "$tmp/table.txt" || fail "the table is not printed"
first=$(ls "$tmp/trees" | grep '^tree_' | head -1)
pts=$("$SYLVA" info "$tmp/trees/$first" | awk '/points/ {print $2; exit}')
want=$(awk -F, -v f="$first" '$9 == f {print $8}' "$tmp/trees/trees.csv")
[ "$pts" = "$want" ] || fail "$first holds $pts points, the table says $want"
# A rerun replaces its own folder; a folder of something else is refused.
"$SYLVA" segment "$tmp/plot.las" -o "$tmp/trees" --split --quiet >/dev/null || fail "rerun over its own folder failed"
mkdir "$tmp/mine" && echo keep >"$tmp/mine/notes.txt"
"$SYLVA" segment "$tmp/plot.las" -o "$tmp/mine" --split 2>"$tmp/err"
[ $? -eq 2 ] || fail "replacing a foreign folder must exit 2"
[ -f "$tmp/mine/notes.txt" ] || fail "a foreign folder was touched"
[ -z "$(ls -A "$tmp" | grep '^\.')" ] || fail "temp folders left behind: $(ls -A "$tmp")"

# Hostile inputs: exit 2, one line naming the file, no output.
: >"$tmp/empty.xyz"
"$SYLVA" segment "$tmp/empty.xyz" -o "$tmp/empty.las" 2>"$tmp/err"
[ $? -eq 2 ] || fail "an empty plot must exit 2"
grep -q "empty.xyz" "$tmp/err" || fail "the error must name the input: $(cat "$tmp/err")"
[ ! -e "$tmp/empty.las" ] || fail "an empty plot left an output"
echo "1 2 3" >"$tmp/one.xyz"
"$SYLVA" segment "$tmp/one.xyz" -o "$tmp/one.las" --json >"$tmp/one.json" || fail "one point must segment (to no tree)"
[ "$(num tree_count "$tmp/one.json")" -eq 0 ] || fail "one point is no tree"
awk 'BEGIN {for (i = 0; i < 100; i++) for (j = 0; j < 100; j++) printf "%.2f %.2f 0\n", i * 0.1, j * 0.1}' >"$tmp/flat.xyz"
"$SYLVA" segment "$tmp/flat.xyz" -o "$tmp/flat.las" --json >"$tmp/flat.json" || fail "a flat cloud must segment"
[ "$(num tree_count "$tmp/flat.json")" -eq 0 ] || fail "a flat cloud has no trees"

# Airborne: lidR's MixedConifer by the canopy watershed, scored against its treeID.
mc=${SYLVA_DATA_DIR:-../shared/data}/real/lidr/MixedConifer.las
if [ -f "$mc" ]; then
  "$SYLVA" segment "$mc" -o "$tmp/mc.las" --json >"$tmp/mc.json" || fail "MixedConifer failed"
  grep -q '"method":"airborne"' "$tmp/mc.json" || fail "MixedConifer must take the airborne method"
  "$SYLVA" eval --segmentation "$mc" "$tmp/mc.las" --json >"$tmp/mce.json" || fail "MixedConifer eval failed"
  f1=$(num f1 "$tmp/mce.json")
  awk -v f="$f1" 'BEGIN {exit !(f >= 0.5)}' || fail "MixedConifer F1 $f1 < 0.5"
else
  echo "skip: $mc not present"
fi
echo "ok: segment CLI"
