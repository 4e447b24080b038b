#!/usr/bin/env bash
# sylva grow end to end: every library species becomes a .glb that the Khronos
# validator accepts with 0 errors and 0 warnings, within the LOD budget
# (LOD0 bark <= 60k triangles, each level <= 50% of the previous), and the
# same seed gives a byte-identical file.
set -u
source "$SYLVA_SOURCE_DIR/tests/glb_cli_common.sh"

for sp in "$SYLVA_SOURCE_DIR"/species/*.ini; do
  name=$(basename "$sp" .ini)
  "$SYLVA" grow "$sp" --seed 2 -o "$tmp/$name.glb" --json >"$tmp/$name.json" 2>"$tmp/$name.err" \
    || { echo "FAIL: grow $name: $(cat "$tmp/$name.err")"; fail=1; continue; }
  check "$name validates with 0 errors, 0 warnings" \
    "node '$validator' '$tmp/$name.glb' | head -1 | grep -q 'errors=0 warnings=0'"
  # lod_triangles includes 2 triangles per leaf card; leaves are on top of the bark budget.
  check "$name LOD budget" "node -e '
    const r = JSON.parse(require(\"fs\").readFileSync(\"$tmp/$name.json\"));
    const t = r.lod_triangles, leafTris = 2 * r.leaves;
    if (t[0] - leafTris > 60000) process.exit(1);
    for (let i = 1; i < t.length; i++) if (t[i] > 0.5 * t[i - 1]) process.exit(1);
  '"
done

"$SYLVA" grow --species quaking_aspen --seed 9 -o "$tmp/a1.glb" --quiet
"$SYLVA" grow --species quaking_aspen --seed 9 -o "$tmp/a2.glb" --quiet
"$SYLVA" grow --species quaking_aspen --seed 10 -o "$tmp/a3.glb" --quiet
check "same seed, same bytes" "cmp -s '$tmp/a1.glb' '$tmp/a2.glb'"
check "another seed, another tree" "! cmp -s '$tmp/a1.glb' '$tmp/a3.glb'"

"$SYLVA" grow --species quaking_aspen --meshopt --seed 9 -o "$tmp/m.glb" --quiet
check "meshopt output validates" "node '$validator' '$tmp/m.glb' | head -1 | grep -q 'errors=0 warnings=0'"
check "meshopt output is smaller" "[[ \$(stat -c %s '$tmp/m.glb') -lt \$(stat -c %s '$tmp/a1.glb') ]]"
"$SYLVA" grow --species palm --no-instancing --seed 9 -o "$tmp/b.glb" --quiet
check "baked leaves validate and need no extension" \
  "node '$validator' '$tmp/b.glb' | head -1 | grep -q 'errors=0 warnings=0' && ! grep -q EXT_mesh_gpu_instancing '$tmp/b.glb'"

# The materials cache: the first tree of a species stores its encoded
# textures, the next embeds them as they are; the bytes never change.
SYLVA_CACHE_DIR="$tmp/cache" "$SYLVA" grow --species quaking_aspen --seed 3 -o "$tmp/c1.glb" --quiet
SYLVA_CACHE_DIR="$tmp/cache" "$SYLVA" grow --species quaking_aspen --seed 3 -o "$tmp/c2.glb" --quiet
SYLVA_CACHE_DIR= "$SYLVA" grow --species quaking_aspen --seed 3 -o "$tmp/c0.glb" --quiet
check "cached textures: the same bytes as made ones, one entry" \
  "cmp -s '$tmp/c0.glb' '$tmp/c1.glb' && cmp -s '$tmp/c0.glb' '$tmp/c2.glb' && [[ \$(ls '$tmp/cache' | wc -l) == 1 ]]"
check "no temp file in the cache" "[[ -z \$(ls -A '$tmp/cache' | grep tmp) ]]"

"$SYLVA" grow --species no_such_tree -o "$tmp/x.glb" 2>"$tmp/err"; rc=$?
check "unknown species exits 2" "[[ $rc == 2 ]]"
check "one-line error naming it" "[[ \$(wc -l <'$tmp/err') == 1 ]] && grep -q no_such_tree '$tmp/err'"
check "no output left" "[[ ! -e '$tmp/x.glb' ]] && [[ -z \$(ls -A '$tmp' | grep tmp) ]]"
printf '[General]\nShape = 99\n' >"$tmp/bad.ini"
"$SYLVA" grow "$tmp/bad.ini" -o "$tmp/y.glb" 2>"$tmp/err2"; rc=$?
check "bad species file exits 2 naming file" "[[ $rc == 2 ]] && grep -q bad.ini '$tmp/err2' && [[ ! -e '$tmp/y.glb' ]]"
"$SYLVA" grow --species palm 2>/dev/null; rc=$?
check "missing -o is a usage error" "[[ $rc == 1 ]]"
exit $fail
