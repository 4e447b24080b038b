#!/usr/bin/env bash
# The README's demo command: installs dependencies, builds Sylva and runs the
# main job on the bundled samples. Outputs land in out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc 2>/dev/null || echo 2)"
mkdir -p out
sylva=build/sylva

echo "== sylva info samples/tree1.xyz"
$sylva info samples/tree1.xyz
echo "== sylva preprocess samples/tree1.xyz -o out/tree1_clean.ply"
$sylva preprocess samples/tree1.xyz -o out/tree1_clean.ply
$sylva info out/tree1_clean.ply
echo "== sylva grow --species quaking_aspen -o out/quaking_aspen.glb"
$sylva grow --species quaking_aspen --seed 1 -o out/quaking_aspen.glb
echo "== sylva run samples/aspen_tls.las -o out/aspen_tls.glb --sylva out/aspen_tls.sylva"
$sylva run samples/aspen_tls.las -o out/aspen_tls.glb --sylva out/aspen_tls.sylva
echo "reconstructed tree: $PWD/out/aspen_tls.glb (bark mesh + instanced leaves from the species branchlets), $PWD/out/aspen_tls.sylva"
$sylva eval --truth samples/aspen_tls.json out/aspen_tls.sylva
echo "== sylva run samples/aspen_als.las -o out/aspen_als.glb --sylva out/aspen_als.sylva (airborne: no stem in the scan)"
$sylva run samples/aspen_als.las -o out/aspen_als.glb --sylva out/aspen_als.sylva
$sylva eval --truth samples/aspen_als.json out/aspen_als.sylva
echo
echo "demo outputs are in $PWD/out/"
ls -l out/
