#!/usr/bin/env bash
# Limbs a game artist would ship: no hooks, loops or level crossings on the
# main skeleton's limbs (docs/skeleton.md 6b and 11c). The report's
# limb_kinks counts nodes of limbs >= 2 cm turning more than 60 degrees
# within max(4 radii, 10 cm) on either side.
# - tree1 (AdTree): a limb whose foot the scan misses was reached over a
#   level crossing branch and hung from it in a 90-degree hook 5 cm thick;
#   the hairpin rule now turns it to grow up from the trunk's fork (15 kinks
#   before, unfaired).
# - tree33 (AdTree, leafy): the level sets wander through its leaf clumps
#   and the limbs looped (37 kinks unfaired); fairing over 4 radii leaves 8
#   and the asset covers its scan as well as before.
. "$SYLVA_SOURCE_DIR/tests/measure_cli_common.sh"
data=${SYLVA_DATA_DIR:-$SYLVA_SOURCE_DIR/../shared/data}
adtree=$data/real/adtree
kinks() { jq -r .limb_kinks "$1"; }
for t in tree1 tree33; do
  for f in 0 4; do
    "$SYLVA" run "$adtree/$t.xyz" -o "$tmp/${t}_$f.glb" --fair-limbs $f --json --quiet > "$tmp/${t}_$f.json" ||
      { echo "FAIL: sylva run $t.xyz --fair-limbs $f"; exit 1; }
  done
done
k=$(kinks "$tmp/tree1_0.json")
check "tree1 unfaired: $k kinked limb nodes (<= 13; 15 with the level crossing)" "$k <= 13"
k=$(kinks "$tmp/tree1_4.json"); m=$(jq -r .limb_turn_max "$tmp/tree1_4.json")
check "tree1: $k kinked limb nodes (<= 2), sharpest turn $m degrees (< 75)" "$k <= 2 && $m < 75"
k0=$(kinks "$tmp/tree33_0.json"); k=$(kinks "$tmp/tree33_4.json")
check "tree33: $k kinked limb nodes faired, $k0 unfaired (<= 15 and > 25: the measure fails without it)" \
  "$k <= 15 && $k0 > 25"
# The same crown: fairing moves limbs by a fraction of their reach, and
# the asset still covers the scan (0.619 IoU mean faired, 0.621 unfaired).
for f in 0 4; do
  "$SYLVA" eval --points "$adtree/tree33.xyz" "$tmp/tree33_$f.glb" --json > "$tmp/eval_$f.json" ||
    { echo "FAIL: sylva eval tree33 --fair-limbs $f"; exit 1; }
done
a=$(jq -r .iou_mean "$tmp/eval_4.json"); b=$(jq -r .iou_mean "$tmp/eval_0.json")
check "tree33: IoU mean $a faired, $b unfaired (within 0.03)" "$a >= $b - 0.03"
# Bad values are usage errors naming the option.
check_bad_run "$adtree/tree1.xyz" --fair-limbs -1 fair_sigma
exit $fail
