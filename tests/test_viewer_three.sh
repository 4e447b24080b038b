#!/usr/bin/env bash
# The viewer against a second glTF client: the same grown tree, same camera, rendered as a
# silhouette by sylva view (EGL, llvmpipe) and by three.js r187 (GLTFLoader) in headless
# Chromium (SwiftShader). The masks must agree: IoU >= 0.9. Both at LOD0 (three.js ignores
# MSFT_lod), wind off, leaves alpha-tested against their own cut-off.
set -u
source "$SYLVA_SOURCE_DIR/tests/glb_cli_common.sh"
here="$SYLVA_SOURCE_DIR/tests/viewer"
[[ -f $SYLVA_SOURCE_DIR/node_modules/three/build/three.module.js ]] ||
    { echo "FAIL: three.js missing (run scripts/install-deps.sh)"; exit 1; }
command -v "${CHROMIUM:-chromium}" >/dev/null || { echo "FAIL: chromium missing (run scripts/install-deps.sh)"; exit 1; }

"$SYLVA" grow --species sassafras --seed 2 --lods 2 -o "$tmp/tree.glb" --quiet
for cam in 30,10 120,35; do
  "$SYLVA" view "$tmp/tree.glb" --mask --lod 0 --no-wind --size 320x240 --camera "$cam" --json \
      --screenshot "$tmp/viewer.png" >"$tmp/view.json"
  rm -f "$tmp/three.png"
  node "$here/three_render.mjs" "$tmp/tree.glb" "$tmp/view.json" "$tmp/three.png" ||
    { echo "FAIL: three.js render from $cam (headless Chromium)"; fail=1; continue; }
  check "viewer and three.js silhouettes agree from $cam (IoU >= 0.9)" "node '$here/check.mjs' iou '$tmp/viewer.png' '$tmp/three.png' 0.9"
done
exit $fail
