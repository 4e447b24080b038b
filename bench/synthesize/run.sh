#!/usr/bin/env bash
# Synthesis benchmark: every target of issue 11 (docs/synthesize.md) in one
# run, printed, never asserted. CPU = user + sys (/usr/bin/time); the machine
# is shared, so the load average is printed with each table.
#   (r) real scans in ../shared/data/real, each `sylva run` asset against its
#       own scan (`sylva eval --points`): silhouette IoU mean/min of 6 views,
#       profile correlation, height and crown-width errors, LOD0 bark
#       triangles, leaf instances, share of leaves within 5 cm of their
#       lobe's hull; the same IoU for `sylva run --leaf-off` and for AdTree's
#       own branch mesh (bench_synthesize look: the same measure on an OBJ).
#   (a) `sylva run` vs AdTree CPU time on each of AdTree's own data files.
#   (s) simulated terrestrial scans of every library species (`sylva scan`):
#       the asset against the true tree's own asset (`sylva grow`, same
#       species and seed) by the same silhouette measure, beside the true
#       tree against the scan's own returns (what the stations saw of its
#       silhouette: a crown top none of them sees); total leaf area
#       and the count of branches with base radius >= 2 cm, asset / truth;
#       the main skeleton's leaf-on recall of limbs >= 2 cm (`sylva eval
#       --truth`) next to its visibility ceiling (bench_visibility: the share
#       of that limb length with a wood return near it at all).
#   (l) simulated airborne scans of every library species (`sylva scan
#       --scanner airborne`, 40 m, 10 pulses/m^2, as samples/*_als.las): the
#       asset against the true tree's asset by the same silhouette measure,
#       height, crown width and DBH against the truth, whether the stem was
#       drawn as unseen (docs/skeleton.md 8d), leaves.
#   (d) decode (synthesis + meshing LOD0, no export) on one core for every
#       .sylva made above, and its linearity in LOD0 triangles (least squares).
#   (k) scan -> glb for a 100k-point simulated tree (`sylva run`, all cores).
# Usage: bash bench/synthesize/run.sh [r] [a] [s] [l] [d] [k]   (default: all)
# Env: SYLVA (build/sylva), BENCH (build/bench/bench_synthesize),
#      ADTREE (/work/peers/adtree/build/bin/AdTree; a binary built from
#      tudelft3d/AdTree outside this repository; skipped when absent),
#      SYLVA_DATA_DIR (../shared/data), SEED (1), KEEP=DIR keeps the files,
#      SPECIES="a b" limits part (s), RENDER=DIR writes scan|asset PNGs of (r)
#      (scripts/render_tree.mjs, headless Chromium).
set -u
here=$(cd "$(dirname "$0")/../.." && pwd)
cd "$here"
sylva=${SYLVA:-build/sylva}
bench=${BENCH:-build/bench/bench_synthesize}
bench_visibility=${BENCH_VISIBILITY:-build/bench/bench_visibility}
adtree=${ADTREE:-/work/peers/adtree/build/bin/AdTree}
[[ -x $adtree ]] || adtree=
data=${SYLVA_DATA_DIR:-../shared/data}
seed=${SEED:-1}
parts=${*:-r a s l d k}
export SYLVA_LIBRARY=${SYLVA_LIBRARY:-$here/species}
if [[ -n ${KEEP:-} ]]; then tmp=$KEEP; mkdir -p "$tmp"; else tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT; fi
key() { local v; v=$(grep -o "\"$1\":[^,}]*" <<< "$2" | head -1 | cut -d: -f2); echo "${v:-nan}"; }
kv() { local v; v=$(grep -o "\b$1=[^ ]*" <<< "$2" | head -1 | cut -d= -f2); echo "${v:-nan}"; }
load() { cut -d' ' -f1-3 /proc/loadavg; }
# cpu OUTFILE CMD...: runs CMD, writes "user+sys maxrss_kB wall" to OUTFILE; CMD's status.
cpu() { local o=$1; shift; /usr/bin/time -f '%U %S %M %e' -o "$o.t" "$@"; local rc=$?
  tail -1 "$o.t" | awk '{ printf "%.2f %d %.2f\n", $1 + $2, $3, $4 }' > "$o"; return $rc; }
f3() { awk -v v="$1" 'BEGIN { if (v == "nan" || v == "" || v == "—") print "—"; else printf "%.3f", v }'; }
pct() { awk -v v="$1" 'BEGIN { if (v == "nan" || v == "") print "—"; else printf "%+.1f%%", 100 * v }'; }
declare -A run_cpu

real="adtree/tree1.xyz adtree/tree7.xyz adtree/tree13.xyz adtree/tree33.xyz adtree/Lille_11.xyz adtree/ahn3_delft.xyz
treels/pine.las pytlidar/tree_1.las rtwig/cloud.txt"

# AdTree on a scan: its own .xyz as given; other formats go in as the points
# `sylva run` reconstructs (preprocessed: outliers and ground removed), since
# AdTree reads .xyz of an isolated tree. Prints "cpu_s iou_mean iou_min
# precision recall".
adtree_look() {
  local in=$1 name=$2 x=$1 d="$tmp/adt_$2"
  [[ -n $adtree ]] || { echo "— — — — —"; return; }
  if [[ $in != *.xyz ]]; then
    x="$tmp/$name.pre.xyz"
    "$sylva" preprocess "$in" -o "$x" --remove-ground --no-normals --quiet >/dev/null 2>&1 || { echo "— — — — —"; return; }
  fi
  rm -rf "$d"; mkdir -p "$d"
  cpu "$tmp/adt.cpu" "$adtree" "$x" "$d" >/dev/null 2>&1 # its batch mode exits 1 after writing
  local obj; obj=$(ls "$d"/*branches*.obj 2>/dev/null | head -1)
  [[ -n $obj ]] || { echo "$(cut -d' ' -f1 "$tmp/adt.cpu") — — — —"; return; }
  local lk; lk=$("$bench" look "$in" "$obj" 2>/dev/null)
  echo "$(cut -d' ' -f1 "$tmp/adt.cpu") $(kv iou_mean "$lk") $(kv iou_min "$lk") $(kv precision "$lk") $(kv recall "$lk")"
}

if [[ $parts == *r* ]]; then
  echo "(r) real scans: sylva run (no --species: the classifier's species) vs its scan; load $(load)"
  echo "| scan | points | species (leaf-off: returns on the traced wood) | IoU mean | IoU min | precision / recall | profile r | height err | width err | LOD0 bark tris | leaf inst. | leaves ≤5 cm of hull | IoU mean/min --leaf-off | AdTree IoU mean/min, precision / recall | returns as the asset, IoU 4 mm / spacing | .sylva B | run CPU s |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
  for f in $real; do
    in=$data/real/$f
    [[ -f $in ]] || { echo "| $f | missing |"; continue; }
    name=$(basename "$f" | sed 's/\.[^.]*$//')
    cpu "$tmp/run.cpu" "$sylva" run "$in" -o "$tmp/$name.glb" --sylva "$tmp/r_$name.sylva" --json > "$tmp/run.json" 2>"$tmp/err" ||
      { echo "| $f | run failed: $(tail -1 "$tmp/err") |"; continue; }
    r=$(cat "$tmp/run.json"); c=$(cut -d' ' -f1 "$tmp/run.cpu"); run_cpu[$name]=$c
    ev=$("$sylva" eval --points "$in" "$tmp/$name.glb" --json 2>/dev/null)
    "$sylva" run "$in" -o "$tmp/${name}_off.glb" --leaf-off --quiet 2>/dev/null
    off=$("$sylva" eval --points "$in" "$tmp/${name}_off.glb" --json 2>/dev/null)
    read -r at am an ap ar < <(adtree_look "$in" "$name")
    [[ $f == adtree/* && -n $adtree ]] && run_cpu[adt_$name]=$at
    sp=$(grep -o '"species":"[^"]*"' <<< "$r" | head -1 | cut -d'"' -f4)
    # The measure's ceiling on this scan: its own returns drawn as 4 mm
    # tetrahedra, then as wide as its spacing (bench_synthesize returns).
    own=$("$bench" returns "$in" 2>/dev/null)
    own4=$(sed -n 's/^radius=[0-9.]* iou_mean=\([0-9.]*\) .*/\1/p' <<< "$own")
    owns=$(sed -n 's/.* radius=[0-9.]* iou_mean=\([0-9.]*\) .*/\1/p' <<< "$own")
    # Leaf-off when the returns lie on the traced wood (returns_on_wood).
    lo=""; [[ $(key leaf_off "$r") == true ]] && lo=", leaf-off"
    row=$(key returns_on_wood "$r"); [[ $row != nan ]] && lo="$lo ($(f3 "$row") on wood)"
    echo "| $f | $(key points_preprocessed "$r") | ${sp:-—}$lo | $(f3 "$(key iou_mean "$ev")") | $(f3 "$(key iou_min "$ev")") |" \
      "$(f3 "$(key silhouette_precision "$ev")") / $(f3 "$(key silhouette_recall "$ev")") |" \
      "$(f3 "$(key profile_correlation "$ev")") | $(pct "$(key height_error_rel "$ev")") | $(pct "$(key crown_width_error_rel "$ev")") |" \
      "$(key lod0_bark_triangles "$r") | $(key lod0_leaf_instances "$r") | $(f3 "$(key leaves_in_hull "$r")") |" \
      "$(f3 "$(key iou_mean "$off")") / $(f3 "$(key iou_min "$off")") | $(f3 "$am") / $(f3 "$an"), $(f3 "$ap") / $(f3 "$ar") | $(f3 "$own4") / $(f3 "$owns") |" \
      "$(key sylva_bytes "$r") | $c |"
    if [[ -n ${RENDER:-} ]]; then
      mkdir -p "$RENDER"
      "$sylva" preprocess "$in" -o "$tmp/$name.xyz" --remove-ground --no-normals --quiet >/dev/null 2>&1
      node scripts/render_tree.mjs --glb "$tmp/$name.glb" --points "$tmp/$name.xyz" --out "$RENDER/$name.png" \
        --title "$f" --size 1200x600 >/dev/null 2>&1
    fi
  done
  echo "targets: IoU mean >= 0.85, every view >= 0.75, above AdTree's on every file; profile r >= 0.85;"
  echo "         |height| <= 5%, |width| <= 10%; LOD0 <= 60k bark triangles, <= 30k leaf instances; >= 95% of leaves within 5 cm;"
  echo "         .sylva < 40 kB"
  echo
fi

if [[ $parts == *a* ]]; then
  echo "(a) sylva run vs AdTree, CPU s (user+sys) on AdTree's own files; load $(load)"
  echo "| file | points | sylva run | AdTree | AdTree / sylva |"
  echo "|---|---|---|---|---|"
  for f in tree1 tree7 tree13 tree33 Lille_11 ahn3_delft house "tiny(for_debug)"; do
    in="$data/real/adtree/$f.xyz"
    [[ -f $in ]] || continue
    s=${run_cpu[$f]:-}
    [[ -n $s ]] || { cpu "$tmp/run.cpu" "$sylva" run "$in" -o "$tmp/a.glb" --quiet 2>/dev/null; s=$(cut -d' ' -f1 "$tmp/run.cpu"); }
    a=${run_cpu[adt_$f]:-}
    if [[ -z $a && -n $adtree ]]; then
      rm -rf "$tmp/adt"; mkdir -p "$tmp/adt"; cpu "$tmp/adt.cpu" "$adtree" "$in" "$tmp/adt" >/dev/null 2>&1; a=$(cut -d' ' -f1 "$tmp/adt.cpu")
    fi
    echo "| $f | $(wc -l < "$in") | $s | ${a:-—} | $(awk -v s="$s" -v a="${a:-}" 'BEGIN { if (a == "" || s <= 0) print "—"; else printf "%.2f", a / s }') |"
  done
  echo "target: AdTree / sylva >= 5 on every file"
  echo
fi

if [[ $parts == *s* ]]; then
  echo "(s) simulated terrestrial scans (seed $seed) vs the true tree's asset (sylva grow, same species and seed); load $(load)"
  echo "| species | points | IoU mean | IoU min | the scan's own IoU mean | leaf area ratio | branches r>=2cm asset (main) / truth | ratio | limb recall r>=2cm | visibility ceiling | run CPU s |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|"
  for ini in species/*.ini; do
    sp=$(basename "$ini" .ini)
    [[ -z ${SPECIES:-} || " $SPECIES " == *" $sp "* ]] || continue
    # 100k-300k points: a first scan at 0.15 degrees, rescanned coarser when
    # the tree is large (as bench/reconstruct does).
    step=0.15
    out=$("$sylva" scan "$sp" --seed "$seed" --scanner terrestrial --step $step -o "$tmp/$sp.las" --truth "$tmp/$sp.json" \
          --quiet --json 2>/dev/null) || { echo "| $sp | scan failed |"; continue; }
    n=$(key point_count "$out")
    if (( n > 300000 )); then
      step=$(awk -v s=$step -v n="$n" 'BEGIN { printf "%.3f", s * sqrt(n / 250000) }')
      out=$("$sylva" scan "$sp" --seed "$seed" --scanner terrestrial --step "$step" -o "$tmp/$sp.las" --truth "$tmp/$sp.json" \
            --quiet --json 2>/dev/null) || { echo "| $sp | scan failed |"; continue; }
    fi
    cpu "$tmp/run.cpu" "$sylva" run "$tmp/$sp.las" --species "$sp" -o "$tmp/$sp.glb" --sylva "$tmp/s_$sp.sylva" --quiet 2>/dev/null ||
      { echo "| $sp | run failed |"; continue; }
    "$sylva" grow --species "$sp" --seed "$seed" -o "$tmp/${sp}_true.glb" --quiet 2>/dev/null
    ev=$("$bench" lookglb "$tmp/${sp}_true.glb" "$tmp/$sp.glb" 2>/dev/null) # eval --points' silhouette alone
    # What the scanner saw, by the same measure: the true tree against the
    # scan's own returns (a crown top no station sees is missing from both
    # the scan and the asset).
    own=$("$sylva" eval --points "$tmp/$sp.las" "$tmp/${sp}_true.glb" --json 2>/dev/null)
    cmp=$("$bench" compare "$sp" "$seed" "$tmp/s_$sp.sylva" 2>&1)
    tr=$("$sylva" eval --truth "$tmp/$sp.json" "$tmp/s_$sp.sylva" --json 2>/dev/null)
    vis=$("$bench_visibility" "$tmp/$sp.las" "$tmp/$sp.json" 2>/dev/null | sed -n 's/.*of a wood return \([0-9.]*\),.*/\1/p')
    echo "| $sp | $(key point_count "$out") | $(f3 "$(kv iou_mean "$ev")") | $(f3 "$(kv iou_min "$ev")") | $(f3 "$(key iou_mean "$own")") |" \
      "$(f3 "$(kv leaf_area_ratio "$cmp")") | $(kv branches_r2cm "$cmp") ($(kv branches_r2cm_main "$cmp")) / $(kv branches_r2cm_truth "$cmp") |" \
      "$(f3 "$(kv branches_r2cm_ratio "$cmp")") | $(f3 "$(key recall_r2cm "$tr")") | $(f3 "${vis:-nan}") | $(cut -d' ' -f1 "$tmp/run.cpu") |"
  done
  echo "targets: IoU mean >= 0.80; leaf area ratio within 0.75-1.25; branches r>=2cm ratio within 0.70-1.30"
  echo
fi

if [[ $parts == *l* ]]; then
  echo "(l) simulated airborne scans (40 m, 10 pulses/m^2, seed $seed) vs the true tree's asset; load $(load)"
  echo "| species | returns | stem unseen | IoU mean | IoU min | height err | width err | DBH err | leaves | run CPU s |"
  echo "|---|---|---|---|---|---|---|---|---|---|"
  for ini in species/*.ini; do
    sp=$(basename "$ini" .ini)
    [[ -z ${SPECIES:-} || " $SPECIES " == *" $sp "* ]] || continue
    out=$("$sylva" scan "$sp" --seed "$seed" --scanner airborne --altitude 40 --density 10 -o "$tmp/l_$sp.las" \
          --truth "$tmp/l_$sp.json" --quiet --json 2>/dev/null) || { echo "| $sp | scan failed |"; continue; }
    cpu "$tmp/run.cpu" "$sylva" run "$tmp/l_$sp.las" --species "$sp" -o "$tmp/l_$sp.glb" --json > "$tmp/l_$sp.run" 2>/dev/null ||
      { echo "| $sp | run failed |"; continue; }
    [[ -f "$tmp/${sp}_true.glb" ]] || "$sylva" grow --species "$sp" --seed "$seed" -o "$tmp/${sp}_true.glb" --quiet 2>/dev/null
    ev=$("$bench" lookglb "$tmp/${sp}_true.glb" "$tmp/l_$sp.glb" 2>/dev/null)
    run=$(cat "$tmp/l_$sp.run")
    dbh=$(awk -v a="$(key dbh "$run")" -v t="$(grep -o '"dbh":[^,}]*' "$tmp/l_$sp.json" | head -1 | cut -d: -f2)" \
          'BEGIN { if (t > 0) print a / t - 1; else print "nan" }')
    echo "| $sp | $(key point_count "$out") | $(key stem_unseen "$run") | $(f3 "$(kv iou_mean "$ev")") | $(f3 "$(kv iou_min "$ev")") |" \
      "$(pct "$(kv height_error_rel "$ev")") | $(pct "$(kv crown_width_error_rel "$ev")") | $(pct "$dbh") | $(key leaves "$run") |" \
      "$(cut -d' ' -f1 "$tmp/run.cpu") |"
  done
  echo "no target of its own: the terrestrial ones (IoU mean >= 0.80 of (s)) for comparison"
  echo
fi

if [[ $parts == *d* ]]; then
  echo "(d) decode on one core (median of 5; synthesis + meshing LOD0, no export, no impostor); load $(load)"
  echo "| tree | species | LOD0 triangles | bark | leaf inst. | library ms | synthesis ms | mesh ms | decode ms |"
  echo "|---|---|---|---|---|---|---|---|---|"
  : > "$tmp/fit"
  for s in "$tmp"/r_*.sylva "$tmp"/s_*.sylva; do
    [[ -f $s ]] || continue
    d=$("$bench" decode "$s" 5 2>&1) || { echo "| $(basename "$s") | failed: $d |"; continue; }
    n=$(basename "$s" .sylva); n=${n#?_}
    echo "| $n | $(kv species "$d") | $(kv lod0_tris "$d") | $(kv lod0_bark_tris "$d") | $(kv leaf_instances "$d") |" \
      "$(kv library_ms "$d") | $(kv synth_ms "$d") | $(kv mesh_ms "$d") | $(kv decode_ms "$d") |"
    echo "$(kv lod0_tris "$d") $(kv decode_ms "$d")" >> "$tmp/fit"
  done
  # Sorted by decode time first, so the median needs no gawk-only asort (Debian's awk is mawk).
  sort -k2,2g "$tmp/fit" | awk '{ n++; x += $1; y += $2; xx += $1 * $1; xy += $1 * $2; yy += $2 * $2; v[n] = $2 }
    END { if (n < 3) exit; b = (n * xy - x * y) / (n * xx - x * x); a = (y - b * x) / n
      r = (n * xy - x * y) / sqrt((n * xx - x * x) * (n * yy - y * y)); m = v[int((n + 1) / 2)]
      printf "linearity: decode ms = %.2f + %.3f per 1k LOD0 triangles, r^2 = %.3f over %d trees; median %.1f ms\n", a, 1000 * b, r * r, n, m }'
  echo "target: <= 50 ms for a typical tree, linear in triangles"
  echo
fi

if [[ $parts == *k* ]]; then
  echo "(k) scan -> glb, 100k-point simulated quaking_aspen (sylva run, default threads); load $(load)"
  "$sylva" scan quaking_aspen --seed "$seed" --scanner terrestrial --step 0.15 --max-points 100000 -o "$tmp/k.las" --quiet
  cpu "$tmp/k.cpu" "$sylva" run "$tmp/k.las" --species quaking_aspen -o "$tmp/k.glb" --quiet
  read -r c m w < "$tmp/k.cpu"
  echo "points $("$sylva" info "$tmp/k.las" --json 2>/dev/null | grep -o '"point_count":[0-9]*' | cut -d: -f2): wall $w s, CPU $c s, peak RSS $((m / 1024)) MiB (load $(load))"
  echo "target: <= 3 s on this 2-core machine"
fi
