#!/usr/bin/env bash
# Batch targets (docs/batch.md), printed with the target beside each figure:
#   1. 50 simulated trees (about 5 M points) end to end: time per tree (wall and CPU), peak
#      memory, and throughput at 1 vs 2 workers (on --sub single-tree scans). With the segment
#      stage present (`sylva segment`), the 50 trees are one simulated plot; without it, 50
#      single-tree scans, and the output says so.
#   2. lidR Megaplot.las and TreeLS pine_plot.las end to end with the report rendered in
#      headless Chromium (screenshot to --shot).
#   3. 20 kills at random moments, then a resume: outputs identical to an uninterrupted run.
# Usage: bench/batch/bench_batch.sh [--build DIR] [--work DIR] [--trees 50] [--sub 10] [--kills 20]
#        [--shot docs/pictures/batch_report.png] [--only trees|plots|kills] [--nice 10]
# The machine is shared: run under nice; CPU times (user+sys) are the figures to trust.
set -u
here=$(cd "$(dirname "$0")/../.." && pwd)
build=$here/build work=/tmp/sylva-bench-batch trees=50 sub=10 kills=20 shot=$here/docs/pictures/batch_report.png only=all niceness=10
while [[ $# -gt 0 ]]; do
    case $1 in
    --build) build=$2; shift 2 ;; --work) work=$2; shift 2 ;; --trees) trees=$2; shift 2 ;;
    --sub) sub=$2; shift 2 ;; --kills) kills=$2; shift 2 ;; --shot) shot=$2; shift 2 ;; --only) only=$2; shift 2 ;;
    --nice) niceness=$2; shift 2 ;;
    *) echo "bench_batch: unknown option $1"; exit 1 ;;
    esac
done
data=$here/../shared/data/real
mkdir -p "$work/bin"
# A private copy of the executables, so that a rebuild during the bench changes nothing.
cp "$build/sylva" "$work/bin/sylva"
cp "$build/sylva-pipeline" "$work/bin/sylva-pipeline"
[[ -x $build/sylva-view ]] && cp "$build/sylva-view" "$work/bin/sylva-view"
sylva=$work/bin/sylva
export SYLVA_VIEW=$work/bin/sylva-view SYLVA_LIBRARY=$here/species SYLVA_THREE=$here/node_modules/three
has_segment=0
"$sylva" --help 2>&1 | grep -q '^ *segment ' && has_segment=1
# cpu_of LOG: user+sys seconds and peak RSS (kB) from /usr/bin/time -v.
cpu_of() { awk -F': ' '/User time/ {u=$2} /System time/ {s=$2} /Maximum resident/ {m=$2} END {printf "%.1f %d", u+s, m}' "$1"; }
tree_stats() { # OUTDIR: trees ok, mean wall s, mean cpu s, max worker peak RSS MB, points
    jq -s '[.[] | select(.status == "ok")] | [length, (map(.seconds.total) | add / length), (map(.seconds.cpu) | add / length),
      (map(.peak_rss_kb) | max / 1024), (map(.metrics.points_in) | add)] | @tsv' -r "$1"/trees/*.json
}
species=(quaking_aspen black_oak european_pine balsam_fir silver_birch sugar_maple european_beech norway_spruce
    london_plane sassafras lombardy_poplar weeping_willow palm)

if [[ $only == all || $only == trees ]]; then
    echo "== 1. $trees simulated trees end to end (machine load: $(cut -d' ' -f1-3 /proc/loadavg))"
    in=$work/trees
    mkdir -p "$in" "$work/sub"
    if [[ $has_segment == 1 ]]; then
        mode="one simulated plot of $trees trees (segmented first)"
        [[ -s $in/plot.las ]] || nice -n "$niceness" "$sylva" scan --plot 60 --trees "$trees" --step 0.1 --seed 11 -o "$in/plot.las" --quiet
    else
        mode="$trees single-tree scans (the segment stage has not landed on this branch: no plot)"
        for ((k = 0; k < trees; k++)); do
            f=$(printf '%s/t%02d.las' "$in" "$k")
            [[ -s $f ]] || nice -n "$niceness" "$sylva" scan "${species[k % ${#species[@]}]}" --seed $((k + 1)) --step 0.3 --no-terrain \
                -o "$f" --quiet
        done
    fi
    echo "input: $mode"
    # Throughput at 1 vs 2 workers on --sub single-tree scans of the library's species (a plot is
    # segmented by one worker first, which would hide the tree workers' scaling).
    for ((k = 0; k < sub; k++)); do
        f=$(printf '%s/s%02d.las' "$work/sub" "$k")
        [[ -s $f ]] || nice -n "$niceness" "$sylva" scan "${species[k % ${#species[@]}]}" --seed $((k + 1)) --step 0.3 --no-terrain \
            -o "$f" --quiet
    done
    for w in 1 2; do
        rm -rf "$work/out_w$w"
        /usr/bin/time -v nice -n "$niceness" "$sylva" batch "$work/sub" -o "$work/out_w$w" --workers "$w" --quiet 2> "$work/time_w$w.log"
        wall[$w]=$(awk -F': ' '/Elapsed/ {n = split($2, a, ":"); s = 0; for (i = 1; i <= n; i++) s = s * 60 + a[i]; print s}' "$work/time_w$w.log")
        read -r cpu[$w] rss[$w] <<< "$(cpu_of "$work/time_w$w.log")"
    done
    printf '%-38s %10s %10s %10s\n' "throughput ($sub single trees)" "1 worker" "2 workers" "ratio"
    printf '%-38s %10.1f %10.1f %10.2f  (target: near-linear, 2.0)\n' "wall s" "${wall[1]}" "${wall[2]}" \
        "$(awk -v a="${wall[1]}" -v b="${wall[2]}" 'BEGIN { print a / b }')"
    printf '%-38s %10.2f %10.2f\n' "trees per wall minute" "$(awk -v s="${wall[1]}" -v n="$sub" 'BEGIN { print 60 * n / s }')" \
        "$(awk -v s="${wall[2]}" -v n="$sub" 'BEGIN { print 60 * n / s }')"
    printf '%-38s %10.1f %10.1f  (same work: the CPU should match)\n' "CPU s (user+sys, all processes)" "${cpu[1]}" "${cpu[2]}"
    rm -rf "$work/out_all"
    /usr/bin/time -v nice -n "$niceness" "$sylva" batch "$in" -o "$work/out_all" --workers 2 --quiet 2> "$work/time_all.log"
    read -r cpu_all rss_all <<< "$(cpu_of "$work/time_all.log")"
    IFS=$'\t' read -r ok mwall mcpu mrss pts <<< "$(tree_stats "$work/out_all")"
    wall_all=$(awk -F': ' '/Elapsed/ {n = split($2, a, ":"); s = 0; for (i = 1; i <= n; i++) s = s * 60 + a[i]; print s}' "$work/time_all.log")
    printf '%-38s %s of %s trees, %s points\n' "made" "$ok" "$(ls "$work/out_all/trees/"*.json | wc -l)" "$pts"
    printf '%-38s %.0f s wall, %.0f s CPU\n' "whole batch (2 workers)" "$wall_all" "$cpu_all"
    printf '%-38s %.1f s wall, %.1f s CPU per tree\n' "per tree (worker's own)" "$mwall" "$mcpu"
    printf '%-38s %.0f MB largest worker (its own getrusage), %.0f MB largest process (time -v)\n' "peak memory" "$mrss" \
        "$(awk -v k="$rss_all" 'BEGIN { print k / 1024 }')"
    jq -s -r '[.[] | select(.status == "ok") | .seconds] | [(map(.preprocess) | add), (map(.skeleton + .clusters) | add),
        (map(.classify) | add), (map(.synthesize + .mesh + .export) | add), (map(.eval) | add), (map(.thumbnail) | add)] |
        "stage wall s (sum): preprocess \(.[0] | floor), skeleton+clusters \(.[1] | floor), classify \(.[2] | floor), synth+mesh+export \(.[3] | floor), eval \(.[4] | floor), thumbnail \(.[5] | floor)"' \
        "$work"/out_all/trees/*.json
fi

if [[ $only == all || $only == plots ]]; then
    echo "== 2. real plots end to end, report rendered"
    for p in "$data/lidr/Megaplot.las" "$data/treels/pine_plot.las"; do
        name=$(basename "$p" .las)
        rm -rf "$work/plot_$name"
        /usr/bin/time -v nice -n "$niceness" "$sylva" batch "$p" -o "$work/plot_$name" --workers 2 --quiet 2> "$work/time_$name.log"
        read -r c r <<< "$(cpu_of "$work/time_$name.log")"
        printf '%-16s %s  (%.0f s CPU, peak %.0f MB)%s\n' "$name" "$(jq -c .counts "$work/plot_$name/index.json")" "$c" \
            "$(awk -v k="$r" 'BEGIN { print k / 1024 }')" "$([[ $has_segment == 0 ]] && echo ' - no segment stage: the plot ran as ONE tree')"
        node --experimental-websocket "$here/tests/three/report_check.mjs" "$work/plot_$name/report.html" --max 3 \
            --png "$work/report_$name.png" > "$work/report_$name.json" 2> /dev/null
        echo "  report in Chromium: $(jq -c '{errors: (.errors | length), thumbnails, placeholders, previews: [.trees[] | .coverage]}' "$work/report_$name.json")"
    done
    [[ -n $shot ]] && cp "$work/report_Megaplot.png" "$shot" 2> /dev/null && echo "  screenshot: $shot"
fi

if [[ $only == all || $only == kills ]]; then
    echo "== 3. $kills kills at random moments, then a resume"
    kin=$work/kin
    mkdir -p "$kin"
    # Terrestrial single-tree scans (a few seconds a tree), so that the kills land mid-tree; the
    # three airborne samples were made in under a second, and every kill after the second found
    # the batch finished.
    for ((k = 0; k < 6; k++)); do
        f=$(printf '%s/k%02d.las' "$kin" "$k")
        [[ -s $f ]] || nice -n "$niceness" "$sylva" scan "${species[k % ${#species[@]}]}" --seed $((k + 1)) --step 0.3 --no-terrain \
            -o "$f" --quiet
    done
    rm -rf "$work/kref" "$work/kkill"
    t0=$(date +%s%N)
    nice -n "$niceness" "$sylva" batch "$kin" -o "$work/kref" --workers 2 --no-eval --no-thumbnails --quiet
    # Each run resumes the last, killed at a moment drawn over the whole of an uninterrupted run,
    # so the kills land in every phase: start-up, a tree's stages, a record's commit, and (once
    # the batch is complete) a resume with nothing to do. A killed tree starts again on resume.
    span=$((($(date +%s%N) - t0) / 1000000))
    total=$(ls "$work"/kref/trees/*.json | wc -l)
    echo "  uninterrupted run: $((span / 1000)) s wall (load $(cut -d' ' -f1 /proc/loadavg)), $total trees; kills drawn in 0.1 .. $((span / 1000)) s after each start"
    mid=0
    RANDOM=20
    moments=()
    for ((k = 0; k < kills; k++)); do
        ms=$((100 + (RANDOM * 32768 + RANDOM) % (span - 99)))
        before=$(ls "$work"/kkill/trees/*.json 2> /dev/null | wc -l)
        [[ $before -lt $total ]] && mid=$((mid + 1))
        moments+=("$ms")
        nice -n "$niceness" "$sylva" batch "$kin" -o "$work/kkill" --workers 2 --no-eval --no-thumbnails --quiet &
        pid=$!
        sleep "$(awk -v m="$ms" 'BEGIN { print m / 1000 }')"
        kill -9 "$pid" 2> /dev/null
        wait "$pid" 2> /dev/null
        done_now=$(ls "$work"/kkill/trees/*.json 2> /dev/null | wc -l)
        echo "  kill $((k + 1)) at $ms ms: $done_now records so far"
    done
    echo "  $mid of $kills kills landed while trees were still to run"
    # The resume starts at once: the killed workers may still be unreaped (sy_process_gone).
    nice -n "$niceness" "$sylva" batch "$kin" -o "$work/kkill" --workers 2 --no-eval --no-thumbnails --quiet
    same() {
        ( cd "$1" && for f in $(find trees -type f \( -name '*.glb' -o -name '*.sylva' -o -name '*.png' -o -name '*.glb.js' \) | sort); do sha1sum "$f"; done
          for f in trees/*.json; do echo "$f"; jq -S 'del(.seconds, .peak_rss_kb)' "$f"; done
          jq -S 'del(.trees[].seconds)' index.json; cat trees.csv; sed 's/[0-9.]* s\b//g' report.html | sha1sum )
    }
    if diff <(same "$work/kref") <(same "$work/kkill") > "$work/kill.diff"; then
        echo "  resumed after $kills kills: outputs IDENTICAL to the uninterrupted run (target: identical); temp files left: $(find "$work/kkill" -name '.tmp.*' | wc -l)"
    else
        echo "  resumed after $kills kills: outputs DIFFER ($(wc -l < "$work/kill.diff") diff lines, $work/kill.diff)"
    fi
fi
