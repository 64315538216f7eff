#!/usr/bin/env bash
# The README's product picture: the stool of `btf gen-model` with a knitted seat and a
# stone frame (generated materials, compressed as linear light) under the built-in
# studio environment (doc/lighting.md). Writes doc/figures/product-studio.png.
set -euo pipefail
cd "$(dirname "$0")/.."
btf=${BTF_BIN:-build/btf}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$btf" compress gen:knit:64 "$tmp/knit" --linear --quiet
"$btf" compress gen:stone:64 "$tmp/stone" --linear --quiet
"$btf" gen-model "$tmp/stool.glb"
"$btf" render - doc/figures/product-studio.png --model "$tmp/stool.glb" --bind "Seat=$tmp/knit,4" \
    --bind "Frame=$tmp/stone" --environment studio --no-light --size 640x480 --background 0.93,0.93,0.93
echo "wrote doc/figures/product-studio.png"
