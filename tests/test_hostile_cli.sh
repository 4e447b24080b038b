#!/usr/bin/env bash
# Hostile input on every verb: extents of 1 km to 100 km, 1e30 and 1e308
# coordinates, NaN/Inf, lying counts, truncations, device and symlink outputs,
# an output equal to an input, long names. Every case runs under a time and
# memory cap and must end in exit 0 with a valid output, or exit 2 with one
# stderr line naming the file (exit 1 with one line for command-line misuse),
# and never leave a partial output or a temp file behind.
# Each case prints one ok:/FAIL: line; the script exits 1 if any failed.
set -uo pipefail
: "${SYLVA:?}" "${SYLVA_SOURCE_DIR:?}"
unset OPENCV_LOG_LEVEL
export LC_ALL=C
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cd "$tmp"
failed=0
count=0
# Per case: 60 s, and 6 GB of address space unless the binary carries
# AddressSanitizer (its shadow memory reserves terabytes of it).
CAP_S=60
if grep -q __asan_init "$SYLVA" 2>/dev/null; then CAP_KB=unlimited; else CAP_KB=6000000; fi

note() { echo "$1: $2"; [[ $1 == FAIL ]] && failed=1; count=$((count + 1)); }

# run EXPECT WHO NAME -- ARGS...: EXPECT is ok (exit 0), bad (exit 2),
# usage (exit 1) or either (0 or 2); WHO is the path a failure must name.
# Leaves stdout in $tmp/so, stderr in $tmp/se, the exit in $rc.
run() {
    local expect=$1 who=$2 name=$3
    shift 4
    (ulimit -v "$CAP_KB"; timeout "$CAP_S" "$SYLVA" "$@" >"$tmp/so" 2>"$tmp/se")
    rc=$?
    local lines
    lines=$(wc -l <"$tmp/se")
    if [[ $rc == 124 ]]; then note FAIL "$name: over ${CAP_S} s"; return 1; fi
    case $expect:$rc in
    ok:0 | either:0) note ok "$name"; return 0 ;;
    bad:2 | either:2 | usage:1)
        if [[ $lines != 1 ]]; then note FAIL "$name: exit $rc with $lines stderr lines: $(head -c 600 "$tmp/se")"; return 1; fi
        if ! grep -qF -- "$who" "$tmp/se"; then note FAIL "$name: message does not name $who: $(cat "$tmp/se")"; return 1; fi
        note ok "$name (exit $rc: $(cut -c1-150 "$tmp/se"))"
        return 0
        ;;
    esac
    note FAIL "$name: exit $rc, expected $expect: $(head -c 600 "$tmp/se")"
    return 1
}

# No temp file of the output rule (".tmp.<pid>.<name>") anywhere under $tmp.
no_temps() {
    local left
    left=$(find "$tmp" -name '.tmp.*' | head -3)
    [[ -z $left ]] || note FAIL "$1: temp files left: $left"
}
is_glb() { [[ $(head -c 4 "$1" 2>/dev/null) == glTF ]]; }

# ---- inputs ------------------------------------------------------------
# A small tree: a 2 m trunk and a branch, 550 points.
awk 'BEGIN { srand(3);
  for (i = 0; i < 400; i++) { z = i * 0.01; a = rand() * 6.283; print 0.05 * cos(a), 0.05 * sin(a), z }
  for (i = 0; i < 150; i++) { t = i * 0.01; a = rand() * 6.283; print t + 0.02 * cos(a), 0.02 * sin(a), 2 + t }
}' >tree.xyz
shift_cloud() { awk -v dx="$1" -v dy="$2" '{ print $1 + dx, $2 + dy, $3 }' tree.xyz; }
{ cat tree.xyz; shift_cloud 700 700; } >km1.xyz         # two trees 1 km apart
{ cat tree.xyz; shift_cloud 7000 7000; } >km10.xyz      # 10 km
{ cat tree.xyz; shift_cloud 70000 70000; } >km100.xyz   # 100 km
{ cat tree.xyz; echo "0 1e30 1"; } >e30.xyz
{ cat tree.xyz; echo "1e308 0 1"; } >e308.xyz
{ cat tree.xyz; echo "0 nan 1"; } >nan.xyz
{ cat tree.xyz; echo "inf 0 1"; } >inf.xyz
printf 'ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0' >lying.ply
"$SYLVA" skeleton --quiet tree.xyz -o tree.ply >/dev/null 2>&1 || note FAIL "setup: skeleton of tree.xyz"
"$SYLVA" skeleton --quiet tree.xyz -o tree.sylva >/dev/null 2>&1 || note FAIL "setup: .sylva of tree.xyz"
"$SYLVA" mesh --quiet tree.ply --lods 1 --no-impostor -o tree.glb >/dev/null 2>&1 || note FAIL "setup: mesh of tree.ply"
head -c 2000 tree.glb >cut.glb
head -c 60 tree.sylva >cut.sylva
head -c 300 tree.ply >cut.ply
ascii_skeleton() { # y of the third node
    printf 'ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n'
    printf 'property float radius\nelement edge 3\nproperty list uchar int vertex_indices\nend_header\n'
    printf '0 0 0 0.2\n0 0 3 0.15\n0 %s 5 0.1\n1 0 5 0.1\n2 0 1\n2 1 2\n2 1 3\n' "$1"
}
ascii_skeleton 1 >skel.ply
ascii_skeleton 1e30 >skel_e30.ply
ascii_skeleton 1e38 >skel_e38.ply
printf 'ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty float radius\nend_header\n0 0 0 0.1\n' >one_node.ply
printf 'ID,parentID,startX,startY,startZ,endX,endY,endZ,radius\n1,-1,0,0,0,0,0,1,nan\n' >nan.csv
printf '# sylva origin 1 2\nv 0 0 0\n# radius 0.1\nv 0 0 1\n# radius 0.1\nl 1 2\n' >short_origin.obj
printf '{"format":"sylva-truth","version":1,"trees":[{"tree_id":1,"position":[1e999,0,0],"nodes":[' >inf_truth.json
printf '{"id":0,"parent":-1,"x":0,"y":0,"z":0,"radius":0.1},{"id":1,"parent":0,"x":0,"y":0,"z":1,"radius":0.1}]}]}' >>inf_truth.json
node -e '
const fs = require("fs");
const b = fs.readFileSync(process.argv[1]), jl = b.readUInt32LE(12);
const d = JSON.parse(b.slice(20, 20 + jl).toString());
for (const n of d.nodes) { delete n.translation; delete n.rotation; delete n.scale;
  n.matrix = [1e308, 0, 0, 0, 0, 1e308, 0, 0, 0, 0, 1e308, 0, 0, 0, 0, 1]; }
let js = Buffer.from(JSON.stringify(d)); js = Buffer.concat([js, Buffer.alloc((4 - js.length % 4) % 4, 32)]);
const rest = b.slice(20 + jl), h = Buffer.alloc(20);
h.write("glTF", 0); h.writeUInt32LE(2, 4); h.writeUInt32LE(20 + js.length + rest.length, 8);
h.writeUInt32LE(js.length, 12); h.write("JSON", 16);
fs.writeFileSync(process.argv[2], Buffer.concat([h, js, rest]));' tree.glb e308.glb || note FAIL "setup: e308.glb"
printf 'id,species\n1,aspen\n2,oak\n1,aspen\n' >dup.csv
printf '1,aspen\n2,oak\n' >pred.csv

# ---- extents: bounded by the points, never by the span --------------------
for c in km1 km10 km100; do
    run ok x "preprocess $c" -- preprocess --quiet $c.xyz -o $c.ply && { "$SYLVA" info --quiet $c.ply >/dev/null || note FAIL "$c.ply unreadable"; }
    run either $c.xyz "skeleton $c" -- skeleton --quiet $c.xyz -o $c.sylva
    if run either $c.xyz "run $c" -- run --quiet $c.xyz -o $c.glb; then
        [[ $rc != 0 ]] || is_glb $c.glb || note FAIL "run $c: not a glb"
    fi
done

# ---- absurd and non-finite coordinates: the input's fault -----------------
for f in e30 e308 nan inf; do
    run bad $f.xyz "info $f" -- info --quiet $f.xyz
    run bad $f.xyz "preprocess $f" -- preprocess --quiet $f.xyz -o $f.ply
    run bad $f.xyz "eval --points $f" -- eval --quiet --points $f.xyz tree.glb
done
run bad e30.xyz "skeleton e30" -- skeleton --quiet e30.xyz -o e30.sylva
run bad e30.xyz "run e30" -- run --quiet e30.xyz -o e30.glb
run bad e30.xyz "convert e30" -- convert --quiet e30.xyz -o e30.las
for s in skel_e30 skel_e38; do
    run bad $s.ply "mesh $s" -- mesh --quiet $s.ply -o $s.glb
    run bad $s.ply "eval --truth $s" -- eval --quiet --truth $s.ply skel.ply
    run bad $s.ply "eval --points $s" -- eval --quiet --points tree.xyz $s.ply
    run bad $s.ply "encode $s" -- encode --quiet $s.ply -o $s.sylva
done
run bad e308.glb "eval --points e308.glb" -- eval --quiet --points tree.xyz e308.glb
run bad e308.glb "eval --truth e308.glb" -- eval --quiet --truth skel.ply e308.glb
run bad nan.csv "mesh nan radius" -- mesh --quiet nan.csv -o nan.glb
run bad short_origin.obj "mesh short origin comment" -- mesh --quiet short_origin.obj -o so.glb
run bad inf_truth.json "eval inf position" -- eval --quiet --truth inf_truth.json skel.ply

# ---- lying counts and truncations -----------------------------------------
run bad lying.ply "info lying count" -- info --quiet lying.ply
run bad lying.ply "run lying count" -- run --quiet lying.ply -o lying.glb
run bad cut.glb "eval truncated glb" -- eval --quiet --points tree.xyz cut.glb
# An asset where a point cloud belongs: named as a glTF asset, not parsed as text.
run bad tree.glb "info of a glb" -- info --quiet tree.glb && grep -q "glTF asset, not a point cloud" "$tmp/se" ||
    note FAIL "info of a glb: not named a glTF asset: $(cat "$tmp/se")"
run bad tree.glb "run on a glb" -- run --quiet tree.glb -o tree2.glb
run bad cut.sylva "decode truncated" -- decode --quiet cut.sylva
run bad cut.sylva "mesh truncated .sylva" -- mesh --quiet cut.sylva -o cut1.glb
run bad cut.ply "mesh truncated skeleton" -- mesh --quiet cut.ply -o cut2.glb
run bad one_node.ply "mesh one node" -- mesh --quiet one_node.ply -o one.glb
run bad dup.csv "eval duplicate species ids" -- eval --quiet --species dup.csv pred.csv
for f in e30.glb e30.sylva lying.glb cut1.glb cut2.glb one.glb so.glb nan.glb; do
    [[ ! -e $f ]] || note FAIL "$f left behind by a failed command"
done
no_temps "inputs"

# ---- outputs ----------------------------------------------------------------
# Devices are written through and stay devices.
run ok x "mesh -o /dev/null" -- mesh --quiet skel.ply --lods 1 --no-impostor -o /dev/null
run ok x "grow -o /dev/null" -- grow --quiet --species palm --lods 1 --no-impostor -o /dev/null
run ok x "run -o /dev/null" -- run --quiet tree.xyz --lods 1 --no-impostor -o /dev/null
[[ -c /dev/null ]] || note FAIL "/dev/null is no longer a character device"
run ok x "mesh -o /dev/stdout" -- mesh --quiet skel.ply --lods 1 --no-impostor -o /dev/stdout
is_glb "$tmp/so" || note FAIL "mesh -o /dev/stdout: no glb on stdout"
# A symlink stays a link; its target is replaced.
cp tree.glb real.glb
ln -s real.glb link.glb
run ok x "mesh -o symlink" -- mesh --quiet skel.ply --lods 1 --no-impostor -o link.glb
[[ -L link.glb ]] || note FAIL "mesh replaced the symlink link.glb"
cmp -s real.glb tree.glb && note FAIL "mesh did not write through link.glb"
ln -s nowhere.glb dangling.glb
run ok x "mesh -o dangling symlink" -- mesh --quiet skel.ply --lods 1 --no-impostor -o dangling.glb
[[ -L dangling.glb ]] && is_glb nowhere.glb || note FAIL "dangling link: target not made"
# An output equal to an input is refused and the input kept.
cp tree.xyz raw.xyz
sum=$(cksum <raw.xyz)
run bad raw.xyz "preprocess -o its input" -- preprocess --quiet raw.xyz -o raw.xyz
ln -s raw.xyz raw_link.xyz
run bad raw_link.xyz "preprocess -o a link to its input" -- preprocess --quiet raw.xyz -o raw_link.xyz
[[ $(cksum <raw.xyz) == "$sum" ]] || note FAIL "raw.xyz changed"
"$SYLVA" convert --quiet tree.xyz -o scan.ply >/dev/null 2>&1 || note FAIL "setup: scan.ply"
sum=$(cksum <scan.ply)
run bad scan.ply "convert -o its input" -- convert --quiet scan.ply -o scan.ply
run bad scan.ply "skeleton -o its input" -- skeleton --quiet scan.ply -o scan.ply
run bad scan.ply "run --sylva its input" -- run --quiet scan.ply -o scan.glb --sylva scan.ply
[[ $(cksum <scan.ply) == "$sum" && ! -e scan.glb ]] || note FAIL "scan.ply changed or scan.glb written"
cp tree.sylva t2.sylva
run bad t2.sylva "encode -o its input" -- encode --quiet t2.sylva -o t2.sylva
ln -s t2.sylva t2_as.json
run bad t2_as.json "decode -o a link to its input" -- decode --quiet t2.sylva -o t2_as.json
cmp -s t2.sylva tree.sylva || note FAIL "t2.sylva changed"
# A legal 250-byte name (the temp name must stay within NAME_MAX).
long=$(printf 'n%.0s' $(seq 246)).glb
run ok x "mesh -o 250-byte name" -- mesh --quiet skel.ply --lods 1 --no-impostor -o "$long"
is_glb "$long" || note FAIL "250-byte output missing"
longxyz=$(printf 'c%.0s' $(seq 246)).ply
run ok x "convert -o 250-byte name" -- convert --quiet tree.xyz -o "$longxyz"
# Outputs that cannot be: a directory, a missing folder.
mkdir adir
run bad adir "mesh -o a directory" -- mesh --quiet skel.ply -o adir
run bad nodir/x.glb "mesh -o a missing folder" -- mesh --quiet skel.ply -o nodir/x.glb
# Command-line misuse is exit 1: a second -o, a NaN crop box.
run usage -o "second -o" -- preprocess --quiet tree.xyz -o a.ply -o b.ply
[[ ! -e a.ply && ! -e b.ply ]] || note FAIL "second -o: an output was written"
run usage --crop "--crop nan" -- preprocess --quiet --crop nan,nan,nan,nan,nan,nan tree.xyz -o crop.ply
# Paired outputs: both written, and never a truth beside another run's cloud.
run ok x "scan pair" -- scan --quiet palm --positions 1 --step 0.5 -o pair.las --truth pair.json
[[ -s pair.las && -s pair.json ]] || note FAIL "scan pair: missing output"
run ok x "run pair" -- run --quiet tree.xyz --lods 1 --no-impostor -o pair.glb --sylva pair.sylva
is_glb pair.glb && [[ -s pair.sylva ]] || note FAIL "run pair: missing output"
# A decoded tree JSON is a model eval reads (docs/sylva-format.md).
run ok x "decode -o json" -- decode --quiet tree.sylva -o tree.json
run ok x "eval --truth decoded json" -- eval --quiet --truth tree.json tree.json
no_temps "outputs"

echo "$count cases"
exit $failed
