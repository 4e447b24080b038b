#!/usr/bin/env bash
# sylva grow with every LeafShape 0..9 (docs/mesh.md "Leaves"): each tree
# validates with 0 errors and 0 warnings, and its leaf_card mesh has the
# triangle count of that shape's outline.
set -u
source "$SYLVA_SOURCE_DIR/tests/glb_cli_common.sh"
# The species' texture paths are relative to the file.
ln -s "$SYLVA_SOURCE_DIR/species/textures" "$tmp/textures"

# Triangles per card: quad, elliptic, ovate, lanceolate, disc, square,
# obovate, deltoid, cordate, palmate.
tris=(2 10 10 10 24 2 10 1 24 40)
for k in 0 1 2 3 4 5 6 7 8 9; do
  sed "s/^LeafShape = .*/LeafShape = $k/" "$SYLVA_SOURCE_DIR/species/quaking_aspen.ini" >"$tmp/shape$k.ini"
  grep -q "^LeafShape = $k\$" "$tmp/shape$k.ini" || { echo "FAIL: could not set LeafShape $k"; fail=1; continue; }
  "$SYLVA" grow "$tmp/shape$k.ini" --seed 4 -o "$tmp/shape$k.glb" --quiet 2>"$tmp/err$k" \
    || { echo "FAIL: grow LeafShape $k: $(cat "$tmp/err$k")"; fail=1; continue; }
  check "LeafShape $k validates with 0 errors, 0 warnings" \
    "node '$validator' '$tmp/shape$k.glb' | head -1 | grep -q 'errors=0 warnings=0'"
  check "LeafShape $k card has ${tris[$k]} triangles" "node -e '
    const b = require(\"fs\").readFileSync(\"$tmp/shape$k.glb\");
    const j = JSON.parse(b.toString(\"utf8\", 20, 20 + b.readUInt32LE(12)));
    const m = j.meshes.find(m => m.name === \"leaf_card\");
    if (!m || m.primitives.length !== 1) process.exit(1);
    if (j.accessors[m.primitives[0].indices].count !== 3 * ${tris[$k]}) process.exit(1);
  '"
done
exit $fail
