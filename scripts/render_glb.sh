#!/usr/bin/env bash
# Renders LOD0 of a .glb with three.js in headless Chromium (SwiftShader) to a PNG,
# for looking at assets (docs pictures). Usage: scripts/render_glb.sh IN.glb OUT.png [ZOOM] [TARGET_HEIGHT]
# ZOOM > 1 moves the camera closer; TARGET_HEIGHT in [0,1] is where on the tree it looks.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
cp "$1" "$work/tree.glb"
sed "s|NODE_MODULES|file://$root/node_modules|g" "$root/scripts/render_glb.html" > "$work/index.html"
chromium --headless --no-sandbox --allow-file-access-from-files --use-gl=angle --use-angle=swiftshader \
  --enable-unsafe-swiftshader --window-size=900,900 --virtual-time-budget=30000 \
  --screenshot="$(realpath -m "$2")" "file://$work/index.html?f=tree.glb&zoom=${3:-1}&ty=${4:-0.5}" 2>/dev/null
