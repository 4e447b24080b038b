#!/usr/bin/env bash
# Airborne scans (docs/skeleton.md 8d): the simulated airborne aspen, fir and
# palm see their crowns from above and no stem. `sylva run` must still make
# the whole tree: a stem from the ground (the scan's lowest return stands
# 0.4-9.6 m up), height and DBH near the truth, leaves, and a silhouette
# near the true tree's. Until stop 25 it made the 13.6 m aspen a 4.0 m tree
# with no leaf and the 11.7 m palm a 0.9 m one.
# Measured at stop 25, asset against `sylva grow` of the same species and
# seed (the tree the scan was made from), silhouette IoU mean: aspen 0.615,
# fir 0.761, palm 0.544 (the terrestrial scans of the same trees: 0.84-0.87);
# at stop 26, with the limbs the scan hides grown inside the lobes
# (docs/synthesize.md, the scaffold): 0.812, 0.791, 0.556 (mean 0.720).
# Stop 31 counts alpha-tested leaf cards where their leaves are drawn, not as
# whole quads (docs/eval.md), on both trees: the same assets measure 0.832,
# 0.722, 0.553 (mean 0.703) the old way and 0.807, 0.681, 0.513 (0.667) now,
# so the mean's floor moved from 0.68 to 0.645 (the same share of the mean).
# Stop 49: the palm's stem grows no limbs and tapers by its species, 0.533 -> 0.569;
# with its blocks counting leaf area, not cards (more fronds), 0.575.
. "$SYLVA_SOURCE_DIR/tests/measure_cli_common.sh"
s="$SYLVA_SOURCE_DIR/samples"
sum=0
for sp in quaking_aspen:aspen balsam_fir:fir palm:palm; do
    name=${sp##*:} species=${sp%%:*}
    "$SYLVA" run "$s/${name}_als.las" -o "$tmp/$name.glb" --sylva "$tmp/$name.sylva" --json --impostor-size 64 \
        > "$tmp/$name.run" 2> "$tmp/$name.err" ||
        { echo "FAIL: run ${name}_als: $(tail -1 "$tmp/$name.err")"; fail=1; continue; }
    H=$(jq -r '.trees[0].height' "$s/${name}_als.json"); D=$(jq -r '.trees[0].dbh' "$s/${name}_als.json")
    h=$(jq -r .height "$tmp/$name.run"); d=$(jq -r .dbh "$tmp/$name.run"); leaves=$(jq -r .leaves "$tmp/$name.run")
    [ "$(jq -r .stem_unseen "$tmp/$name.run")" = true ] && echo "ok: ${name}_als stem drawn as unseen" ||
        { echo "FAIL: ${name}_als stem not drawn as unseen"; fail=1; }
    check "${name}_als height $h m within 5% of the true $H m" "$h >= 0.95 * $H && $h <= 1.05 * $H"
    check "${name}_als DBH $d m within 25% of the true $D m" "$d >= 0.75 * $D && $d <= 1.25 * $D"
    check "${name}_als has leaves ($leaves >= 300)" "$leaves >= 300"
    # A crown of fronds: the palm's unseen stem grows no limbs (stop 49).
    # Colonised ones stood as four 7-10 cm stumps round its crown, 6 of its 63
    # LOD0 junctions unwelded, under the fronds laid from the stem's top. The
    # stem tapers by the species' 0Taper (0.3), as its true tree's does
    # (0.157 m at 0.9 m, 0.118 m at 8.6 m): the pipe model over a stem with
    # no limbs ended it at 0.4 of its foot's radius.
    if [ "$name" = palm ]; then
        b=$(jq -r .branches "$tmp/$name.run")
        check "palm_als: the stem alone carries the fronds ($b branch)" "$b == 1"
        "$SYLVA" decode "$tmp/$name.sylva" -o "$tmp/$name.sylva.json" > /dev/null
        taper=$(jq '[.nodes[] | select(.branch == 0)] | (max_by(.z).radius / min_by(.z).radius)' "$tmp/$name.sylva.json")
        check "palm_als: the stem's top is $taper of its foot's radius (0.6-0.8)" "$taper >= 0.6 && $taper <= 0.8"
    fi
    "$SYLVA" grow --species "$species" --seed 1 -o "$tmp/${name}_true.glb" --impostor-size 64 --quiet ||
        { echo "FAIL: grow $species"; fail=1; continue; }
    iou=$("$SYLVA" eval --points "$tmp/${name}_true.glb" "$tmp/$name.glb" --json | jq -r .iou_mean)
    check "${name}_als asset against its true tree: IoU mean $iou >= 0.50" "$iou >= 0.50"
    sum=$(awk -v a="$sum" -v b="$iou" 'BEGIN { print a + b }')
done
check "airborne IoU mean over the three $(awk -v s="$sum" 'BEGIN { printf "%.3f", s / 3 }') >= 0.645" "$sum / 3 >= 0.645"

# A conifer whose skirt reaches the ground (stop 27): the airborne Norway spruce's
# lowest returns stand 0.13 m up, its spacing (0.244 m) is under the 0.3 m of a
# scan that resolves no stem, and until stop 27 its trunk grew from the skirt's
# edge, leaning 8 m across the crown (IoU 0.588 against its true tree). None of
# its lowest returns lies near the crown's axis: its stem is unseen (0.871).
"$SYLVA" scan norway_spruce --seed 1 --scanner airborne --altitude 40 --density 10 -o "$tmp/spruce.las" \
    --truth "$tmp/spruce.json" --quiet || { echo "FAIL: scan the airborne spruce"; fail=1; }
if "$SYLVA" run "$tmp/spruce.las" -o "$tmp/spruce.glb" --json --impostor-size 64 > "$tmp/spruce.run" 2> "$tmp/spruce.err"; then
    [ "$(jq -r .stem_unseen "$tmp/spruce.run")" = true ] && echo "ok: airborne spruce stem drawn as unseen" ||
        { echo "FAIL: airborne spruce stem not drawn as unseen"; fail=1; }
    H=$(jq -r '.trees[0].height' "$tmp/spruce.json"); h=$(jq -r .height "$tmp/spruce.run")
    check "airborne spruce height $h m within 5% of the true $H m" "$h >= 0.95 * $H && $h <= 1.05 * $H"
    "$SYLVA" grow --species norway_spruce --seed 1 -o "$tmp/spruce_true.glb" --impostor-size 64 --quiet
    iou=$("$SYLVA" eval --points "$tmp/spruce_true.glb" "$tmp/spruce.glb" --json | jq -r .iou_mean)
    check "airborne spruce against its true tree: IoU mean $iou >= 0.75" "$iou >= 0.75"
else
    echo "FAIL: run the airborne spruce: $(tail -1 "$tmp/spruce.err")"; fail=1
fi
exit $fail
