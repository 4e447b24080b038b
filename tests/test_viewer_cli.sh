#!/usr/bin/env bash
# sylva view, headless through EGL (llvmpipe here): bad input, the beam against the analytic
# cantilever, wind that stays bounded, moves continuously and comes to rest, back-lit leaves
# with and without translucency (HL2 against the reconstruction of its maps), LOD switching at
# the documented screen coverage with a complementary dithered cross-fade, a 100-tree scene
# under 100 x LOD0 triangles, the silhouette against the projected bounding box, the scan
# overlay in the asset's frame and an animation. Small images: llvmpipe is slow.
set -u
source "$SYLVA_SOURCE_DIR/tests/glb_cli_common.sh"
here="$SYLVA_SOURCE_DIR/tests/viewer"
node "$here/fixtures.mjs" "$tmp"
V() { "$SYLVA" view "$@"; }

# --- bad input: one line, exit 2, no output ---
bad() { # NAME ARGS...
  local name=$1; shift
  V "$@" --screenshot "$tmp/bad.png" --size 64x64 >/dev/null 2>"$tmp/err"; local rc=$?
  check "$name: exit 2 (got $rc)" "[[ $rc == 2 ]]"
  check "$name: one line on stderr" "[[ \$(wc -l <'$tmp/err') == 1 ]] && grep -q 'sylva view: ' '$tmp/err'"
  check "$name: no output file" "[[ ! -e '$tmp/bad.png' ]]"
}
bad "corrupt glb" "$tmp/corrupt.glb"
bad "glb with no meshes" "$tmp/nomesh.glb"
bad "missing texture" "$tmp/missing_texture.gltf"
bad "missing file" "$tmp/nosuch.glb"
bad "absurd size 0x0" "$tmp/beam.glb" --size 0x0
bad "absurd size 99999x99999" "$tmp/beam.glb" --size 99999x99999
bad "camera with NaN" "$tmp/beam.glb" --camera nan,10
bad "scan that is not a scan" "$tmp/beam.glb" --points "$tmp/beam.json"
check "errors name the file" "V '$tmp/corrupt.glb' --screenshot '$tmp/x.png' 2>&1 | grep -q 'corrupt.glb'"
SYLVA_VIEW=/nonexistent/sylva-view "$SYLVA" view "$tmp/beam.glb" --screenshot "$tmp/x.png" 2>"$tmp/err"; rc=$?
check "without the GL viewer: one line, exit 2" "[[ $rc == 2 && \$(wc -l <'$tmp/err') == 1 ]] && grep -q 'no GL' '$tmp/err'"

# --- beam: a steady push bends it like the tapered cantilever (Habel 2009 eq. 4.7) ---
V "$tmp/beam.glb" --dump-wind "$tmp/b1.csv" --static-load --wind-strength 0.2
V "$tmp/beam.glb" --dump-wind "$tmp/b2.csv" --static-load --wind-strength 0.4
check "beam deflection matches the analytic cantilever within 1 %" "node '$here/check.mjs' beam '$tmp/b1.csv' '$tmp/beam.json'"
check "deflection is linear in the load" "node '$here/check.mjs' linear '$tmp/b1.csv' '$tmp/b2.csv' 2"

V "$tmp/fork.glb" --dump-wind "$tmp/fork.csv" --time 1.3 --wind-strength 2
check "children follow their parents: no crack at the fork" "node '$here/check.mjs' fork '$tmp/fork.csv'"

# --- wind on a grown tree: bounded, continuous, back to rest when it stops ---
"$SYLVA" grow --species palm --seed 4 --lods 2 -o "$tmp/palm.glb" --quiet
H=$(V "$tmp/palm.glb" --json --size 64x64 --no-shadows --no-ground | node -e 'const v=JSON.parse(require("fs").readFileSync(0));const t=v.trees[0];console.log(t.bounds_max[1]-t.bounds_min[1])')
V "$tmp/palm.glb" --dump-wind "$tmp/w0.csv" --time 3
V "$tmp/palm.glb" --dump-wind "$tmp/w1.csv" --time 3.004
V "$tmp/palm.glb" --dump-wind "$tmp/w2.csv" --time 12 --wind-stop 4
V "$tmp/palm.glb" --dump-wind "$tmp/ws.csv" --time 60 --wind-strength 3
check "wind moves the tree" "node '$here/check.mjs' moves '$tmp/w0.csv' $H 0.002"
check "wind displacement bounded (strength 3: < 10 % of the height)" "awk -F, 'NR>1{d=sqrt((\$11-\$8)^2+(\$12-\$9)^2+(\$13-\$10)^2); if(d>m)m=d} END{exit !(m < 0.1*$H)}' '$tmp/ws.csv'"
check "wind continuous: 4 ms moves a vertex < 0.2 % of the height" "node '$here/check.mjs' wind '$tmp/w0.csv' '$tmp/w1.csv' $H 0.002"
check "8 s after the wind stops the tree is within 0.1 % of the height of rest" "awk -F, 'NR>1{d=sqrt((\$11-\$8)^2+(\$12-\$9)^2+(\$13-\$10)^2); if(d>m)m=d} END{exit !(m < 0.001*$H)}' '$tmp/w2.csv'"

# --- translucency: a leaf lit from behind (sun behind it, camera in front) ---
leaf=(--size 96x96 --camera 90,0,1.2 --sun 270,30 --no-ground --no-stats --no-wind)
V "$tmp/leaf_hl2.glb" "${leaf[@]}" --screenshot "$tmp/hl2_on.png"
V "$tmp/leaf_hl2.glb" "${leaf[@]}" --screenshot "$tmp/hl2_off.png" --no-translucency
V "$tmp/leaf_dt.glb" "${leaf[@]}" --screenshot "$tmp/dt_on.png"
V "$tmp/leaf_dt.glb" "${leaf[@]}" --screenshot "$tmp/dt_off.png" --no-translucency
check "HL2 leaf brighter with translucency on than off" "node '$here/check.mjs' brighter '$tmp/hl2_on.png' '$tmp/hl2_off.png'"
check "diffuse-transmission leaf brighter on than off" "node '$here/check.mjs' brighter '$tmp/dt_on.png' '$tmp/dt_off.png'"
V "$tmp/leaf_hl2.glb" "${leaf[@]}" --ambient 0 --no-shadows --screenshot "$tmp/hl2_exact.png" --json >"$tmp/hl2.json"
check "HL2 translucency matches the reconstruction of its maps within 3 %" "node '$here/check.mjs' hl2 '$tmp/hl2_exact.png' '$tmp/hl2.json' 0.03"

# A grown tree with the species' leaf maps (SYLVA_leaf_translucency when the library ships them),
# seen against the sun: translucency brightens the crown, and the HL2 path is the one used.
"$SYLVA" grow --species quaking_aspen --seed 1 --lods 1 --no-impostor -o "$tmp/aspen.glb" --quiet
crown=(--size 128x128 --camera 40,20,7 --sun 220,30 --no-wind --no-stats --no-shadows --no-ground)
V "$tmp/aspen.glb" "${crown[@]}" --screenshot "$tmp/aspen_on.png" --json >"$tmp/aspen.json"
V "$tmp/aspen.glb" "${crown[@]}" --screenshot "$tmp/aspen_off.png" --no-translucency
V "$tmp/aspen.glb" "${crown[@]}" --screenshot "$tmp/aspen_mask.png" --mask
check "back-lit crown brighter with translucency" "node '$here/check.mjs' mean_brighter '$tmp/aspen_on.png' '$tmp/aspen_off.png' '$tmp/aspen_mask.png'"
check "leaf maps in the file are drawn through HL2" "! grep -q SYLVA_leaf_translucency '$tmp/aspen.glb' || node -e 'process.exit(JSON.parse(require(\"fs\").readFileSync(\"$tmp/aspen.json\")).hl2_materials>0?0:1)'"

# --- LOD: thresholds 0.5, 0.2, 0.05 of the screen height (MSFT_screencoverage) ---
# coverage = bounding-sphere radius / (distance tan(fovy / 2)); the box's radius is sqrt(0.75).
dist() { node -e "console.log(Math.sqrt(0.75) / ($1 * Math.tan(22.5 * Math.PI / 180)))"; }
lod_at() { V "$tmp/lod.glb" --json --size 64x64 --no-shadows --camera "0,0,$(dist "$1")" | node -e 'const v=JSON.parse(require("fs").readFileSync(0));const t=v.trees[0];console.log(t.lod, t.drawn.join(" "), t.fade.toFixed(3))'; }
check "coverage 0.501: LOD0" "[[ \$(lod_at 0.501 | cut -d' ' -f1) == 0 ]]"
check "coverage 0.499: LOD1" "[[ \$(lod_at 0.499 | cut -d' ' -f1) == 1 ]]"
check "coverage 0.201 / 0.199: LOD1 / LOD2" "[[ \$(lod_at 0.201 | cut -d' ' -f1) == 1 && \$(lod_at 0.199 | cut -d' ' -f1) == 2 ]]"
check "coverage 0.049: hidden (below the last threshold)" "[[ \$(lod_at 0.049 | cut -d' ' -f1) == 3 ]]"
check "coverage 0.6: LOD0 alone, no fade" "[[ \$(lod_at 0.6) == '0 0 -1 1.000' ]]"
check "coverage 0.5: LOD0 and LOD1 cross-fade half and half" "[[ \$(lod_at 0.5) == '0 0 1 0.500' ]]"
box=(--size 128x128 --mask --camera "20,15,$(dist 0.5)")
V "$tmp/lod.glb" "${box[@]}" --screenshot "$tmp/fade.png"
V "$tmp/lod.glb" "${box[@]}" --lod 0 --screenshot "$tmp/lod0.png"
check "the dithered cross-fade covers the silhouette exactly once (IoU with LOD0 >= 0.99)" "node '$here/check.mjs' iou '$tmp/fade.png' '$tmp/lod0.png' 0.99"

# --- many trees: instanced, LOD by coverage ---
V "$tmp/palm.glb" --copies 100 --json --size 160x120 --no-shadows --camera 30,20,60 >"$tmp/forest.json"
check "100 trees draw fewer triangles than 100 x LOD0" "node -e 'const v=JSON.parse(require(\"fs\").readFileSync(\"$tmp/forest.json\"));console.log(\"  \"+v.triangles+\" of \"+v.lod0_triangles);process.exit(v.trees.length==100&&v.triangles>0&&v.triangles<v.lod0_triangles?0:1)'"
check "100 trees span three levels of detail" "node -e 'const v=JSON.parse(require(\"fs\").readFileSync(\"$tmp/forest.json\"));process.exit(new Set(v.trees.map(t=>t.lod)).size>=3?0:1)'"
check "100 trees in few draw calls (instanced)" "node -e 'const v=JSON.parse(require(\"fs\").readFileSync(\"$tmp/forest.json\"));process.exit(v.draw_calls<=20?0:1)'"

# --- silhouette vs the bounding box projected at its centre's depth (side view) ---
V "$tmp/palm.glb" --mask --lod 0 --no-wind --size 200x200 --camera 0,0 --json --screenshot "$tmp/sil.png" >"$tmp/sil.json"
# A box fills its projected bounding box (the renderer's projection is the textbook one); a tree
# lies inside its own, spanning less of it (cut-out leaf cards, perspective of the box corners).
check "sample tree inside its projected bounding box (1 %), spanning >= 40 % x 75 %" "node '$here/check.mjs' bbox '$tmp/sil.png' '$tmp/sil.json' 0.01 0.4 0.75"
V "$tmp/lod.glb" --mask --lod 0 --size 200x200 --camera 30,20 --json --screenshot "$tmp/box.png" >"$tmp/box.json"
check "a box covers its projected bounding box within 1 %" "node '$here/check.mjs' bbox '$tmp/box.png' '$tmp/box.json' 0.01 0.99 0.99"

# --- scan overlay: the palm's own virtual scan lands on the palm ---
"$SYLVA" scan palm --seed 4 --step 0.6 -o "$tmp/scan.ply" --quiet 2>/dev/null || "$SYLVA" scan palm --seed 4 --step 0.6 -o "$tmp/scan.xyz" --quiet
scan=$(ls "$tmp"/scan.* | head -1)
ov=(--size 160x160 --no-ground --no-stats --no-wind --camera 0,0 --lod 0)
V "$tmp/palm.glb" "${ov[@]}" --mask --screenshot "$tmp/ov_mask.png"
V "$tmp/palm.glb" "${ov[@]}" --screenshot "$tmp/ov_off.png"
V "$tmp/palm.glb" "${ov[@]}" --points "$scan" --screenshot "$tmp/ov_on.png"
check "the scan overlay draws points" "[[ -f '$tmp/ov_on.png' && -f '$tmp/ov_off.png' ]] && ! cmp -s '$tmp/ov_on.png' '$tmp/ov_off.png'"

# --- EXT_meshopt_compression (sylva grow --meshopt) decodes to the same tree ---
"$SYLVA" grow --species palm --seed 4 --lods 2 --meshopt -o "$tmp/palm_mo.glb" --quiet
V "$tmp/palm_mo.glb" --mask --lod 0 --no-wind --size 160x160 --screenshot "$tmp/mo.png"
V "$tmp/palm.glb" --mask --lod 0 --no-wind --size 160x160 --screenshot "$tmp/plain.png"
check "a meshopt-compressed glb shows the same silhouette (IoU >= 0.999)" "node '$here/check.mjs' iou '$tmp/mo.png' '$tmp/plain.png' 0.999"

# --- a folder of glbs: every tree, laid out on the ground ---
mkdir -p "$tmp/trees" && cp "$tmp/palm.glb" "$tmp/trees/a.glb" && cp "$tmp/lod.glb" "$tmp/trees/b.glb" && touch "$tmp/trees/notes.txt"
V "$tmp/trees" --json --size 64x64 --no-shadows >"$tmp/folder.json"
check "a folder shows each of its glbs, side by side" "node -e 'const v=JSON.parse(require(\"fs\").readFileSync(\"$tmp/folder.json\"));const t=v.trees;process.exit(t.length==2&&(t[0].bounds_max[0]<=t[1].bounds_min[0]||t[1].bounds_max[0]<=t[0].bounds_min[0])?0:1)'"

# The frame change: a scan in survey coordinates (Z up) lands on an asset placed by asset.extras.origin.
V "$tmp/beam_origin.glb" --points "$tmp/beam_scan.xyz" --json --size 64x64 --no-shadows >"$tmp/origin.json"
check "the scan lands on the asset through asset.extras.origin (bounds within 1 mm)" "node -e '
  const v = JSON.parse(require(\"fs\").readFileSync(\"$tmp/origin.json\")), t = v.trees[0];
  let w = 0; for (let k = 0; k < 3; k++) w = Math.max(w, Math.abs(v.points_min[k] - t.bounds_min[k]), Math.abs(v.points_max[k] - t.bounds_max[k]));
  console.log(\"  largest bound difference \" + w.toExponential(2) + \" m\"); process.exit(v.points > 0 && w < 1e-3 ? 0 : 1)'"

# --points-beside: the scan stands one tree width to the right as the first
# view sees it (across < 0: the eye looks back along (cos az, sin az), so
# screen-right is (sin az, -cos az)), at the tree's distance from the camera (along +X, the default
# 45-degree view had it a third of a width nearer, and larger on screen).
for cam in "" "--camera 120,10"; do
  V "$tmp/beam_origin.glb" --points "$tmp/beam_scan.xyz" --points-beside $cam --json --size 64x64 --no-shadows >"$tmp/beside.json"
  check "the scan beside the tree, square to the view ${cam:-(default camera)}" "node -e '
    const v = JSON.parse(require(\"fs\").readFileSync(\"$tmp/beside.json\")), t = v.trees[0], az = v.camera[0] * Math.PI / 180;
    const d = [0, 2].map(k => 0.5 * (v.points_min[k] + v.points_max[k] - t.bounds_min[k] - t.bounds_max[k]));
    const along = d[0] * Math.cos(az) + d[1] * Math.sin(az), across = -d[0] * Math.sin(az) + d[1] * Math.cos(az);
    console.log(\"  toward the camera \" + along.toFixed(4) + \" m, to the right \" + (-across).toFixed(3) + \" m\");
    process.exit(Math.abs(along) < 0.01 * Math.abs(across) && across < -0.5 ? 0 : 1)'"
done

# --- animation ---
V "$tmp/palm.glb" --size 64x64 --frames 3 --fps 10 -o "$tmp/anim" --no-shadows
check "--frames writes the frames" "[[ -f '$tmp/anim/frame_0000.png' && -f '$tmp/anim/frame_0002.png' ]]"
check "wind frames differ" "[[ -f '$tmp/anim/frame_0002.png' ]] && ! cmp -s '$tmp/anim/frame_0000.png' '$tmp/anim/frame_0002.png'"
exit $fail
