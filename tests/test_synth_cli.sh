#!/usr/bin/env bash
# CLI test for synthesis (docs/synthesize.md): `sylva run` on the bundled
# simulated aspen fills its lobes with the species' branchlets and leaves.
# The asset has no hull proxy by default, looks like its scan (silhouette
# IoU, profile, height, width: thresholds that the bare skeleton failed),
# keeps >= 95% of its leaves within 5 cm of their lobes' hulls (the exact
# distance, synthesize.c near_hull; 0.998 on the real tree13), is byte-identical for
# any thread count, and `sylva mesh` of the .sylva makes the same tree.
set -u
fail() { echo "FAIL: $*"; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
src=$SYLVA_SOURCE_DIR
scan=$src/samples/aspen_tls.las
key() { grep -o "\"$1\":[^,}]*" <<< "$2" | head -1 | cut -d: -f2; }
at_least() { awk -v v="$1" -v t="$2" 'BEGIN { exit !(v != "" && v + 0 >= t) }'; }
at_most() { awk -v v="$1" -v t="$2" 'BEGIN { exit !(v != "" && v + 0 <= t) }'; }
abs_at_most() { awk -v v="$1" -v t="$2" 'BEGIN { exit !(v != "" && (v < 0 ? -v : v) <= t) }'; }

out=$("$SYLVA" run "$scan" -o "$tmp/a.glb" --sylva "$tmp/a.sylva" --species quaking_aspen --json --threads 2) ||
  fail "run exit $?"
# Every lobe of this scan has traced twigs: its leaves hang on them, no
# species branchlet docks (test_synthesize covers the patches).
(( $(key patches "$out") == 0 )) || fail "patches on traced twigs: $out"
(( $(key leaves "$out") > 1000 )) || fail "few leaves: $out"
(( $(key hull_triangles "$out") == 0 )) || fail "proxy in the default output: $out"
at_least "$(key leaves_in_hull "$out")" 0.95 || fail "leaves outside their hulls: $out"
(( $(key sylva_bytes "$out") < 40000 )) || fail ".sylva too large: $out"
grep -a -q '"name":"foliage_proxy"' "$tmp/a.glb" && fail "foliage_proxy without --proxy"
if command -v node >/dev/null && [[ -d $src/node_modules/gltf-validator ]]; then
  v=$(node "$src/tests/gltf_validate.mjs" "$tmp/a.glb") || fail "validator: $v"
  grep -q 'errors=0 warnings=0' <<< "$v" || fail "validator: $v"
fi

# Determinism: one thread gives the same bytes.
"$SYLVA" run "$scan" -o "$tmp/b.glb" --sylva "$tmp/b.sylva" --species quaking_aspen --quiet --threads 1 || fail "run 2"
cmp -s "$tmp/a.glb" "$tmp/b.glb" || fail "1 and 2 threads differ (.glb)"
cmp -s "$tmp/a.sylva" "$tmp/b.sylva" || fail "1 and 2 threads differ (.sylva)"

# Decode: the .sylva alone (its species id and seed) gives the same tree.
"$SYLVA" mesh "$tmp/a.sylva" -o "$tmp/m.glb" --quiet || fail "mesh .sylva exit $?"
if command -v node >/dev/null; then
  node "$src/tests/glb_same_tree.mjs" "$tmp/a.glb" "$tmp/m.glb" || fail "decoded tree differs from run's"
else
  echo "node missing: decode identity skipped"
fi
# --proxy keeps the hulls, in both.
"$SYLVA" mesh "$tmp/a.sylva" -o "$tmp/p.glb" --proxy --quiet || fail "mesh --proxy"
grep -a -q '"name":"foliage_proxy"' "$tmp/p.glb" || fail "no foliage_proxy with --proxy"

# --leaf-off (a scan of bare branches): no leaf cards, the traced twigs
# are the lobes' wood as in the leafy run; the .sylva differs only in its
# leaf-off flag (byte 5, and the checksum), and `mesh` of either file with
# --no-leaves, or of the flagged one alone, gives the same tree.
off=$("$SYLVA" run "$scan" -o "$tmp/off.glb" --sylva "$tmp/off.sylva" --species quaking_aspen --leaf-off --json --threads 2) ||
  fail "run --leaf-off exit $?"
(( $(key leaves "$off") == 0 && $(key lod0_leaf_instances "$off") == 0 )) || fail "leaves with --leaf-off: $off"
(( $(key twig_nodes "$out") > 1000 && $(key twig_nodes "$off") == $(key twig_nodes "$out") )) ||
  fail "traced twigs: $(key twig_nodes "$out") leafy, $(key twig_nodes "$off") leaf-off"
# The same wood either way, to a few triangles: a stem's reach counts the
# leaves it carries, and the LOD0 budget drops the stems of least reach
# first (sy_lod_fit_budget; 1 % allowed).
a=$(key lod0_bark_triangles "$out"); b=$(key lod0_bark_triangles "$off")
(( $(key patches "$off") == 0 && b > 0 && 100 * (a > b ? a - b : b - a) <= a )) ||
  fail "bark: $a leafy, $b leaf-off triangles (want the same within 1 %)"
[[ $(cmp -l "$tmp/a.sylva" "$tmp/off.sylva" | awk '$1 == 6 || $1 > size - 4 { next } { n++ } END { print n + 0 }' \
     size="$(stat -c %s "$tmp/a.sylva")") == 0 ]] || fail "--leaf-off changed the .sylva beyond its flag"
[[ $(od -An -tu1 -j5 -N1 "$tmp/off.sylva") -eq 1 && $(od -An -tu1 -j5 -N1 "$tmp/a.sylva") -eq 0 ]] ||
  fail "leaf-off flag: $(od -An -tu1 -j5 -N1 "$tmp/a.sylva") leafy, $(od -An -tu1 -j5 -N1 "$tmp/off.sylva") leaf-off"
# The aspen's returns lie off its traced wood (0.65 within a spacing): leaves.
[[ $(key leaf_off "$out") == false ]] && at_most "$(key returns_on_wood "$out")" 0.8 ||
  fail "the leafy aspen judged leaf-off: $out"
if command -v node >/dev/null; then
  "$SYLVA" mesh "$tmp/a.sylva" -o "$tmp/mo.glb" --no-leaves --quiet || fail "mesh --no-leaves exit $?"
  node "$src/tests/glb_same_tree.mjs" "$tmp/off.glb" "$tmp/mo.glb" || fail "mesh --no-leaves differs from run --leaf-off"
  "$SYLVA" mesh "$tmp/off.sylva" -o "$tmp/mf.glb" --quiet || fail "mesh of the leaf-off .sylva exit $?"
  node "$src/tests/glb_same_tree.mjs" "$tmp/off.glb" "$tmp/mf.glb" || fail "mesh of the flagged .sylva differs from run --leaf-off"
fi

# A leaf-off scan, found without --leaf-off: rTwig's sapling, whose returns
# lie on its traced twigs (0.89 within a spacing; docs/synthesize.md "Stop
# 39"). It gets no cards (IoU 0.784 with them, 0.849 without), its .sylva is
# flagged, and --leaves dresses it in leaves all the same.
cloud=$SYLVA_DATA_DIR/real/rtwig/cloud.txt
co=$("$SYLVA" run "$cloud" -o "$tmp/cl.glb" --sylva "$tmp/cl.sylva" --json) || fail "run cloud exit $?"
[[ $(key leaf_off "$co") == true ]] && at_least "$(key returns_on_wood "$co")" 0.8 && (( $(key leaves "$co") == 0 )) ||
  fail "the leaf-off sapling kept its cards: $co"
[[ $(od -An -tu1 -j5 -N1 "$tmp/cl.sylva") -eq 1 ]] || fail "the sapling's .sylva is not flagged leaf-off"
if command -v node >/dev/null; then
  "$SYLVA" mesh "$tmp/cl.sylva" -o "$tmp/clm.glb" --quiet || fail "mesh cloud .sylva exit $?"
  node "$src/tests/glb_same_tree.mjs" "$tmp/cl.glb" "$tmp/clm.glb" || fail "the sapling's .sylva decodes to another tree"
fi
# Twigs traced finer than 1.5 scan spacings take nearly every return as a
# node: a leafy aspen of 6,000 returns lay 0.94 on its wood. Not judged.
"$SYLVA" scan quaking_aspen --seed 1 --max-points 6000 -o "$tmp/sparse.las" --quiet || fail "scan (sparse) exit $?"
sp=$("$SYLVA" run "$tmp/sparse.las" -o "$tmp/sparse.glb" --json) || fail "run (sparse) exit $?"
[[ $(key leaf_off "$sp") == false ]] && ! grep -q returns_on_wood <<< "$sp" && (( $(key leaves "$sp") > 1000 )) ||
  fail "the sparse leafy aspen was judged: $sp"
cl=$("$SYLVA" run "$cloud" -o "$tmp/cll.glb" --leaves --json) || fail "run cloud --leaves exit $?"
[[ $(key leaf_off "$cl") == false ]] && (( $(key leaves "$cl") > 0 )) || fail "--leaves gave no leaves: $cl"
"$SYLVA" run "$cloud" -o "$tmp/x.glb" --leaves --leaf-off 2>"$tmp/err"; rc=$?
[[ $rc == 1 && ! -e $tmp/x.glb ]] && grep -q "contradict" "$tmp/err" || fail "--leaves --leaf-off: exit $rc, $(cat "$tmp/err")"

# The look against the scan. Measured with the aspen's denser, larger cards
# (docs/species.md): IoU mean 0.741, min 0.700, profile 0.764, height -5.9%,
# width -11.8% (0.815 / 0.793 with the earlier small cards; the bare skeleton of
# before: IoU ~0.1). Since the root stands at the trunk's foot, not at the
# 0.5th percentile of z (docs/skeleton.md, step 9): IoU mean 0.727, min 0.677,
# profile 0.820, height -5.4%, width -13.2%.
ev=$("$SYLVA" eval --points "$scan" "$tmp/a.glb" --json) || fail "eval exit $?"
at_least "$(key iou_mean "$ev")" 0.72 || fail "iou_mean: $ev"
at_least "$(key iou_min "$ev")" 0.66 || fail "iou_min: $ev"
at_least "$(key profile_correlation "$ev")" 0.74 || fail "profile: $ev"
abs_at_most "$(key height_error_rel "$ev")" 0.12 || fail "height: $ev"
abs_at_most "$(key crown_width_error_rel "$ev")" 0.25 || fail "width: $ev"

# What the scores are made of: --json carries both 40-bin profiles, --png
# the six views' masks (3 x 2 views of 256 pixels, labelled, 4-pixel gutters) with
# the same scores; --png needs a glTF model.
n_prof=$(grep -o '"profile_model":\[[^]]*\]' <<< "$ev" | tr ',' '\n' | wc -l)
[[ $n_prof == 40 ]] || fail "profile_model has $n_prof bins: $ev"
ev2=$("$SYLVA" eval --points "$scan" "$tmp/a.glb" --png "$tmp/masks.png" --json) || fail "eval --png exit $?"
[[ $(key iou_mean "$ev2") == "$(key iou_mean "$ev")" ]] || fail "--png changed the score"
size=$(od -An -tu1 -j16 -N8 "$tmp/masks.png" | awk '{ print $3 * 256 + $4, $7 * 256 + $8 }')
[[ $size == "784 548" ]] || fail "masks PNG is $size"
"$SYLVA" eval --points "$scan" "$tmp/a.sylva" --png "$tmp/x.png" 2>"$tmp/err"; rc=$?
[[ $rc == 1 && ! -e $tmp/x.png ]] || fail "--png with a .sylva model: exit $rc"

# A dense crown: the simulated aspen at 0.15 degrees (246k returns) cut at
# a tenth of its extent gave 300 lobes and a 51 kB .sylva. The run cuts
# again with larger lobes until the file holds them, and says so.
"$SYLVA" scan quaking_aspen --seed 1 --scanner terrestrial --step 0.15 -o "$tmp/dense.las" --quiet || fail "scan exit $?"
dense=$("$SYLVA" run "$tmp/dense.las" --species quaking_aspen -o "$tmp/dense.glb" --sylva "$tmp/dense.sylva" --json) ||
  fail "run (dense) exit $?"
(( $(key sylva_bytes "$dense") < 40000 )) || fail "dense crown's .sylva too large: $dense"
awk -v v="$(key lobe_size "$dense")" 'BEGIN { exit !(v > 0.1 && v < 1) }' || fail "lobes not enlarged: $dense"
(( $(key clusters "$dense") >= 40 )) || fail "too few lobes left: $dense"
(( $(key leaves "$dense") > 5000 )) || fail "dense crown's leaves: $dense"
# A sparse scan keeps the lobe size it asked for.
[[ $(key lobe_size "$out") == 0.1 ]] || fail "lobe size changed on the sample: $out"

# Species that do not exist, a bad grammar: clear errors.
"$SYLVA" run "$scan" -o "$tmp/x.glb" --species no_such_tree 2>"$tmp/err"; rc=$?
[[ $rc == 2 ]] || fail "unknown species exit $rc"
[[ ! -e $tmp/x.glb ]] || fail "output left behind"
echo "all synthesis CLI checks passed"
