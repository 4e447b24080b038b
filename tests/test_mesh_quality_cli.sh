#!/usr/bin/env bash
# The mesh checks (sylva ... --check, docs/mesh.md "Quality checks") on the
# reconstructions a user makes first: `sylva run` on every bundled
# single-tree sample and `sylva mesh` on rTwig's reference QSM (with species
# leaves). Asserted per file: no misoriented edges, nothing below the
# ground (the root's height less the trunk's base radius: a leaning trunk's
# base disc tilts), no triangle under 0.005 mm^2 at any level (until stop 29
# the airborne fir's LOD3 kept one, 0.0008 mm^2 beside a capped junction,
# whose edge flip would make an edge that exists), no edge far
# across the branches it runs by (max_across, docs/mesh.md "Stop 28": LOD0
# measured <= 11.4, coarser <= 23.7), few sails and slivers, LOD0 leaves within a leaf length of bark,
# each LOD level 25-50 % of the previous one's triangles, and each level's
# silhouette close to LOD0's (sylva's own masks, `silhouette_iou`): LOD1 at
# least 0.83 and every level 0.55. Measured at stop 48: LOD1 >= 0.865 (tree1),
# every level >= 0.584 (tree1's LOD3). Before coarse levels widened narrow
# cards and kept the cards the bark can pay for, LOD1 read 0.743 on the QSM
# and 0.809 on tree1, and LOD3 0.499 on the QSM and 0.599 on palm_tls.
set -u
source "$SYLVA_SOURCE_DIR/tests/glb_cli_common.sh"
samples="$SYLVA_SOURCE_DIR/samples"
# The checks of one --json report: jq exits 1 unless every condition holds.
# Sails: at most 0.5 % of LOD0's bark triangles. Measured at stop 25: the
# classified palm_tls 0.31 %, tree1 0.04 %, the others under 0.15 %. Until
# then the check measured a child's first segment from the two parent
# segments at its attachment node, while the mesher attaches it anywhere
# within reach along its parent's stem (and chains stems through children of
# other ids, sy_skeleton_continuations): a fir's whorl of twigs attached 20 cm down
# its shoot counted as sails across that gap (palm_tls 0.60 %, the airborne
# fir 0.97 %), and the bound here was 0.7 %.
# At the coarser levels, sails are at most 2 % of each level's bark:
# measured <= 0.73 % (palm_tls's LOD3, 4 of 546) since stop 49 bounded how
# far a coarse level's chord may leave the rings it skips; before, palm_tls's
# LOD3 flagged 187 of its 600 triangles, palm_als's 52 of 416 and fir_tls's
# 86 of 1,666 (long chords across gently bowed rachises and shoots).
# Slivers: at most 0.1 % of LOD0's bark. Until stop 34 a junction strip
# took needle triangles beside thin twigs (the airborne fir 104, 0.198 %,
# against a bound of 0.2 %); a weld now tries a needle-free strip first
# (tube.c): at most 31 (0.06 %, that fir), 0 on the others.
assert_quality() {
    jq -e '
      .mesh_check as $c | ($c[0]) as $l0 |
      ($c | length) >= 2 and
      ([$c[] | .misoriented_edges == 0 and .below_ground == 0 and .leaves_below_ground == 0] | all) and
      ([$c[] | .degenerate] | add) == 0 and
      $l0.sails <= 0.005 * $l0.bark_triangles and $l0.slivers <= 0.001 * $l0.bark_triangles and
      ([$c[1:][] | .sails <= 0.02 * .bark_triangles] | all) and
      $l0.bark_triangles <= 60000 and $l0.leaves_far == 0 and
      $l0.max_across <= 16 and ([$c[] | .max_across <= 40] | all) and
      ([$c[1:][] | .ratio >= 0.25 and .ratio <= 0.5] | all) and
      $c[1].silhouette_iou >= 0.83 and ([$c[1:][] | .silhouette_iou >= '"${2:-0.55}"'] | all)' "$1" > /dev/null
}
for s in aspen_tls fir_tls palm_tls aspen_als fir_als palm_als; do
    if "$SYLVA" run "$samples/$s.las" -o "$tmp/$s.glb" --check --json --impostor-size 64 > "$tmp/$s.json" 2> "$tmp/$s.err"; then
        # Airborne scans see no wood, yet get a stem from the ground (docs/skeleton.md 8d):
        # until stop 25 they were let off with no bark to check.
        check "run $s: mesh checks hold ($(jq -c '[.mesh_check[] | .triangles]' "$tmp/$s.json"))" "assert_quality '$tmp/$s.json'"
    else
        echo "FAIL: run $s: $(tail -1 "$tmp/$s.err")"; fail=1
    fi
done
"$SYLVA" run "$samples/tree1.xyz" -o "$tmp/tree1.glb" --check --json --impostor-size 64 > "$tmp/tree1.json" 2> "$tmp/tree1.err" ||
    { echo "FAIL: run tree1.xyz: $(tail -1 "$tmp/tree1.err")"; fail=1; }
check "run tree1.xyz: mesh checks hold" "assert_quality '$tmp/tree1.json'"
qsm="$SYLVA_DATA_DIR/real/rtwig/QSM.csv"
"$SYLVA" mesh "$qsm" -o "$tmp/q.glb" --species quaking_aspen --check --json --impostor-size 64 > "$tmp/q.json" 2> "$tmp/q.err" ||
    { echo "FAIL: mesh QSM.csv: $(tail -1 "$tmp/q.err")"; fail=1; }
check "rTwig QSM: mesh checks hold ($(jq -c '[.mesh_check[] | .triangles]' "$tmp/q.json"))" "assert_quality '$tmp/q.json'"
# Junctions welded into their parents at LOD0 (the rest are capped inside
# them). A stem that ended with children on its tip welded none of them:
# until stop 29 only a child >= 0.7 as thick turning < 45 degrees went on
# through (sy_skeleton_continuations), and rTwig's QSM, which forks into
# thinner limbs, welded 30 of 100; the airborne fir, whose patches dock at
# each other's ends, 468 of 708. Now 56 of 72 and 525 of 615.
welded() { jq -r '.mesh_check[0] | .welded / .junctions' "$1"; }
w=$(welded "$tmp/q.json")
check "rTwig QSM: $w of LOD0 junctions welded (>= 0.7)" "awk 'BEGIN { exit !($w >= 0.7) }'"
w=$(welded "$tmp/fir_als.json")
check "run fir_als: $w of LOD0 junctions welded (>= 0.85)" "awk 'BEGIN { exit !($w >= 0.85) }'"
# A child whose ring stood partly off its parent's first or last ring, or
# crossed a sibling's ring, was capped: palm_tls welded 0.57 of its LOD0
# junctions, palm_als 0.71, tree1 0.61. Since stop 30 such children slide
# along the parent until the ring fits (fit_on_parent, stems.c): 0.81, 0.86,
# 0.78. Most of the rest were two synthesised limbs leaving one place the
# same way, their rings crossing; since stop 34 each start of a lobe leaves
# its bark another way than the ones before it (start_crowding,
# synthesize.c): 0.98, 0.98, 0.88, and every sample's run at least 0.85.
for s in aspen_tls fir_tls palm_tls aspen_als fir_als palm_als tree1; do
    [[ -f $tmp/$s.json ]] || continue
    w=$(welded "$tmp/$s.json")
    check "run $s: $w of LOD0 junctions welded (>= 0.85)" "awk 'BEGIN { exit !($w >= 0.85) }'"
done
# The traced twigs (lean stems, docs/mesh.md "Stop 39"): a lean parent drawn
# as a triangular prism capped a fifth of its children (the sapling welded
# 496 of 601, tree1 718 of 770). With four sides and rings every 45 degrees
# of turn: 543 of 592 and 741 of 770; with its children's bases no thicker
# than 0.6 of it: 561 of 592 and 755 of 770.
w=$(welded "$tmp/tree1.json")
check "run tree1.xyz: $w of LOD0 junctions welded (>= 0.97)" "awk 'BEGIN { exit !($w >= 0.97) }'"
cloud="$SYLVA_DATA_DIR/real/rtwig/cloud.txt"
"$SYLVA" run "$cloud" -o "$tmp/cloud.glb" --check --json --impostor-size 64 > "$tmp/cloud.json" 2> "$tmp/cloud.err" ||
    { echo "FAIL: run cloud.txt: $(tail -1 "$tmp/cloud.err")"; fail=1; }
# The leaf-off sapling is bark alone: its coarse levels drop the twigs that
# draw its silhouette and no cards stand in for them, so its levels are held
# to 0.5 (LOD1 / LOD2 / LOD3 0.933 / 0.766 / 0.532 at stop 48; 0.873 / 0.685 /
# 0.457 while levels also dropped every stem shorter than 3 % of the tree,
# its traced twigs' chains with them).
check "run rTwig cloud: mesh checks hold" "assert_quality '$tmp/cloud.json' 0.5"
w=$(welded "$tmp/cloud.json")
check "run rTwig cloud: $w of LOD0 junctions welded (>= 0.93)" "awk 'BEGIN { exit !($w >= 0.93) }'"
# Its bark is closed at every level: junctions welded or capped.
check "rTwig QSM: closed bark" "jq -e '[.mesh_check[] | .boundary_edges == 0] | all' '$tmp/q.json' > /dev/null"
exit $fail
