#!/usr/bin/env bash
# Synthesis benchmark (issue targets in docs/synthesize.md): `sylva run` on
# the real scans in ../shared/data/real and scores each asset against its
# own scan with `sylva eval --points` (silhouette IoU of 6 views, vertical
# profile correlation, height and crown-width errors), LOD0 budgets, the
# .sylva size and CPU time. Optional: RENDER=DIR writes scan|asset PNGs
# (scripts/render_tree.mjs, headless Chromium).
#   bash bench/synthesize/run.sh [build/sylva]
set -u
SYLVA=${1:-build/sylva}
here=$(cd "$(dirname "$0")/../.." && pwd)
data=${SYLVA_DATA_DIR:-$here/../shared/data}/real
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
key() { grep -o "\"$1\":[^,}]*" <<< "$2" | head -1 | cut -d: -f2; }
files="adtree/tree1.xyz adtree/tree7.xyz adtree/tree13.xyz adtree/tree33.xyz adtree/Lille_11.xyz adtree/ahn3_delft.xyz
treels/pine.las pytlidar/tree_1.las rtwig/cloud.txt"
printf '| scan | points | IoU mean | IoU min | profile r | height err | width err | LOD0 bark tris | leaves | leaves in hull | lobes | .sylva | run CPU s |\n'
printf '|---|---|---|---|---|---|---|---|---|---|---|---|---|\n'
for f in $files; do
  in=$data/$f
  [[ -f $in ]] || { echo "| $f | missing |"; continue; }
  name=$(basename "$f" | sed 's/\.[^.]*$//')
  /usr/bin/time -f '%U %S' -o "$tmp/time" "$SYLVA" run "$in" -o "$tmp/$name.glb" --sylva "$tmp/$name.sylva" --json \
    > "$tmp/run.json" 2>"$tmp/err" || { echo "| $f | run failed: $(tail -1 "$tmp/err") |"; continue; }
  r=$(cat "$tmp/run.json")
  cpu=$(awk '{printf "%.2f", $1 + $2}' "$tmp/time")
  ev=$("$SYLVA" eval --points "$in" "$tmp/$name.glb" --json 2>/dev/null)
  printf '| %s | %s | %.3f | %.3f | %.3f | %+.3f | %+.3f | %s | %s | %.3f | %s | %s | %s |\n' "$f" \
    "$(key points_preprocessed "$r")" "$(key iou_mean "$ev")" "$(key iou_min "$ev")" "$(key profile_correlation "$ev")" \
    "$(key height_error_rel "$ev")" "$(key crown_width_error_rel "$ev")" "$(key lod0_bark_triangles "$r")" \
    "$(key lod0_leaf_instances "$r")" "$(key leaves_in_hull "$r")" "$(key clusters "$r")" "$(key sylva_bytes "$r")" "$cpu"
  if [[ -n ${RENDER:-} ]]; then
    mkdir -p "$RENDER"
    "$SYLVA" preprocess "$in" -o "$tmp/$name.xyz" --remove-ground --no-normals --quiet >/dev/null 2>&1
    node "$here/scripts/render_tree.mjs" --glb "$tmp/$name.glb" --points "$tmp/$name.xyz" --out "$RENDER/$name.png" \
      --title "$f" --size 1200x600 >/dev/null 2>&1
    cp "$tmp/$name.glb" "$RENDER/$name.glb"
  fi
done
echo
echo "targets: IoU mean >= 0.85, every view >= 0.75, profile r >= 0.85, |height err| <= 0.05, |width err| <= 0.10,"
echo "         LOD0 <= 60k bark triangles and <= 30k leaf instances, >= 95% of leaves in their lobe's hull, .sylva < 40 kB"
