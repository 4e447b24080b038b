#!/usr/bin/env bash
# CLI: info and convert on XYZ and PLY; bad inputs exit 2 with one stderr line
# naming the path and leave no output behind.
set -u
fail() { echo "FAIL: $*" >&2; exit 1; }
: "${SYLVA:?}" "${SYLVA_DATA_DIR:?}" "${SYLVA_SOURCE_DIR:?}"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
tree1="$SYLVA_DATA_DIR/real/adtree/tree1.xyz"

json_field() { # FILE KEY: the value of a flat key in sylva's --json output
    python3 -c 'import json,sys; v=json.load(open(sys.argv[1]))[sys.argv[2]]; print(v if not isinstance(v, list) else " ".join("%.4f" % x for x in v))' "$1" "$2"
}

# tree1.xyz holds 11,855 rows (data/README.md says 11,854: its last row has no newline).
"$SYLVA" info --json "$tree1" > "$work/xyz.json" || fail "info on tree1.xyz exited $?"
[ "$(json_field "$work/xyz.json" point_count)" = 11855 ] || fail "tree1.xyz point_count $(json_field "$work/xyz.json" point_count)"
[ "$(json_field "$work/xyz.json" format)" = XYZ ] || fail "tree1.xyz format"

"$SYLVA" convert "$tree1" -o "$work/t.ply" 2> "$work/convert.err" || fail "convert exited $?: $(cat "$work/convert.err")"
"$SYLVA" info --json "$work/t.ply" > "$work/ply.json" || fail "info on t.ply exited $?"
[ "$(json_field "$work/ply.json" point_count)" = 11855 ] || fail "t.ply point_count"
[ "$(json_field "$work/ply.json" version)" = "binary_little_endian 1.0" ] || fail "t.ply version"
for key in bounds_min bounds_max; do
    a=$(json_field "$work/xyz.json" $key); b=$(json_field "$work/ply.json" $key)
    [ "$a" = "$b" ] || fail "$key differs: xyz [$a] ply [$b]"
done

# And back to XYZ: same count and bounds again.
"$SYLVA" convert "$work/t.ply" -o "$work/back.xyz" 2>/dev/null || fail "convert ply->xyz exited $?"
"$SYLVA" info --json "$work/back.xyz" > "$work/back.json" || fail "info on back.xyz"
[ "$(json_field "$work/back.json" point_count)" = 11855 ] || fail "back.xyz point_count"
[ "$(json_field "$work/back.json" bounds_max)" = "$(json_field "$work/xyz.json" bounds_max)" ] || fail "back.xyz bounds"

# Bad inputs: exit 2, exactly one stderr line naming the input, no output file.
: > "$work/empty.xyz"
mkdir "$work/somedir"
printf 'ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nend_header\n' > "$work/bad.ply"
printf '1 2 3\n4 5\n' > "$work/ragged.xyz"
for bad in "$work/empty.xyz" "$work/somedir" "$work/missing.xyz" "$work/bad.ply" "$work/ragged.xyz"; do
    for cmd in info convert; do
        out="$work/out-$cmd.ply"
        if [ $cmd = info ]; then "$SYLVA" info "$bad" > /dev/null 2> "$work/err"; rc=$?
        else "$SYLVA" convert "$bad" -o "$out" > /dev/null 2> "$work/err"; rc=$?; fi
        lines=$(wc -l < "$work/err")
        [ "$lines" = 1 ] || fail "$cmd $bad: $lines stderr lines: $(cat "$work/err")"
        grep -qF "$bad" "$work/err" || fail "$cmd $bad: stderr does not name it: $(cat "$work/err")"
        [ ! -e "$out" ] || fail "$cmd $bad: left $out behind"
        if [ "$bad" = "$work/somedir" ] && grep -q 'reader missing' "$SYLVA_SOURCE_DIR/stages/ingest/colmap.c"; then
            # A directory goes to the COLMAP reader, which lands in another branch.
            echo "note: directory exit code not checked until the COLMAP reader is merged (got $rc)"
            continue
        fi
        [ $rc = 2 ] || fail "$cmd $bad: exit $rc, expected 2: $(cat "$work/err")"
    done
done
leftovers=$(find "$work" -name '*.tmp.*' | wc -l)
[ "$leftovers" = 0 ] || fail "temporary files left behind"
echo "ok"
