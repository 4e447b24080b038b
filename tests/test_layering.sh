#!/usr/bin/env bash
# The layers (docs/architecture.md): every stage folder may include only the
# headers of the stages its CMake library lists, the CMake link lines list no
# more than that, heavy libraries appear only in C++ shims, the main path never
# reaches scan or eval and reconstruction never reaches export. A second run on
# a copy with a forbidden include planted proves the check can fail.
set -u
root=${SYLVA_SOURCE_DIR:?}

# Allowed dependencies per folder (besides itself). Keep in step with CMakeLists.txt.
declare -A allowed=(
  [core]=""
  [leafmaps]="core"
  [species]="core leafmaps"
  [ingest]="core"
  [preprocess]="core"
  [clusters]="core"
  [skeleton]="core"
  [synthesize]="core clusters"
  [encode]="core clusters"
  [grow]="core species"
  [qsm]="core clusters encode grow"
  [mesh]="core"
  [gltf]="core"
  [export]="core gltf"
  [scan]="core grow species"
  [eval]="core encode qsm gltf mesh"
  [photogrammetry]="core ingest"
  [viewer]="core gltf ingest"
  [classify]="core clusters skeleton"
  [segment]="core preprocess skeleton"
)
main_path="core leafmaps species ingest preprocess segment clusters skeleton synthesize encode grow mesh gltf export photogrammetry classify"
reconstruction="skeleton clusters encode"

folder_of() { case $1 in species|viewer|classify) echo "$root/$1" ;; *) echo "$root/stages/$1" ;; esac; }

check() {
  local src=$1 fail=0
  for stage in "${!allowed[@]}"; do
    local dir; dir=$(case $stage in species|viewer|classify) echo "$src/$stage" ;; *) echo "$src/stages/$stage" ;; esac)
    [ -d "$dir" ] || continue
    # Every "stages/X/..." or "species/..." or "pipeline/..." include of the folder.
    while IFS= read -r line; do
      local file=${line%%:*} inc=${line#*:}
      local target
      case $inc in
        stages/*) target=${inc#stages/}; target=${target%%/*} ;;
        species/*) target=species ;;
        pipeline/*|classify/*|viewer/*) target=${inc%%/*} ;;
        *) continue ;;
      esac
      [ "$target" = "$stage" ] && continue
      if [[ " ${allowed[$stage]} " != *" $target "* ]]; then
        echo "FAIL: ${file#$src/} includes $inc: $stage may not use $target"; fail=1
      fi
      if [[ " $main_path " == *" $stage "* ]] && [[ "$target" == scan || "$target" == eval ]]; then
        echo "FAIL: ${file#$src/}: the main path ($stage) must not reach $target"; fail=1
      fi
      if [[ " $reconstruction " == *" $stage "* ]] && [[ "$target" == export ]]; then
        echo "FAIL: ${file#$src/}: reconstruction ($stage) must not reach export"; fail=1
      fi
    done < <(grep -HoE '^#include "[^"]+"' "$dir"/*.c "$dir"/*.h "$dir"/*.cpp "$dir"/*.hpp 2>/dev/null |
             sed -E 's/:#include "(.*)"$/:\1/')
    # Heavy libraries only in the C++ shims.
    if grep -lE '^#include <(pcl/|CGAL/|opencv2/|tiny_gltf\.h|Eigen/)' "$dir"/*.c "$dir"/*.h 2>/dev/null | grep -q .; then
      echo "FAIL: $(grep -lE '^#include <(pcl/|CGAL/|opencv2/|tiny_gltf\.h|Eigen/)' "$dir"/*.c "$dir"/*.h | head -1): a heavy library outside a .cpp shim"
      fail=1
    fi
  done
  # The link lines: sylva_stage(NAME ... DEPS a b ... [PRIVATE_DEPS ...]).
  while IFS= read -r call; do
    local name deps
    name=$(sed -E 's/^sylva_stage\(([a-z_]+).*/\1/' <<< "$call")
    [ -n "${allowed[$name]+x}" ] || continue
    deps=$(sed -E 's/.* DEPS (.*)/\1/; s/ (PRIVATE_DEPS|SYSTEM_INCLUDES|SOURCES|DIR) .*//; s/\)$//' <<< "$call")
    [[ "$call" == *" DEPS "* ]] || deps=""
    for d in $deps; do
      d=${d#sylva_}
      if [[ " ${allowed[$name]} " != *" $d "* ]]; then echo "FAIL: CMakeLists.txt links sylva_$name to sylva_$d"; fail=1; fi
    done
  done < <(cat "$src/CMakeLists.txt" "$src"/viewer/CMakeLists.txt 2>/dev/null | tr '\n' ' ' | sed 's/sylva_stage(/\nsylva_stage(/g' |
           grep -E '^sylva_stage\(' | sed -E 's/\).*/)/')
  return $fail
}

check "$root" || { echo "FAIL: the layering check found violations above"; exit 1; }
echo "ok: every include and link line respects the layers"

# The check must be able to fail: plant a forbidden include (skeleton -> export) in a copy.
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/stages"
cp -r "$root/stages/skeleton" "$root/stages/core" "$tmp/stages/"
cp "$root/CMakeLists.txt" "$tmp/"
echo '#include "stages/export/export.h"' >> "$tmp/stages/skeleton/skeleton_internal.h"
sed -i 's/^sylva_stage(mesh DEPS sylva_core/sylva_stage(mesh DEPS sylva_core sylva_scan/' "$tmp/CMakeLists.txt"
out=$(check "$tmp")
grep -q "skeleton may not use export" <<< "$out" || { echo "FAIL: a planted include went unnoticed"; exit 1; }
grep -q "links sylva_mesh to sylva_scan" <<< "$out" || { echo "FAIL: a planted link went unnoticed"; exit 1; }
echo "ok: planted violations are caught"
