#!/usr/bin/env bash
# Installs exactly what Sylva needs to build, test and benchmark, on Debian 12 as root.
# Idempotent: a second run only checks. Set SYLVA_SKIP_APT=1 to skip the apt part.
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES=(
  # build
  build-essential cmake pkg-config ccache clang libclang-rt-14-dev
  # geometry and images
  libpcl-dev libcgal-dev libgmp-dev libmpfr-dev libeigen3-dev
  libopencv-core-dev libopencv-imgproc-dev
  libtinygltf-dev libmeshoptimizer-dev nlohmann-json3-dev libstb-dev
  # GL preview and headless rendering
  libglfw3-dev libepoxy-dev libegl-dev libegl-mesa0 libgl1-mesa-dri xvfb xauth
  # classification baseline (xgboost C API) and photogrammetry (COLMAP CLI as a subprocess)
  libxgboost-dev colmap
  # tests: a second glTF client (three.js in headless Chromium), image tools
  libcmocka-dev nodejs npm chromium imagemagick jq
  # batch scale-out: the Slurm test starts a single-node cluster (slurmctld, slurmd, munged) on loopback
  slurm-wlm munge procps
)

missing=()
for p in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
# node/npm may come from the machine image rather than Debian: do not fight it.
if command -v node >/dev/null && command -v npm >/dev/null; then
  filtered=(); for p in "${missing[@]}"; do [[ $p == nodejs || $p == npm ]] || filtered+=("$p"); done
  missing=("${filtered[@]}")
fi
if [[ ${SYLVA_SKIP_APT:-0} != 1 && ${#missing[@]} -gt 0 ]]; then
  echo "install-deps: installing ${#missing[@]} Debian packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# Node test tools (Khronos glTF validator), pinned by the committed lock file.
if [[ -f package-lock.json ]]; then
  # Reinstall whenever the lock file changed since the last install.
  stamp=node_modules/.sylva-lock.sha256
  want=$(sha256sum package-lock.json | cut -d' ' -f1)
  if [[ ! -f $stamp || $(cat "$stamp") != "$want" ]]; then
    echo "install-deps: npm ci"
    npm ci --no-audit --no-fund --loglevel=error
    echo "$want" > "$stamp"
  fi
fi
echo "install-deps: ok"
