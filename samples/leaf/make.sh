#!/usr/bin/env bash
# Regenerates the shipped species leaf maps (species/leafmaps/) from the eztree
# twig photos, and a synthetic full capture (both sides, back-lit, flat field,
# scans) with its maps into samples/leaf/synthetic/ (not committed).
set -euo pipefail
cd "$(dirname "$0")/../.."
S=${SYLVA:-build/sylva}
E=${SYLVA_DATA_DIR:-../shared/data}/real/eztree
# The aspen photo is an autumn twig: --tint makes it the summer green of the
# other broadleaf cards (their mean albedo is about 80-92, 116-122, 47-52).
$S leaf "$E/aspen_color.png" --species quaking_aspen --size 512 --leaf-length 300 --tint 96,128,52
$S leaf "$E/oak_color.png" "$E/oak_leaf.png" --species black_oak --size 512 --leaf-length 400 --no-orient
$S leaf "$E/ash_color.png" --species weeping_willow --size 512 --leaf-length 300
$S leaf "$E/pine_color.png" --species european_pine --size 512 --leaf-length 300
c=samples/leaf/synthetic
$S leaf --synthetic-capture $c/capture --size 512
$S leaf $c/capture/adaxial.png --back-lit $c/capture/adaxial_back_lit.png --flat-field $c/capture/flat_field.png \
  --abaxial $c/capture/abaxial.png --abaxial-back-lit $c/capture/abaxial_back_lit.png \
  --height $c/capture/adaxial_height.png --abaxial-height $c/capture/abaxial_height.png \
  --white 12,12,51,51 --texel 0.20833 --size 512 -o $c/maps
