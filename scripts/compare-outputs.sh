#!/usr/bin/env bash
# Runs a fixed set of sylva commands with two builds and compares every output
# file byte for byte (and the stdout of the commands whose output holds no
# timings): a refactor that should change nothing proves it here.
# Usage: bash scripts/compare-outputs.sh OLD_SYLVA NEW_SYLVA [WORKDIR]
set -u
old=$(realpath "$1"); new=$(realpath "$2")
work=${3:-$(mktemp -d)}; mkdir -p "$work"
here=$(cd "$(dirname "$0")/.." && pwd)
s="$here/samples"
export SOURCE_DATE_EPOCH=1700000000 OPENCV_LOG_LEVEL=ERROR
run_all() {
  local b=$1 d=$2
  mkdir -p "$d" && cd "$d" || exit 3
  "$b" grow --species quaking_aspen --seed 3 -o grow_aspen.glb --quiet
  "$b" grow --species balsam_fir --seed 1 --lods 2 --meshopt -o grow_fir.glb --quiet
  "$b" grow --species palm --no-instancing --no-impostor -o grow_palm.glb --quiet
  grep -v "^bark\|^leaf" "$here/species/weeping_willow.ini" > willow.ini
  "$b" grow willow.ini -o grow_willow.glb --quiet
  "$b" skeleton "$s/aspen_tls.las" -o skel_aspen.sylva --quiet > /dev/null
  "$b" skeleton "$s/fir_tls.las" -o skel_fir.ply --quiet > /dev/null
  "$b" skeleton "$s/palm_tls.las" -o skel_palm.json --k 10 --quiet > /dev/null
  "$b" skeleton "$s/aspen_als.las" -o skel_aspen.csv --quiet > /dev/null
  "$b" skeleton "$s/fir_als.las" -o skel_fir.obj --quiet > /dev/null
  "$b" run "$s/aspen_tls.las" -o run_aspen.glb --sylva run_aspen.sylva --species quaking_aspen --quiet
  "$b" run "$s/fir_tls.las" -o run_fir.glb --voxel 0.02 --wood-share 0.005 --meshopt --quiet
  "$b" run "$s/palm_als.las" -o run_palm.glb --species palm --sylva run_palm.sylva --quiet
  "$b" mesh run_aspen.sylva -o mesh_sylva.glb --quiet
  "$b" mesh skel_fir.ply -o mesh_ply.glb --species balsam_fir --quiet
  "$b" mesh skel_aspen.csv -o mesh_csv.glb --no-leaves --quiet
  "$b" mesh "$s/aspen_tls.json" -o mesh_truth.glb --quiet
  "$b" encode skel_palm.json -o enc_palm.sylva --species 4 --quiet
  "$b" decode run_aspen.sylva -o dec_aspen.json --quiet > dec_aspen.txt
  "$b" decode run_aspen.sylva --json > dec_aspen_json.txt
  "$b" preprocess "$s/plot_tls.las" -o pre_plot.ply --quiet
  "$b" preprocess "$s/aspen_tls.las" -o pre_aspen.las --voxel 0.05 --remove-ground --no-normals --quiet
  "$b" convert "$s/tree1.xyz" -o conv_tree1.ply --quiet
  "$b" info "$s/fir_als.las" --json > info_fir.txt
  "$b" scan quaking_aspen --seed 5 --step 1.5 -o scan_aspen.las --truth scan_aspen.json --quiet
  "$b" scan --plot 12 --trees 3 --species sugar_maple,european_pine --seed 4 --step 1.5 -o scan_plot.las --truth scan_plot.json --quiet
  "$b" eval --skeleton "$s/aspen_tls.json" skel_aspen.json --json > /dev/null 2>&1 || true
}
( run_all "$old" "$work/old" ) 2> "$work/old.log"
( run_all "$new" "$work/new" ) 2> "$work/new.log"
fail=0; n=0
for f in "$work/old"/*; do
  n=$((n + 1)); g="$work/new/$(basename "$f")"
  if [ ! -e "$g" ]; then echo "MISSING: $(basename "$f")"; fail=1
  elif ! cmp -s "$f" "$g"; then echo "DIFFERS: $(basename "$f")"; fail=1; fi
done
for g in "$work/new"/*; do [ -e "$work/old/$(basename "$g")" ] || { echo "EXTRA: $(basename "$g")"; fail=1; }; done
echo "$n outputs compared in $work: $([ $fail = 0 ] && echo identical || echo DIFFERENT)"
exit $fail
