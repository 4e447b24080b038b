#!/usr/bin/env bash
# sylva leaf end to end: a synthetic full capture (both sides, back-lit,
# flat field, scans, white reference) becomes every map and the material
# file; bad inputs fail with one line, exit 2 and nothing written; a species
# with shipped leaf maps grows into a .glb that carries them (diffuse
# transmission, thickness, HL2) and that the Khronos validator accepts with 0
# errors and 0 warnings.
set -u
source "$SYLVA_SOURCE_DIR/tests/glb_cli_common.sh"

cap="$tmp/cap"
"$SYLVA" leaf --synthetic-capture "$cap" --size 256 --quiet
check "synthetic capture written" "[[ -f $cap/adaxial.png && -f $cap/abaxial_height.png && -f $cap/flat_field.png ]]"

out="$tmp/maps"
"$SYLVA" leaf "$cap/adaxial.png" --back-lit "$cap/adaxial_back_lit.png" --flat-field "$cap/flat_field.png" \
  --abaxial "$cap/abaxial.png" --abaxial-back-lit "$cap/abaxial_back_lit.png" \
  --height "$cap/adaxial_height.png" --abaxial-height "$cap/abaxial_height.png" \
  --white 6,6,25,25 --texel 0.41667 --size 256 --directions 64 -o "$out" --json >"$tmp/leaf.json" 2>"$tmp/leaf.err"
check "leaf exits 0" "[[ $? == 0 ]]"
for f in albedo.png albedo_abaxial.png normal.png normal_abaxial.png thickness.png translucency.png \
         translucency_abaxial.png hl2_adaxial.png hl2_abaxial.png atlas.png leaf.material; do
  check "writes $f" "[[ -s $out/$f ]]"
done
check "albedo is RGBA 8-bit" "file '$out/albedo.png' | grep -q '8-bit/color RGBA'"
check "HL2 maps are 16-bit RGB" "file '$out/hl2_adaxial.png' | grep -q '16-bit/color RGB'"
check "thickness is 16-bit grey" "file '$out/thickness.png' | grep -q '16-bit grayscale'"
check "material records the scans" "grep -q '^source_thickness = measured' '$out/leaf.material'"
check "json reports the median thickness" "grep -q '\"thickness_median_mm\"' '$tmp/leaf.json'"

# Bad input: one line on stderr, exit 2, nothing written.
printf 'not an image\n' >"$tmp/text.png"
convert -size 1x1 xc:green -depth 8 PNG24:"$tmp/one.png"
convert -size 64x64 xc:'#808080' -depth 8 PNG24:"$tmp/bg.png"
convert -size 64x48 xc:white -depth 8 PNG24:"$tmp/small_back.png"
leaf_drawing=(-size 64x64 xc:'#808080' -fill '#206020' -draw 'ellipse 32,32 12,24 0,360')
convert "${leaf_drawing[@]}" -depth 16 PNG48:"$tmp/photo16.png"
convert "${leaf_drawing[@]}" -depth 8 PNG24:"$tmp/photo8.png"
check "test photos have the intended depths" \
  "file '$tmp/photo8.png' | grep -q 8-bit && file '$tmp/photo16.png' | grep -q 16-bit"
bad() { # NAME ARGS...
  local name=$1; shift
  rm -rf "$tmp/bad"
  "$SYLVA" leaf "$@" -o "$tmp/bad" --quiet 2>"$tmp/bad.err"
  local rc=$?
  check "$name: exit 2" "[[ $rc == 2 ]]"
  check "$name: one line" "[[ \$(wc -l <'$tmp/bad.err') == 1 ]]"
  check "$name: nothing written" "[[ ! -e $tmp/bad ]]"
}
bad "not an image" "$tmp/text.png"
bad "1x1" "$tmp/one.png"
bad "all background" "$tmp/bg.png"
bad "mismatched back-lit size" "$tmp/photo8.png" --back-lit "$tmp/small_back.png"
bad "16-bit photo" "$tmp/photo16.png"
bad "8-bit height scan" "$tmp/photo8.png" --height "$tmp/photo8.png"
bad "missing file" "$tmp/none.png"
"$SYLVA" leaf "$tmp/photo8.png" --species no_such_species --quiet 2>"$tmp/sp.err"
check "unknown species: exit 2" "[[ $? == 2 ]] && grep -q 'no such species' '$tmp/sp.err'"

# A displacement scan as a PLY point cloud (mm): a plane rising to the right
# tilts every normal towards -X.
python3 -c "
n = 64
with open('$tmp/tilt.ply', 'w') as f:
    f.write('ply\\nformat ascii 1.0\\nelement vertex %d\\nproperty float x\\nproperty float y\\nproperty float z\\nend_header\\n' % (n * n))
    for y in range(n):
        for x in range(n):
            f.write('%d %d %g\\n' % (x, n - 1 - y, 0.5 * x))
"
"$SYLVA" leaf "$tmp/photo8.png" --height "$tmp/tilt.ply" --texel 1 --size 64 --no-orient --directions 16 \
  -o "$tmp/ply" --quiet
check "PLY scan tilts the normals" \
  "[[ \$(convert '$tmp/ply/normal.png' -format '%[fx:mean.r < 0.47]' info:) == 1 ]]"

# Same input and seed, any thread count: the same bytes.
for t in 1 2; do
  "$SYLVA" leaf "$cap/adaxial.png" --back-lit "$cap/adaxial_back_lit.png" --flat-field "$cap/flat_field.png" \
    --abaxial "$cap/abaxial.png" --size 128 --directions 32 --threads $t -o "$tmp/t$t" --quiet
done
same=1
for f in "$tmp"/t1/*; do cmp -s "$f" "$tmp/t2/$(basename "$f")" || same=0; done
check "--threads 1 and 2 write identical files" "[[ $same == 1 ]]"

# A library species with shipped maps: the glb carries them and validates.
if [[ -f $SYLVA_SOURCE_DIR/species/leafmaps/quaking_aspen/leaf.material ]]; then
  "$SYLVA" grow --species quaking_aspen --seed 3 -o "$tmp/aspen.glb" --quiet
  check "grown aspen validates with 0 errors, 0 warnings" \
    "node '$validator' '$tmp/aspen.glb' | head -1 | grep -q 'errors=0 warnings=0'"
  check "glb uses the leaf maps" "node -e '
    const b = require(\"fs\").readFileSync(\"$tmp/aspen.glb\");
    const j = JSON.parse(b.slice(20, 20 + b.readUInt32LE(12)).toString());
    const m = j.materials.find(m => m.name === \"leaf\");
    const dt = m.extensions.KHR_materials_diffuse_transmission;
    if (!dt.diffuseTransmissionTexture || !dt.diffuseTransmissionColorTexture) process.exit(1);
    const h = m.extensions.SYLVA_leaf_translucency;
    /* Double-sided cards: the volume extension is invalid there, the thickness map rides in ours. */
    if (m.extensions.KHR_materials_volume || !h.thicknessTexture || !(h.thicknessFactor > 0)) process.exit(2);
    if (!h.adaxialTexture || !h.abaxialTexture || h.decodeMin !== -1 || h.decodeMax !== 3) process.exit(3);
    if (!m.normalTexture || !m.pbrMetallicRoughness.baseColorTexture) process.exit(4);
  '"
else
  echo "FAIL: species/leafmaps/quaking_aspen is not shipped"; fail=1
fi
exit $fail
