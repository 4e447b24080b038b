#!/usr/bin/env bash
# Rebuilds the shipped species classifier, species/classifier.sjb, from
# simulated scans of every species in the library (docs/classify.md):
#   species/train-classifier.sh [--trees N] [--work DIR] [--unseen] [--jobs J] [--sylva BIN] [--out MODEL]
#                               [--reuse-features]
# Every library species gets N trees (default 180), each grown from its own seed
# and scanned with one of twelve settings in turn: terrestrial with 4, 3 and 2
# stations (occlusion), coarse and fine steps, extra range noise, leaf-off;
# mobile leaf-on and leaf-off; airborne at 50 and 20 pulses/m^2; and four
# stand settings (sylva scan --forest/--neighbours/--clip: a forest-grown tree
# among 4-6 neighbours, seen from stations inside the stand, from a mobile
# circle and from the air, two of them cut to a 1.25 m / 2 m cylinder round the
# stem as plot segmentation does). The features go to WORK/train.tsv and the
# model to --out. --unseen also scans N/4 trees per species (other seeds) with
# six settings the model never sees (5 and 6 stations, other steps, heights and
# noise, a fast high mobile pass, airborne at 100 and 10 pulses/m^2 from other
# altitudes, a sparser stand with a 1.6 m cylinder) into WORK/unseen.tsv for
# bench_classify. Same sylva, same arguments: the same model, byte for byte.
# --reuse-features trains on WORK/train.tsv as it is (after a change to the
# classifier but not to the features: the same model as from the scans).
# Add a species (a new species/*.ini) and rerun this: nothing else changes.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
trees=180 work="" unseen=0 jobs=2 sylva="" out="$here/classifier.sjb" reuse=0
while [ $# -gt 0 ]; do
  case "$1" in
    --trees) trees=$2; shift 2 ;;
    --work) work=$2; shift 2 ;;
    --unseen) unseen=1; shift ;;
    --jobs) jobs=$2; shift 2 ;;
    --sylva) sylva=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --reuse-features) reuse=1; shift ;;
    *) echo "train-classifier.sh: unknown argument $1" >&2; exit 1 ;;
  esac
done
[ -n "$sylva" ] || sylva="$here/../build/sylva"
[ -x "$sylva" ] || { echo "train-classifier.sh: no sylva at $sylva (build it, or pass --sylva)" >&2; exit 1; }
[ -n "$work" ] || work="$here/../build/classifier-data"
mkdir -p "$work/train" "$work/unseen"
if [ "$reuse" = 1 ]; then
  "$sylva" train --features-in "$work/train.tsv" -o "$out" --seed 1
  echo "train-classifier.sh: wrote $out" >&2
  exit 0
fi

species=$(cd "$here" && ls *.ini | sed 's/\.ini$//' | sort)

seen_settings=(
  "tls4|--positions 4 --step 0.3 --divergence 0"
  "tls3noise|--positions 3 --step 0.35 --noise 0.01 --divergence 0"
  "tls2|--positions 2 --step 0.25 --divergence 0"
  "tls4leafoff|--positions 4 --step 0.3 --divergence 0 --no-leaves"
  "mls|--scanner mobile --step 1 --rotation 10 --divergence 0"
  "mlsleafoff|--scanner mobile --step 0.8 --rotation 10 --noise 0.02 --divergence 0 --no-leaves"
  "als50|--scanner airborne --density 50"
  "als20|--scanner airborne --density 20 --altitude 120 --noise 0.04"
  "tlsstand|--positions 3 --step 0.4 --divergence 0 --forest 0.7 --neighbours 4 --radius 7 --isolate"
  "tlsstandclip|--positions 3 --step 0.4 --divergence 0 --forest 1 --neighbours 6 --radius 5 --clip 1.25"
  "mlsstandclip|--scanner mobile --step 1 --rotation 10 --divergence 0 --forest 0.9 --neighbours 5 --radius 6 --clip 2"
  "alsstand|--scanner airborne --density 40 --forest 0.8 --neighbours 5 --isolate"
)
unseen_settings=(
  "tls5|--positions 5 --step 0.2 --radius 14 --divergence 0"
  "tls6noise|--positions 6 --step 0.4 --noise 0.015 --height 1.2 --divergence 0"
  "mlsfast|--scanner mobile --speed 2 --step 1.2 --rotation 8 --height 2.5 --divergence 0"
  "als100|--scanner airborne --density 100 --altitude 150"
  "als10leafoff|--scanner airborne --density 10 --altitude 60 --no-leaves"
  "tlsstand5clip|--positions 4 --step 0.45 --height 1.2 --noise 0.01 --divergence 0 --forest 0.85 --neighbours 3 --radius 8 --clip 1.6"
)

# One line per scan: output path, species, seed, arguments.
jobs_file="$work/jobs.txt"
: > "$jobs_file"
add_jobs() { # dir count seed0 settings...
  local dir=$1 count=$2 seed0=$3; shift 3
  local settings=("$@") k=${#settings[@]}
  for sp in $species; do
    for ((t = 0; t < count; t++)); do
      local s=${settings[$((t % k))]} name=${settings[$((t % k))]%%|*}
      local seed=$((seed0 + t))
      echo "$work/$dir/${sp}__${name}__s${seed}.las $sp $seed ${s#*|}" >> "$jobs_file"
    done
  done
}
add_jobs train "$trees" 1 "${seen_settings[@]}"
[ "$unseen" = 1 ] && add_jobs unseen $(((trees + 3) / 4)) 5001 "${unseen_settings[@]}"

total=$(wc -l < "$jobs_file")
echo "train-classifier.sh: $total scans into $work ($jobs at a time)" >&2
export SYLVA_BIN="$sylva"
# Finished scans are kept (written atomically), so an interrupted run resumes.
xargs -P "$jobs" -L 1 bash -c 'out=$0 sp=$1 seed=$2; shift 2; [ -s "$out" ] || "$SYLVA_BIN" scan "$sp" --seed "$seed" "$@" -o "$out" --quiet' < "$jobs_file"

# Scans no longer in the job list (a removed species, fewer trees) are not trained on.
list=$(cut -d' ' -f1 "$jobs_file" | grep "/train/")
"$sylva" train $list --skip-bad --features-out "$work/train.tsv" -o "$out" --seed 1
if [ "$unseen" = 1 ]; then
  # A leaf-off palm seen from the air at 10 pulses/m^2 is a handful of points: skipped.
  "$sylva" train $(cut -d' ' -f1 "$jobs_file" | grep "/unseen/") --skip-bad --features-out "$work/unseen.tsv"
fi
echo "train-classifier.sh: wrote $out" >&2
