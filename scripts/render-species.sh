#!/usr/bin/env bash
# Regenerates the species pictures in docs/pictures/ (docs/species.md, docs/mesh.md):
# every library species grown with seed 1 and drawn by three.js in headless Chromium
# (tests/three/render_glb.mjs) at LOD0 and every coarser level, side by side, every species'
# main junction close up (bark only), and bark-only junction close-ups of the rTwig QSM and of
# quaking aspen.
# Usage: bash scripts/render-species.sh [path/to/sylva]   (default build/sylva)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
SYLVA=$(realpath "${1:-$here/build/sylva}")
out="$here/docs/pictures"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$out"
render() { node --experimental-websocket "$here/tests/three/render_glb.mjs" "$@"; }
names=$(awk -F'\t' '!/^#/ && NF >= 5 {print $2}' "$here/species/library.tsv")
files=()
for sp in $names; do
    "$SYLVA" grow --species "$sp" --seed 1 -o "$tmp/$sp.glb" --impostor-size 256 --quiet
    files+=("$tmp/$sp.glb")
done
render --lod all --size 300 --png "$tmp/" "${files[@]}" > "$tmp/verdicts.jsonl"
for sp in $names; do
    shots=$(ls "$tmp/${sp}"_lod*_persp.png | sort)
    montage $shots -tile "$(echo "$shots" | wc -l)x1" -geometry 300x300+1+1 -background '#b9cfe0' \
        "$out/${sp}_lods.png"
done
# Every species at LOD0 with its crown spread over its height, as tests/test_species_habit.c
# measures it, beside the published figure (docs/species.md, "Habit against descriptions").
declare -A published=([balsam_fir]=0.33 [black_oak]="0.5-1.0" [european_pine]="0.5-0.8" [lombardy_poplar]=0.2
    [london_plane]="0.8-1.0" [palm]="6-12 m" [quaking_aspen]="0.33-0.5" [sassafras]=0.7 [silver_birch]="0.5-0.6"
    [sugar_maple]="0.7-1.0" [weeping_willow]=1.0 [norway_spruce]="0.3-0.55" [european_beech]=0.75)
habit=$("$here/build/tests/test_species_habit" 2>/dev/null | grep ' seed 1:' || true)
tiles=()
for sp in $names; do
    spread=$(echo "$habit" | awk -v s="$sp" '$1 == s { for (i = 1; i <= NF; i++) if ($i == "spread") print $(i + 1) }')
    convert "$tmp/${sp}_lod0_persp.png" -gravity south -background '#b9cfe0' -splice 0x34 -font DejaVu-Sans \
        -pointsize 13 -annotate +0+18 "$sp" -annotate +0+2 "spread ${spread:-?} (published ${published[$sp]:-?})" \
        "$tmp/h_$sp.png"
    tiles+=("$tmp/h_$sp.png")
done
montage "${tiles[@]}" -tile 7x -geometry +1+1 -background '#b9cfe0' "$out/species_habits.png"
# Every species' main junction (its stiffest limb leaving the trunk, tests/three/junction_at.mjs),
# bark only, in one labelled montage.
tiles=()
for sp in $names; do
    at=$(node "$here/tests/three/junction_at.mjs" "$tmp/$sp.glb")
    render --view close --bark-only 1 --size 300 --at "$at" --png "$tmp/jn_" "$tmp/$sp.glb" > /dev/null
    convert "$tmp/jn_${sp}_lod0_close.png" -gravity south -background '#b9cfe0' -splice 0x18 \
        -font DejaVu-Sans -pointsize 14 -annotate +0+2 "$sp" "$tmp/jl_$sp.png"
    tiles+=("$tmp/jl_$sp.png")
done
montage "${tiles[@]}" -tile 7x -geometry +1+1 -background '#b9cfe0' "$out/junctions_species.png"
# Junction close-ups, bark only (glTF frame: y up; the QSM's first limb leaves the trunk at
# 1.34 m, the aspen's first limbs at about 5 m).
"$SYLVA" mesh "$here/../shared/data/real/rtwig/QSM.csv" -o "$tmp/qsm.glb" --species quaking_aspen --quiet
render --view close --bark-only 1 --size 400 --at 0.04,1.34,-0.08,0.15 --png "$tmp/j_" "$tmp/qsm.glb" > /dev/null
cp "$tmp/j_qsm_lod0_close.png" "$out/junction_qsm.png"
render --view close --bark-only 1 --size 400 --at -0.1,5.1,0.05,0.5 --png "$tmp/j_" "$tmp/quaking_aspen.glb" > /dev/null
cp "$tmp/j_quaking_aspen_lod0_close.png" "$out/junction_aspen.png"
echo "wrote $(ls "$out" | wc -l) pictures to $out"
