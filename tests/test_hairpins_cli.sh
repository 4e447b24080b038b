#!/usr/bin/env bash
# Hairpins: where a scan misses a limb's lower part, the shortest paths reach
# it over its top from the next limb, and the trunk chain of AdTree's leaf-off
# tree7 climbs 2.6 m and comes 2.1 m back down another limb, as thick as the
# trunk (6.5 x its reach). The skeleton stage turns such chains round to grow
# up from the wood below them (skeletonize.c, unfold_hairpins): the trunk
# then never falls more than 0.25 m below its highest node and winds under
# 1.8 x its reach; --keep-hairpins leaves them, and the same measures fail.
# Limbs that droop from a stem going on above them are left as they are.
. "$SYLVA_SOURCE_DIR/tests/measure_cli_common.sh"
data=${SYLVA_DATA_DIR:-$SYLVA_SOURCE_DIR/../shared/data}
# The trunk's fall: its highest node's z minus its last node's.
trunk_fall() { jq -r '[.nodes[] | select(.branch == 0) | .z] | (max - .[-1])' "$1"; }
# The trunk's path length over the straight line from its root to its end
# (the report's trunk_meander is the chain as the level sets made it, before
# any turn: the stem rebuild and the crown regrowth judge that one).
trunk_wind() { jq -r '[.nodes[] | select(.branch == 0)] as $t |
  def d($a; $b): (($a.x - $b.x) * ($a.x - $b.x) + ($a.y - $b.y) * ($a.y - $b.y) + ($a.z - $b.z) * ($a.z - $b.z)) | sqrt;
  ([range(1; $t | length) as $i | d($t[$i - 1]; $t[$i])] | add) / d($t[0]; $t[-1])' "$1"; }
for mode in turned kept; do
  flag=; [ $mode = kept ] && flag=--keep-hairpins
  "$SYLVA" skeleton "$data/real/adtree/tree7.xyz" -o "$tmp/$mode.json" --json --quiet $flag > "$tmp/$mode.report" ||
    { echo "FAIL: sylva skeleton tree7.xyz $flag"; exit 1; }
done
n=$(jq -r .hairpins "$tmp/turned.report"); m=$(trunk_wind "$tmp/turned.json")
[[ $n =~ ^[0-9]+$ ]] || { echo "FAIL: tree7: no hairpin count in the report ($n)"; exit 1; }
fall=$(trunk_fall "$tmp/turned.json")
check "tree7: $n hairpins turned" "$n >= 1"
check "tree7: the trunk falls $fall m below its highest node (<= 0.25)" "$fall <= 0.25"
check "tree7: the trunk winds $m x its reach (<= 1.8)" "$m <= 1.8"
n=$(jq -r .hairpins "$tmp/kept.report"); m=$(trunk_wind "$tmp/kept.json")
fall=$(trunk_fall "$tmp/kept.json")
check "tree7 --keep-hairpins: none turned ($n)" "$n == 0"
check "tree7 --keep-hairpins: the trunk falls $fall m, winds $m x (the measures above fail)" "$fall > 0.25 && $m > 1.8"
# Same nodes either way: turning re-links them, it adds and drops none.
a=$(jq '.nodes | length' "$tmp/turned.json"); b=$(jq '.nodes | length' "$tmp/kept.json")
check "tree7: $a nodes turned, $b kept (no node added or dropped)" "$a == $b"
# The TreeLS pine's lower crown droops from a stem that goes on 6 m above:
# none of it is a hairpin (a rule without that guard hung the upper stem from
# the tips of three drooping limbs, and the trunk detoured 1.3 m out).
"$SYLVA" run "$data/real/treels/pine.las" -o "$tmp/pine.glb" --json --quiet > "$tmp/pine.report" ||
  { echo "FAIL: sylva run pine.las"; exit 1; }
n=$(jq -r .hairpins "$tmp/pine.report")
[[ $n =~ ^[0-9]+$ ]] || { echo "FAIL: TreeLS pine: no hairpin count in the report ($n)"; fail=1; n=-1; }
check "TreeLS pine: $n hairpins turned (its drooping limbs stay)" "$n == 0"
exit $fail
