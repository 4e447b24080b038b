#!/usr/bin/env bash
# An occluded conifer stem: the simulated terrestrial scan of the dense
# balsam fir shows the scanner the crown's shell and hardly any stem. Its
# trunk must still come out straight and on the crown's axis (the geodesic
# skeleton alone spiralled up the shell: 2.6 m off the axis, DBH 1.31 m for
# 0.376 m), with a DBH near the truth; the other samples, whose trunks the
# scan does show, keep their stems and stay within their current errors.
. "$SYLVA_SOURCE_DIR/tests/measure_cli_common.sh"
s="$SYLVA_SOURCE_DIR/samples"
truth() { jq -r ".trees[0].$2" "$s/$1.json"; }

# The skeleton stage on the fir: rebuilt stem, straight order-0 chain, DBH.
"$SYLVA" skeleton "$s/fir_tls.las" -o "$tmp/fir.json" --json --quiet > "$tmp/fir.report" ||
  { echo "FAIL: sylva skeleton fir_tls.las"; exit 1; }
H=$(truth fir_tls height); D=$(truth fir_tls dbh)
rebuilt=$(jq -r .stem_rebuilt "$tmp/fir.report"); dbh=$(jq -r .dbh "$tmp/fir.report")
[ "$rebuilt" = true ] && echo "ok: fir_tls stem rebuilt on the crown's axis" ||
  { echo "FAIL: fir_tls stem not rebuilt (stem_rebuilt $rebuilt)"; fail=1; }
# Largest horizontal distance of an order-0 node from the line through the
# root and the highest order-0 node: a straight stem stays within a few
# centimetres of it, the helix went 2.6 m out.
dev=$(jq -r '[.nodes[] | select(.order == 0)] as $t | ($t | min_by(.z)) as $a | ($t | max_by(.z)) as $b |
  [$t[] | ((if $b.z > $a.z then (.z - $a.z) / ($b.z - $a.z) else 0 end) as $f |
    ((.x - $a.x - $f * ($b.x - $a.x)) * (.x - $a.x - $f * ($b.x - $a.x)) +
     (.y - $a.y - $f * ($b.y - $a.y)) * (.y - $a.y - $f * ($b.y - $a.y))) | sqrt)] | max' "$tmp/fir.json")
top=$(jq -r '[.nodes[] | select(.order == 0) | .z] | (max - min)' "$tmp/fir.json")
check "fir_tls trunk straight: largest excursion $dev m <= 2% of the $H m height" "$dev <= 0.02 * $H"
check "fir_tls trunk spans $top m of the $H m tree (>= 85%)" "$top >= 0.85 * $H"
# The limbs grow from the stem into the crown's returns (space colonisation),
# one short step at a time: the geodesic branches hung from the rebuilt stem
# at their own heights were spokes across the crown (longest edge 2.99 m).
edge=$(jq -r '.nodes as $n | [$n[] | select(.parent >= 0) | . as $c | $n[$c.parent] as $p |
  (($c.x - $p.x) * ($c.x - $p.x) + ($c.y - $p.y) * ($c.y - $p.y) + ($c.z - $p.z) * ($c.z - $p.z)) | sqrt] | max' "$tmp/fir.json")
check "fir_tls no spokes: longest skeleton edge $edge m <= 1.5 m" "$edge <= 1.5"
check "fir_tls skeleton DBH $dbh m within 25% of the true $D m" "$dbh >= 0.75 * $D && $dbh <= 1.25 * $D"

# The airborne scan of the same fir sees the crown from above and no stem:
# the trunk chain zig-zagged 1.9 m off the axis, DBH 0.686 m from the
# fallback. Since stop 25 a scan this coarse (0.34 m spacing) gets the unseen
# stem of docs/skeleton.md 8d (tests/test_airborne_cli.sh scores its run).
"$SYLVA" skeleton "$s/fir_als.las" -o "$tmp/fir_als.json" --json --quiet > "$tmp/fir_als.report" ||
  { echo "FAIL: sylva skeleton fir_als.las"; exit 1; }
r=$(jq -r .stem_unseen "$tmp/fir_als.report"); d=$(jq -r .dbh "$tmp/fir_als.report")
[ "$r" = true ] && echo "ok: fir_als stem drawn as unseen" || { echo "FAIL: fir_als stem not drawn as unseen"; fail=1; }
check "fir_als DBH $d m within 25% of the true $D m" "$d >= 0.75 * $D && $d <= 1.25 * $D"

# The whole run: the asset's stem, scored against the truth.
"$SYLVA" run "$s/fir_tls.las" -o "$tmp/fir.glb" --sylva "$tmp/fir.sylva" --json > "$tmp/run.json" ||
  { echo "FAIL: sylva run fir_tls.las"; exit 1; }
"$SYLVA" eval --truth "$s/fir_tls.json" "$tmp/fir.sylva" --json > "$tmp/eval.json" || { echo "FAIL: eval"; fail=1; }
derr=$(jq -r .dbh_error "$tmp/eval.json"); herr=$(jq -r .height_error "$tmp/eval.json")
check "fir_tls run DBH error $derr m within 25% of $D m" "($derr < 0 ? -$derr : $derr) <= 0.25 * $D"
check "fir_tls run height error $herr m within 5% of $H m" "($herr < 0 ? -$herr : $herr) <= 0.05 * $H"

# The other samples keep their stems (no rebuild) and their DBH and height
# within the errors they had before the occluded-stem step (measured with
# `sylva skeleton`: aspen_tls 0.307 m vs 0.307, palm_tls 0.184 vs 0.307,
# aspen_als 0.682, palm_als 0.981: ALS sees no stem, the fallback is wide).
while read -r name dmax hmax; do
  "$SYLVA" skeleton "$s/$name.las" -o "$tmp/$name.json" --json --quiet > "$tmp/$name.report" ||
    { echo "FAIL: sylva skeleton $name.las"; fail=1; continue; }
  r=$(jq -r .stem_rebuilt "$tmp/$name.report")
  [ "$r" = false ] && echo "ok: $name stem kept" || { echo "FAIL: $name stem rebuilt"; fail=1; }
  d=$(jq -r .dbh "$tmp/$name.report"); h=$(jq -r .height "$tmp/$name.report")
  td=$(truth "$name" dbh); th=$(truth "$name" height)
  check "$name DBH $d m vs $td m: error within $dmax" "($d - $td < 0 ? $td - $d : $d - $td) <= $dmax * $td"
  check "$name height $h m vs $th m: error within $hmax" "($h - $th < 0 ? $th - $h : $h - $th) <= $hmax * $th"
done <<'EOF'
aspen_tls 0.05 0.03
palm_tls 0.45 0.03
aspen_als 1.30 0.03
palm_als 2.30 0.03
EOF
# The palm's trunk chain runs up its bole and out along a frond (meander 1.6):
# its crown is regrown, but above the bole. Its root (the lowest return) lies
# 0.9 m off the stem, and a crown base measured from the root put the base at
# the ground: the whole palm regrown as a crown, its DBH no longer fitted.
rg=$(jq -r .crown_regrown "$tmp/palm_tls.report"); cb=$(jq -r '.crown_base // 0' "$tmp/palm_tls.report")
ph=$(jq -r .height "$tmp/palm_tls.report"); pf=$(jq -r .dbh_fitted "$tmp/palm_tls.report")
if [ "$rg" = true ]; then
  check "palm_tls crown regrown above its bole: base $cb m >= 0.6 x $ph m" "$cb >= 0.6 * $ph"
fi
[ "$pf" = true ] && echo "ok: palm_tls DBH fitted" || { echo "FAIL: palm_tls DBH not fitted"; fail=1; }
# A broadleaf whose bole the scan shows under a crown that starts higher up:
# its trunk chain strays from the crown's axis because the trunk divides
# among the limbs, and rebuilding it made a pole with spokes (sassafras, the
# crown radius 0.3-0.4 m at the foot under a 3.9 m crown). The stem stays.
"$SYLVA" scan sassafras --seed 1 --scanner terrestrial --step 0.4 -o "$tmp/sass_raw.las" --truth "$tmp/sass.truth" \
  --quiet > /dev/null || { echo "FAIL: sylva scan sassafras"; exit 1; }
"$SYLVA" preprocess "$tmp/sass_raw.las" -o "$tmp/sass.las" --remove-ground --no-normals --quiet ||
  { echo "FAIL: sylva preprocess sassafras"; exit 1; }
"$SYLVA" skeleton "$tmp/sass.las" -o "$tmp/sass.json" --json --quiet > "$tmp/sass.report" ||
  { echo "FAIL: sylva skeleton sassafras"; exit 1; }
r=$(jq -r .stem_rebuilt "$tmp/sass.report"); d=$(jq -r .dbh "$tmp/sass.report"); td=$(jq -r '.trees[0].dbh' "$tmp/sass.truth")
[ "$r" = false ] && echo "ok: sassafras stem kept (its bole is in view)" || { echo "FAIL: sassafras stem rebuilt"; fail=1; }
check "sassafras DBH $d m within 5% of the true $td m" "$d >= 0.95 * $td && $d <= 1.05 * $td"
# A domed broadleaf whose low limbs hide its stem: the simulated black oak of the library until
# stop 28 (tests/data/species/black_oak_low_crown.ini)
# (seed 1; the crown reaches the ground, almost no bark in view) passes every
# test of an occluded stem, but above its widest part the crown holds its
# radius (0.75 of the widest on average) where a cone's falls away (the fir's
# 0.59). Its trunk divides inside the crown, so the rebuilt stem stops where
# the widest part ends and the limbs spread from there. Run to the top it was
# a straight pole through the dome (12 order-0 nodes above 0.55 H within 2 %
# of the height of its line): an oak drawn as a spruce.
oak_ini="$SYLVA_SOURCE_DIR/tests/data/species/black_oak_low_crown.ini" # the pre-stop-28 oak (its header says why)
"$SYLVA" scan "$oak_ini" --seed 1 --scanner terrestrial --step 0.6 -o "$tmp/oak_raw.las" --quiet > /dev/null ||
  { echo "FAIL: sylva scan black_oak"; exit 1; }
"$SYLVA" preprocess "$tmp/oak_raw.las" -o "$tmp/oak.las" --remove-ground --no-normals --quiet ||
  { echo "FAIL: sylva preprocess black_oak"; exit 1; }
"$SYLVA" skeleton "$tmp/oak.las" -o "$tmp/oak.json" --json --quiet > "$tmp/oak.report" ||
  { echo "FAIL: sylva skeleton black_oak"; exit 1; }
r=$(jq -r .stem_rebuilt "$tmp/oak.report"); H=$(jq -r .height "$tmp/oak.report"); fork=$(jq -r .stem_fork "$tmp/oak.report")
[ "$r" = true ] && echo "ok: black_oak stem rebuilt (hidden by its low limbs)" || { echo "FAIL: black_oak stem not rebuilt"; fail=1; }
check "black_oak rebuilt stem ends at $fork m, within 0.25-0.5 of the $H m height" "$fork >= 0.25 * $H && $fork <= 0.5 * $H"
# Order-0 nodes above 0.55 H that still stand on the line of the stem's lower
# quarter (within 2 % of the height): a pole through the crown.
pole=$(jq -r --argjson H "$H" '[.nodes[] | select(.order == 0)] as $t | ($t | min_by(.z)) as $a |
  ($t | map(select(.z - $a.z <= 0.25 * $H)) | max_by(.z)) as $b |
  [$t[] | select(.z - $a.z > 0.55 * $H) | ((.z - $a.z) / ($b.z - $a.z)) as $f |
    (((.x - $a.x - $f * ($b.x - $a.x)) | . * .) + ((.y - $a.y - $f * ($b.y - $a.y)) | . * .)) | sqrt |
    select(. < 0.02 * $H)] | length' "$tmp/oak.json")
check "black_oak no pole through the dome: $pole order-0 nodes above 0.55 H on the stem's line (0)" "$pole == 0"
exit $fail
