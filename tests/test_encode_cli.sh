#!/usr/bin/env bash
# CLI test for `sylva encode` and `sylva decode -o`: .sylva -> JSON -> .sylva is
# byte for byte the same file, decode is deterministic, a skeleton/QSM file
# encodes with its topology, and damaged JSON is refused with one line naming
# the file and no output left behind.
set -u
fail() { echo "FAIL: $*"; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
corpus="$SYLVA_SOURCE_DIR/tests/fuzz/corpus/sylva"
# The fuzz corpus holds real .sylva files (skeleton + hulls) behind a one-byte mode prefix.
tail -c +2 "$corpus/tiny-v3-asis" > "$tmp/v3.sylva"
# The guarantee holds within a version: the version 3 file, read and written
# again, is a version 4 file (the writer's), and that one round-trips.
"$SYLVA" decode --quiet "$tmp/v3.sylva" -o "$tmp/v3.json" >/dev/null || fail "decode of the version 3 file"
"$SYLVA" encode --quiet "$tmp/v3.json" -o "$tmp/a.sylva" || fail "encode to version 4"
[[ $(od -An -tu1 -j4 -N1 "$tmp/a.sylva" | tr -d ' ') == 4 ]] || fail "the writer did not write version 4"

"$SYLVA" decode --quiet "$tmp/a.sylva" -o "$tmp/a.json" >/dev/null || fail "decode -o exit $?"
"$SYLVA" decode --quiet "$tmp/a.sylva" -o "$tmp/a2.json" >/dev/null || fail "second decode"
cmp -s "$tmp/a.json" "$tmp/a2.json" || fail "two decodes differ"
grep -q '"format":"sylva-tree"' "$tmp/a.json" || fail "not a sylva-tree document"
grep -q '"hull":"alpha"' "$tmp/a.json" || fail "no alpha hulls in the JSON"
grep -q '"occupancy":"' "$tmp/a.json" || fail "no occupancy grid in the JSON"
"$SYLVA" encode --quiet "$tmp/a.json" -o "$tmp/b.sylva" || fail "encode exit $?"
cmp "$tmp/a.sylva" "$tmp/b.sylva" || fail "sylva -> json -> sylva is not byte-identical"

# The leaf-off flag (header byte 5, docs/sylva-format.md) survives the round
# trip: a JSON marked leaf_off encodes to a flagged file, which decodes and
# encodes again byte for byte. Before, the JSON lost it and the tree came
# back dressed in leaves.
sed 's/"leaf_off":false/"leaf_off":true/' "$tmp/a.json" > "$tmp/off.json"
grep -q '"leaf_off":true' "$tmp/off.json" || fail "no leaf_off in the decoded JSON"
"$SYLVA" encode --quiet "$tmp/off.json" -o "$tmp/off.sylva" || fail "encode of the leaf-off JSON exit $?"
[[ $(od -An -tu1 -j5 -N1 "$tmp/off.sylva" | tr -d ' ') == 1 ]] || fail "the leaf-off JSON gave an unflagged file"
"$SYLVA" decode --quiet "$tmp/off.sylva" -o "$tmp/off2.json" >/dev/null || fail "decode of the flagged file"
"$SYLVA" encode --quiet "$tmp/off2.json" -o "$tmp/off2.sylva" || fail "re-encode of the flagged file"
cmp "$tmp/off.sylva" "$tmp/off2.sylva" || fail "flagged sylva -> json -> sylva is not byte-identical"
"$SYLVA" decode --json "$tmp/off.sylva" | grep -q '"leaf_off":true' || fail "decode --json does not say leaf-off"
sed 's/"leaf_off":false/"leaf_off":1/' "$tmp/a.json" > "$tmp/badoff.json"
"$SYLVA" encode "$tmp/badoff.json" -o "$tmp/badoff.sylva" 2> "$tmp/err"; rc=$?
[[ $rc == 2 && ! -e $tmp/badoff.sylva ]] && grep -q "leaf_off" "$tmp/err" || fail "leaf_off 1: exit $rc, $(cat "$tmp/err")"

# An edited JSON (one node moved 1 m) encodes to a different, valid file.
node -e 'const fs = require("fs"); const d = JSON.parse(fs.readFileSync(process.argv[1]));
  d.nodes[1].x += 1; fs.writeFileSync(process.argv[2], JSON.stringify(d));' "$tmp/a.json" "$tmp/moved.json" ||
  fail "node could not edit the JSON"
"$SYLVA" encode --quiet "$tmp/moved.json" -o "$tmp/moved.sylva" || fail "edited JSON exit $?"
cmp -s "$tmp/a.sylva" "$tmp/moved.sylva" && fail "edited JSON gave the same file"
"$SYLVA" decode "$tmp/moved.sylva" >/dev/null || fail "decode of the edited file"

# A sylva-tree JSON with lobes is meshed as the .sylva it encodes to: the
# glb's binary chunk (bark, leaves, textures) byte for byte, only the
# source's name differs. Read as a skeleton alone, it lost its lobes and came
# out a bare skeleton with default cards. An edited one too, and one whose
# grid no longer covers its nodes is refused as `encode` refuses it.
glb_bin() { local n; n=$(od -An -tu4 -j12 -N4 "$1" | tr -d ' '); tail -c +$((21 + n)) "$1"; }
for f in a moved; do
  "$SYLVA" mesh --quiet "$tmp/$f.sylva" -o "$tmp/$f.glb" --impostor-size 64 || fail "mesh of $f.sylva exit $?"
  "$SYLVA" mesh --quiet "$tmp/$f.json" -o "$tmp/${f}j.glb" --impostor-size 64 || fail "mesh of $f.json exit $?"
  cmp -s <(glb_bin "$tmp/$f.glb") <(glb_bin "$tmp/${f}j.glb") || fail "$f.json meshed unlike $f.sylva"
done
cmp -s <(glb_bin "$tmp/a.glb") <(glb_bin "$tmp/moved.glb") && fail "the edit did not change the mesh"
# From a pipe, read once (a second read of the pipe would find it empty).
"$SYLVA" mesh --quiet /dev/stdin -o "$tmp/ap.glb" --impostor-size 64 < "$tmp/a.json" || fail "mesh of a piped JSON exit $?"
cmp -s <(glb_bin "$tmp/a.glb") <(glb_bin "$tmp/ap.glb") || fail "a piped tree.json meshed unlike tree.sylva"
sed 's/"step_log2":-[0-9]*/"step_log2":-30/' "$tmp/a.json" > "$tmp/badgrid.json"
"$SYLVA" mesh "$tmp/badgrid.json" -o "$tmp/badgrid.glb" 2> "$tmp/err"; rc=$?
[[ $rc == 2 && ! -e $tmp/badgrid.glb && $(wc -l < "$tmp/err") == 1 ]] && grep -qF "$tmp/badgrid.json" "$tmp/err" ||
  fail "mesh of a grid too fine: exit $rc, $(cat "$tmp/err")"

# The skeleton-only forms: decode -o .csv, and a QSM to .sylva keeping its topology.
"$SYLVA" decode --quiet "$tmp/a.sylva" -o "$tmp/a.csv" >/dev/null || fail "decode -o csv"
qsm="$SYLVA_DATA_DIR/real/rtwig/QSM.csv"
"$SYLVA" encode --json --species 7 "$qsm" -o "$tmp/q.sylva" > "$tmp/q.out" || fail "encode QSM.csv exit $?"
grep -q '"clusters":0' "$tmp/q.out" && grep -q '"species_id":7' "$tmp/q.out" || fail "QSM report: $(cat "$tmp/q.out")"
rows=$(($(wc -l < "$qsm") - 1))
nodes=$("$SYLVA" decode --json "$tmp/q.sylva" | grep -o '"nodes":[0-9]*' | cut -d: -f2)
# One node per cylinder end: every cylinder adds its end node, each root its start.
(( nodes > rows && nodes <= rows + 8 )) || fail "QSM with $rows cylinders gave $nodes nodes"
# A file without lobes is meshed as a skeleton, leaves along its finest
# branches; marked leaf-off (as `run --leaf-off` marks a tree with no lobes)
# it is drawn bare.
"$SYLVA" decode --quiet "$tmp/q.sylva" -o "$tmp/q.json" >/dev/null || fail "decode of the QSM .sylva"
sed 's/"leaf_off":false/"leaf_off":true/' "$tmp/q.json" > "$tmp/qoff.json"
"$SYLVA" encode --quiet "$tmp/qoff.json" -o "$tmp/qoff.sylva" || fail "encode of the leaf-off QSM JSON"
lv=$("$SYLVA" mesh "$tmp/q.sylva" -o "$tmp/q.glb" --impostor-size 64 --json | grep -o '"leaves":[0-9]*' | cut -d: -f2)
lo=$("$SYLVA" mesh "$tmp/qoff.sylva" -o "$tmp/qoff.glb" --impostor-size 64 --json | grep -o '"leaves":[0-9]*' | cut -d: -f2)
(( lv > 0 && lo == 0 )) || fail "QSM .sylva leaves: $lv unflagged, $lo flagged leaf-off"
# The JSON itself, meshed as a skeleton, reads the flag the same way.
lj=$("$SYLVA" mesh "$tmp/qoff.json" -o "$tmp/qoffj.glb" --impostor-size 64 --json | grep -o '"leaves":[0-9]*' | cut -d: -f2)
(( lj == 0 )) || fail "leaf-off tree.json meshed with $lj leaves"

# Bad input: exit 2, one stderr line naming the file, no output.
check_bad() {
  local name=$1 file=$2
  "$SYLVA" encode "$file" -o "$tmp/bad.sylva" 2> "$tmp/err"; local rc=$?
  [[ $rc == 2 ]] || fail "$name: exit $rc"
  [[ $(wc -l < "$tmp/err") == 1 ]] && grep -qF "$file" "$tmp/err" || fail "$name: message $(cat "$tmp/err")"
  [[ ! -e "$tmp/bad.sylva" ]] || fail "$name: output left behind"
}
sed 's/"triangles":\[[0-9]*/"triangles":[99999/' "$tmp/a.json" > "$tmp/badtri.json"
check_bad "triangle index out of range" "$tmp/badtri.json"
sed 's/"seed":[0-9]*,"hull"/"seed":-3,"hull"/' "$tmp/a.json" > "$tmp/badseed.json"
check_bad "cluster seed not a node" "$tmp/badseed.json"
sed 's/"step_log2":-[0-9]*/"step_log2":-30/' "$tmp/a.json" > "$tmp/badgrid.json"
check_bad "grid too fine for the data" "$tmp/badgrid.json"
head -c $(( $(wc -c < "$tmp/a.json") / 2 )) "$tmp/a.json" > "$tmp/cut.json"
check_bad "truncated JSON" "$tmp/cut.json"
"$SYLVA" encode "$tmp/a.json" -o "$tmp/x.glb" 2>/dev/null; [[ $? == 1 ]] || fail "non-.sylva output is a usage error"
"$SYLVA" decode "$tmp/a.sylva" -o "$tmp/x.glb" 2>/dev/null; [[ $? == 1 ]] || fail "decode -o .glb is a usage error"
echo "ok: encode/decode round trip, QSM encode ($rows cylinders -> $nodes nodes), bad input"
