#!/usr/bin/env bash
# GL preview benchmark: frame time of `sylva view --bench` (headless, EGL) for 1, 10 and 100
# instanced copies of a grown tree with LOD, wind, translucency and the shadow map, printed as a
# table against the seed anchors (Habel 2009: 6,392 translucent leaves at 66-116 fps on a 2007
# 8800 GTX; 1,500 branches and 10k leaves animated in 1.49 ms shaded) and the issue's GPU goal
# (100 trees at >= 60 fps at 1080p). On this machine the renderer is Mesa llvmpipe (CPU).
# Usage: bench/viewer/run.sh   Env: SYLVA (default build/sylva), SPECIES (default sassafras),
#        SIZE (default 1920x1080), FRAMES (default 5), COUNTS (default "1 10 100").
set -u
cd "$(dirname "$0")/../.."
sylva=${SYLVA:-build/sylva}
species=${SPECIES:-sassafras}
size=${SIZE:-1920x1080}
frames=${FRAMES:-5}
counts=${COUNTS:-1 10 100}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$sylva" grow --species "$species" --seed 1 -o "$tmp/tree.glb" --quiet || exit 1
echo "| trees | LOD0 triangles | drawn triangles | draw calls | wall ms/frame | CPU ms/frame | fps | renderer |"
echo "|---|---|---|---|---|---|---|---|"
for n in $counts; do
  "$sylva" view "$tmp/tree.glb" --copies "$n" --size "$size" --bench "$frames" --json --camera 30,12 >"$tmp/b.json" || exit 1
  node -e '
    const v = JSON.parse(require("fs").readFileSync(process.argv[1]));
    const fps = 1000 / v.frame_ms;
    console.log(`| ${v.trees.length} | ${v.lod0_triangles} | ${v.triangles} | ${v.draw_calls} | ${v.frame_ms.toFixed(1)} | ${v.cpu_ms_per_frame.toFixed(1)} | ${fps.toFixed(2)} | ${v.renderer} |`);
  ' "$tmp/b.json"
done
echo
echo "Anchors: Habel 2009 leaves 66-116 fps (8800 GTX, 2007); animated tree 1.49 ms shaded (8800 GTS);"
echo "goal on a GPU: 100 trees with LOD, wind and translucency >= 60 fps at 1080p. llvmpipe is a CPU"
echo "rasteriser: its figures bound the CPU cost, not a GPU's."
