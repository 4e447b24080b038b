#!/usr/bin/env bash
# `cmake --install` puts the binary, the species library and the docs under a
# prefix, and the installed sylva finds its library from any directory; a
# binary without a library beside it uses $SYLVA_LIBRARY, and says where it
# looked when there is none. `sylva library` prints the manifest.
set -u
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0
no() { echo "FAIL: $*"; fail=1; }
build=${SYLVA_BUILD_DIR:?}
"${CMAKE:-cmake}" --install "$build" --prefix "$tmp/prefix" > "$tmp/install.log" 2>&1 || { no "cmake --install: $(tail -2 "$tmp/install.log")"; exit 1; }
inst="$tmp/prefix/bin/sylva"
[ -x "$inst" ] || no "no installed bin/sylva"
[ -f "$tmp/prefix/share/sylva/species/library.tsv" ] || no "no installed share/sylva/species/library.tsv"
[ -f "$tmp/prefix/share/sylva/species/textures/bark.png" ] || no "textures not installed"
[ -f "$tmp/prefix/share/doc/sylva/architecture.md" ] || no "docs not installed"
ls "$tmp/prefix/share/sylva/species/"*.c > /dev/null 2>&1 && no "sources installed into the library"
# Small fixed costs: no OpenCV module beyond core and imgproc (opencv_video
# alone brought dnn, calib3d, features2d, flann and protobuf into every
# process), no imgcodecs (GDAL, DICOM, HEIF, ...), no VTK.
[ -x "$tmp/prefix/bin/sylva-pipeline" ] || no "no installed bin/sylva-pipeline"
libs=$(ldd "$tmp/prefix/bin/sylva-pipeline" 2>/dev/null)
for l in opencv_video opencv_dnn opencv_imgcodecs libprotobuf libvtk; do
    case $libs in *"$l"*) no "bin/sylva-pipeline loads $l" ;; esac
done
# The front runs --version and info without PCL, CGAL, OpenCV, OpenMP or tinygltf (the
# sanitizer runtimes of the ASan build bring libstdc++ themselves, so it is not listed).
libs=$(ldd "$inst" 2>/dev/null)
for l in libpcl libopencv libgmp libgomp libtinygltf libmeshoptimizer liblapack; do
    case $libs in *"$l"*) no "bin/sylva loads $l" ;; esac
done

cd /
"$inst" library list > "$tmp/list.txt" 2>&1 || no "installed sylva library list failed: $(cat "$tmp/list.txt")"
grep -q "quaking_aspen" "$tmp/list.txt" || no "library list lacks quaking_aspen"
grep -q "$tmp/prefix/share/sylva/species" "$tmp/list.txt" || no "library list does not name the installed library"
"$inst" library show palm --json > "$tmp/palm.json" || no "library show palm --json failed"
python3 - "$tmp/palm.json" <<'PY' || fail=1
import json, sys
d = json.load(open(sys.argv[1]))
want = {"id": 5, "name": "palm", "kind": "palm"}
for k, v in want.items():
    if d.get(k) != v: print(f"FAIL: library show palm: {k} = {d.get(k)!r}, want {v!r}"); sys.exit(1)
if d["files"][0] != "palm.ini" or "leaf_maps" not in d or d["leaf_maps"] is not None or not d["scientific_name"]:
    print(f"FAIL: library show palm: {d}"); sys.exit(1)
PY
"$inst" library list --json | python3 -c 'import json,sys; l=json.load(sys.stdin); ids=[e["id"] for e in l]; assert len(ids)==len(set(ids))>=11, ids; assert {e["name"]:e["id"] for e in l}["quaking_aspen"]==6' || no "library list --json"
"$inst" grow --species palm --lods 1 --no-impostor --quiet -o "$tmp/palm.glb" || no "installed sylva grow --species palm failed"
[ -s "$tmp/palm.glb" ] || no "no palm.glb"
"$inst" library show no_such_tree > /dev/null 2> "$tmp/err"; rc=$?
[ $rc = 2 ] && grep -q "no_such_tree" "$tmp/err" || no "show of an unknown species: exit $rc, $(cat "$tmp/err")"
"$inst" library frobnicate > /dev/null 2>&1; [ $? = 1 ] || no "library frobnicate is not a usage error"

# The binaries alone: SYLVA_LIBRARY, else a one-line error naming where it looked.
mkdir -p "$tmp/lonely" && cp "$inst" "$tmp/prefix/bin/sylva-pipeline" "$tmp/lonely/"
SYLVA_LIBRARY="$tmp/prefix/share/sylva/species" "$tmp/lonely/sylva" library show quaking_aspen > "$tmp/show.txt" 2>&1 ||
  no "SYLVA_LIBRARY not used: $(cat "$tmp/show.txt")"
if [ ! -e /usr/local/share/sylva/species/library.tsv ]; then
  env -u SYLVA_LIBRARY "$tmp/lonely/sylva" library list > /dev/null 2> "$tmp/err"; rc=$?
  [ $rc = 2 ] && grep -q "SYLVA_LIBRARY" "$tmp/err" && [ "$(wc -l < "$tmp/err")" = 1 ] ||
    no "no library: exit $rc, $(cat "$tmp/err")"
fi
# The batch report's three.js bundle travels with an install.
if [ -f "$SYLVA_SOURCE_DIR/node_modules/three/build/three.module.js" ]; then
  for f in build/three.module.js build/three.core.js examples/jsm/loaders/GLTFLoader.js examples/jsm/controls/OrbitControls.js LICENSE; do
    [ -f "$tmp/prefix/share/sylva/three/$f" ] || no "three.js file $f not installed"
  done
fi
# Without sylva-pipeline, the front says so in one line (exit 3); info still works.
mkdir -p "$tmp/front" && cp "$inst" "$tmp/front/sylva"
env PATH=/usr/bin:/bin "$tmp/front/sylva" library list > /dev/null 2> "$tmp/err"; rc=$?
[ $rc = 3 ] && grep -q "sylva-pipeline" "$tmp/err" && [ "$(wc -l < "$tmp/err")" = 1 ] || no "front alone: exit $rc, $(cat "$tmp/err")"
"$tmp/front/sylva" info "$SYLVA_SOURCE_DIR/samples/aspen_tls.las" > "$tmp/info.txt" 2>&1 && grep -q "points" "$tmp/info.txt" ||
  no "front alone: info failed: $(cat "$tmp/info.txt")"
[ $fail = 0 ] && echo "ok: installed sylva finds its library from /, SYLVA_LIBRARY works, library list/show print the manifest"
exit $fail
