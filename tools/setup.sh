#!/usr/bin/env bash
# Installs what the project needs and is missing; idempotent.
# Debian packages only where `dpkg -s` says absent; `npm ci` where package.json exists.
set -euo pipefail
cd "$(dirname "$0")/.."

PKGS=(build-essential pkg-config clang
      libopenimageio-dev openimageio-tools
      libosmesa6-dev libegl-dev libgles-dev libegl-mesa0 libgl1-mesa-dri libgbm-dev
      libwebsockets-dev liblapacke-dev libopenblas-dev libcjson-dev libcriterion-dev
      libgsl-dev gnuplot-nox chromium nginx-light zlib1g-dev libomp-14-dev time
      libqhull-dev libwebp-dev libavif-dev libtinygltf-dev haproxy python3 jq zstd xz-utils)

missing=()
for p in "${PKGS[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing ${missing[*]}"
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

if [ -f package.json ]; then
    if [ ! -d node_modules ] || [ package-lock.json -nt node_modules ]; then
        npm ci --no-audit --no-fund --loglevel=error
        touch node_modules
    fi
fi
echo "setup: all dependencies present"
