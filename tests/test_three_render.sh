#!/usr/bin/env bash
# A real client: every library species' glb loaded by three.js (npm `three`,
# GLTFLoader with EXT_mesh_gpu_instancing) in Debian's headless Chromium
# (tests/three/render_glb.mjs). Each must load with no error or warning, and
# its LOD0 seen from the front must cover what the asset's own picture of
# itself (the impostor atlas, drawn by Sylva's rasteriser) covers:
# intersection over union of the two silhouettes >= 0.8 at 128 px.
set -u
source "$SYLVA_SOURCE_DIR/tests/glb_cli_common.sh"
[[ -f $SYLVA_SOURCE_DIR/node_modules/three/package.json ]] || { echo "FAIL: npm three missing (run scripts/install-deps.sh)"; exit 1; }
command -v chromium > /dev/null || { echo "FAIL: chromium missing (run scripts/install-deps.sh)"; exit 1; }
files=()
for ini in "$SYLVA_SOURCE_DIR"/species/*.ini; do
    sp=$(basename "$ini" .ini)
    "$SYLVA" grow --species "$sp" --seed 1 -o "$tmp/$sp.glb" --impostor-size 256 --quiet 2> "$tmp/$sp.err" ||
        { echo "FAIL: grow $sp: $(tail -1 "$tmp/$sp.err")"; fail=1; continue; }
    files+=("$tmp/$sp.glb")
done
node --experimental-websocket "$SYLVA_SOURCE_DIR/tests/three/render_glb.mjs" --view front --size 128 "${files[@]}" \
    > "$tmp/verdicts.jsonl" 2> "$tmp/render.err" || { echo "FAIL: render_glb: $(tail -3 "$tmp/render.err")"; exit 1; }
check "one verdict per species" "[[ \$(wc -l < '$tmp/verdicts.jsonl') == ${#files[@]} ]]"
while read -r line; do
    printf '%s\n' "$line" > "$tmp/v.json"
    f=$(jq -r .file "$tmp/v.json")
    check "$f loads in three.js without errors or warnings" \
        "jq -e '(.errors | length) == 0 and (.warnings | length) == 0' '$tmp/v.json' > /dev/null"
    check "$f: three.js silhouette matches the asset's impostor picture (IoU $(jq .impostor_iou "$tmp/v.json"))" \
        "jq -e '.impostor_iou >= 0.8 and .levels >= 3' '$tmp/v.json' > /dev/null"
done < "$tmp/verdicts.jsonl"
exit $fail
