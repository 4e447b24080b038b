#!/usr/bin/env bash
# Radii the returns bound (docs/skeleton.md 11d, radii.c): AdTree's tree7
# forks about a metre up into a vase of thin stems, and the trunk chain
# running up its middle took its radius from the pipe model, a pole twice
# as thick as the returns round it show. With the cap the trunk over 30-70 %
# of the height was a fifth thinner (mean radius 0.064 -> 0.052 m; its returns
# lie 0.02-0.04 m from the chain), the trunk below breast height (the DBH
# fit's) is kept, no radius grows toward a tip, and the asset covers its scan
# as well as before. --return-cap 0 turns it off; a negative value is a usage
# error naming the option, and leaves no file.
. "$SYLVA_SOURCE_DIR/tests/measure_cli_common.sh"
data=${SYLVA_DATA_DIR:-$SYLVA_SOURCE_DIR/../shared/data}
scan=$data/real/adtree/tree7.xyz
for cap in 0 2; do
  "$SYLVA" run "$scan" -o "$tmp/c$cap.glb" --sylva "$tmp/c$cap.sylva" --return-cap $cap --json --quiet > "$tmp/c$cap.json" ||
    { echo "FAIL: sylva run tree7.xyz --return-cap $cap"; exit 1; }
  "$SYLVA" decode "$tmp/c$cap.sylva" -o "$tmp/c$cap.tree.json" > /dev/null || { echo "FAIL: decode"; exit 1; }
done
n=$(jq -r .radii_capped "$tmp/c2.json"); n0=$(jq -r .radii_capped "$tmp/c0.json")
check "edges capped: $n (> 5), $n0 with the cap off (0)" "$n > 5 && $n0 == 0"
# The trunk (branch 0) at a share of the tree's height above its root.
trunk_r() {
  jq -r --argjson f "$2" '.nodes as $n | ($n[0].z) as $z0 | ([$n[].z] | max) as $top |
    [$n[] | select(.branch == 0)] | min_by((.z - $z0 - $f * ($top - $z0)) | fabs) | .radius' "$1"
}
# The trunk over 30-70 % of the height, mean radius.
mid() { local t=0; for f in 0.3 0.4 0.5 0.6 0.7; do t=$(awk -v t="$t" -v r="$(trunk_r "$1" $f)" 'BEGIN { print t + r / 5 }'); done; echo "$t"; }
off=$(mid "$tmp/c0.tree.json"); on=$(mid "$tmp/c2.tree.json")
# Since the stem's foot is kept (stop 41: the ground filter had cut 25 cm of
# it) breast height lies below the fork and the DBH fit is 0.105 m, not
# 0.166: the uncapped chain is 0.043 m there, no longer a pole twice as thick
# as its returns (median 0.025-0.035 m from it at 30-50 %), and the cap
# trims less of it (0.037 m; 0.052 m against 0.064 m before).
check "trunk over 30-70 % of the height: $on m capped, $off m not (at most 0.9 of it, and 0.045 m)" \
  "$on <= 0.9 * $off && $on <= 0.045"
# Unfaired (the fairing smooths radii along each limb and would hide both):
# the trunk below breast height (a quarter of this short tree's height)
# keeps the DBH fit's radii, and the cap's own pass lets no radius grow
# toward a tip.
for cap in 0 2; do
  "$SYLVA" run "$scan" -o "$tmp/u$cap.glb" --sylva "$tmp/u$cap.sylva" --return-cap $cap --fair-limbs 0 --quiet ||
    { echo "FAIL: sylva run tree7.xyz --return-cap $cap --fair-limbs 0"; exit 1; }
  "$SYLVA" decode "$tmp/u$cap.sylva" -o "$tmp/u$cap.tree.json" > /dev/null || { echo "FAIL: decode"; exit 1; }
done
low() { jq -c '.nodes as $n | ($n[0].z) as $z0 | ([$n[].z] | max) as $top |
  [$n[] | select(.branch == 0 and .z < $z0 + 0.25 * ($top - $z0)) | .radius]' "$1"; }
a=$(low "$tmp/u0.tree.json"); b=$(low "$tmp/u2.tree.json")
same=$([[ "$a" == "$b" && ${#a} -gt 20 ]] && echo 1 || echo 0)
check "trunk below breast height unchanged by the cap: $same (1)" "$same == 1"
grows=$(jq -r '.nodes as $n | [$n[] | select(.parent >= 0 and .radius > $n[.parent].radius + 1e-6)] | length' \
  "$tmp/u2.tree.json")
check "radii growing toward a tip, unfaired: $grows (0)" "$grows == 0"
for cap in 0 2; do
  "$SYLVA" eval --points "$scan" "$tmp/c$cap.glb" --json > "$tmp/e$cap.json" || { echo "FAIL: eval"; exit 1; }
done
a=$(jq -r .iou_mean "$tmp/e2.json"); b=$(jq -r .iou_mean "$tmp/e0.json")
check "IoU mean $a capped, $b not (no lower by more than 0.01)" "$a >= $b - 0.01"
check_bad_run "$scan" --return-cap -1 return_cap
exit $fail
