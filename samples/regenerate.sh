#!/usr/bin/env bash
# Regenerates the simulated scans in samples/ with `sylva scan` (see README.md).
# Usage: bash samples/regenerate.sh [path/to/sylva [OUTDIR]]   (default: build/sylva, samples/)
# Deterministic: the same sylva gives the same files (LAS date pinned below);
# tests/test_samples_cli.sh regenerates them into a temporary OUTDIR and
# compares, so a change to the scanner that moves a point fails there.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
SYLVA=$(realpath "${1:-$here/../build/sylva}")
export SOURCE_DATE_EPOCH=1700000000
cd "${2:-$here}"
scan() { echo "sylva scan $*" >&2; "$SYLVA" scan "$@" --quiet --json; }

# Terrestrial: four stations on a circle, 0.5-0.9 degree steps keep ~20k points.
scan quaking_aspen --seed 1 --step 0.6 -o aspen_tls.las --truth aspen_tls.json
scan balsam_fir    --seed 1 --step 0.8 -o fir_tls.las   --truth fir_tls.json
scan palm          --seed 1 --step 0.5 -o palm_tls.las  --truth palm_tls.json
# Airborne: 40 m above ground, 10 pulses per m^2.
for sp in quaking_aspen:aspen balsam_fir:fir palm:palm; do
    scan "${sp%%:*}" --seed 1 --scanner airborne --altitude 40 --density 10 \
        -o "${sp##*:}_als.las" --truth "${sp##*:}_als.json"
done
# A 20 x 20 m plot of five trees on a 4-degree rough slope with understory.
scan --plot 20 --trees 5 --species quaking_aspen,balsam_fir,palm --seed 2 --slope 4 --roughness 0.15 \
    --step 0.9 -o plot_tls.las --truth plot_tls.json
