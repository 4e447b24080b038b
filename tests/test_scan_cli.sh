#!/usr/bin/env bash
# CLI checks for `sylva scan`: a labelled LAS and its truth file, the count
# agreeing with `sylva info`, and a bad species leaving nothing behind.
set -u
fail() { echo "FAIL: $*" >&2; exit 1; }
: "${SYLVA:?SYLVA must point at the sylva binary}"
TMP=$(mktemp -d "${TMPDIR:-/tmp}/sylva-scan-XXXXXX")
trap 'rm -rf "$TMP"' EXIT

report=$("$SYLVA" scan quaking_aspen --seed 3 --step 0.3 -o "$TMP/a.las" --truth "$TMP/a.json" --json) \
    || fail "scan exited $?"
count=$(echo "$report" | sed -n 's/.*"point_count":\([0-9]*\).*/\1/p')
[ -n "$count" ] && [ "$count" -gt 1000 ] || fail "no point_count in report: $report"
echo "$report" | grep -q '"trees":1,' || fail "report lacks \"trees\":1: $report"
info=$("$SYLVA" info --json "$TMP/a.las") || fail "info exited $?"
echo "$info" | grep -q "\"point_count\":$count," || fail "info count differs from scan's $count: $info"
for a in treeID speciesID isWood branchID; do
    echo "$info" | grep -q "\"attributes\":\[[^]]*\"$a\"" || fail "attribute $a missing: $info"
done
grep -q '"format":"sylva-truth"' "$TMP/a.json" || fail "truth file lacks its format tag"
grep -q '"species":"quaking_aspen"' "$TMP/a.json" || fail "truth file lacks the species"

# No wood under the terrain: Norway spruce seed 2 grows low limbs that sag
# below its base (Weber & Penn know no ground; 154 nodes); the scene cuts them
# where they meet the ground, and the truth says how many nodes went. (The
# black oak did until stop 28 raised its crown, docs/species.md.)
"$SYLVA" scan norway_spruce --seed 2 --step 5 --no-leaves -o "$TMP/spruce.las" --truth "$TMP/spruce.json" --quiet || fail "scan spruce"
command -v jq > /dev/null || fail "jq missing (run scripts/install-deps.sh)"
jq -e '.trees[0] | .nodes_below_ground > 100 and ([.nodes[].z] | min) >= .position[2] - 0.1' "$TMP/spruce.json" > /dev/null ||
    fail "spruce wood under the ground: $(jq -c '.trees[0] | {below: .nodes_below_ground, min_z: ([.nodes[].z] | min), base: .position}' "$TMP/spruce.json")"
jq -e '.trees[0].nodes | . as $n | all(.[]; .parent == -1 or (.parent >= 0 and .parent < ($n | length)))' "$TMP/spruce.json" > /dev/null ||
    fail "the cut skeleton's parents are not all nodes"

# Same seed: same bytes (the LAS date comes from SOURCE_DATE_EPOCH).
export SOURCE_DATE_EPOCH=1700000000
"$SYLVA" scan quaking_aspen --seed 3 --step 0.5 -o "$TMP/b.las" --quiet --threads 1 || fail "scan b"
"$SYLVA" scan quaking_aspen --seed 3 --step 0.5 -o "$TMP/c.las" --quiet --threads 2 || fail "scan c"
cmp -s "$TMP/b.las" "$TMP/c.las" || fail "--threads 1 and 2 gave different files"

mkdir "$TMP/out"
"$SYLVA" scan no_such_species -o "$TMP/out/x.las" --truth "$TMP/out/x.json" >"$TMP/stdout" 2>"$TMP/err"
rc=$?
[ "$rc" -eq 2 ] || fail "bad species exited $rc, want 2"
[ "$(wc -l <"$TMP/err")" -eq 1 ] || fail "bad species: want one stderr line, got: $(cat "$TMP/err")"
grep -q "no_such_species" "$TMP/err" || fail "message does not name the species: $(cat "$TMP/err")"
[ -z "$(ls -A "$TMP/out")" ] || fail "failing scan left files: $(ls -A "$TMP/out")"

# An unwritable truth path is refused before scanning, and no scan file is left.
"$SYLVA" scan quaking_aspen -o "$TMP/out/y.las" --truth "$TMP/missing/y.json" 2>"$TMP/err"
rc=$?
[ "$rc" -eq 2 ] || fail "unwritable truth path exited $rc, want 2"
grep -q "missing/y.json" "$TMP/err" || fail "message does not name the truth path: $(cat "$TMP/err")"
[ -z "$(ls -A "$TMP/out")" ] || fail "refused scan left files: $(ls -A "$TMP/out")"
# A forest-grown tree among neighbours, clipped to a cylinder round its stem:
# the truth lists the neighbours, the crown is narrower than the open-grown
# tree's of the same seed, and every point lies within the clip radius.
"$SYLVA" scan european_pine --seed 4 --scanner airborne --density 20 -o "$TMP/open.las" --truth "$TMP/open.json" --quiet \
    || fail "open-grown scan"
"$SYLVA" scan european_pine --seed 4 --scanner airborne --density 20 --forest 1 --neighbours 3 --clip 1.5 \
    -o "$TMP/stand.las" --truth "$TMP/stand.json" --quiet || fail "forest-grown scan exited $?"
[ "$(grep -o '"tree_id":' "$TMP/stand.json" | wc -l)" -eq 4 ] || fail "want 4 trees (3 neighbours) in the truth"
width() { sed -n 's/.*"crown_width":\([0-9.e+-]*\).*/\1/p' "$1" | head -1; }
awk -v o="$(width "$TMP/open.json")" -v f="$(width "$TMP/stand.json")" 'BEGIN { exit !(f < 0.6 * o) }' \
    || fail "forest-grown crown $(width "$TMP/stand.json") m is not narrower than the open-grown $(width "$TMP/open.json") m"
"$SYLVA" convert "$TMP/stand.las" -o "$TMP/stand.xyz" >/dev/null 2>&1 || fail "convert the clipped scan"
awk '!/^\/\// { n++; if ($1 * $1 + $2 * $2 > 1.5 * 1.5 + 1e-3) bad++ } END { exit !(n > 50 && bad == 0) }' "$TMP/stand.xyz" \
    || fail "clipped scan has points outside 1.5 m of the stem (or too few points)"
# --isolate keeps the first tree's own points (and ground): no neighbour's.
"$SYLVA" scan european_pine --seed 4 --scanner airborne --density 20 --forest 0.5 --neighbours 3 --isolate \
    -o "$TMP/iso.las" --quiet || fail "isolated scan exited $?"
"$SYLVA" convert "$TMP/iso.las" -o "$TMP/iso.xyz" >/dev/null 2>&1 || fail "convert the isolated scan"
awk 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "treeID") col = i }
     NR > 1 { n++; if ($col == 1) own++; else if ($col != 0) bad++ }
     END { exit !(col > 0 && own > 50 && bad == 0) }' "$TMP/iso.xyz" \
    || fail "isolated scan holds other trees' points (or none of its own)"
for bad in "--forest 1.5" "--neighbours 13" "--clip 0" "--plot 10 --neighbours 2"; do
    # shellcheck disable=SC2086
    "$SYLVA" scan european_pine $bad -o "$TMP/out/z.las" --quiet 2>"$TMP/err"
    rc=$?
    [ "$rc" -eq 1 ] || fail "scan $bad exited $rc, want 1 (usage)"
    [ "$(wc -l <"$TMP/err")" -eq 1 ] || fail "scan $bad: want one stderr line, got: $(cat "$TMP/err")"
    [ -z "$(ls -A "$TMP/out")" ] || fail "scan $bad left files"
done
echo "ok"
