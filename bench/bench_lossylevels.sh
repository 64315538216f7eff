#!/usr/bin/env bash
# bench/bench_lossylevels.sh - what spatial levels cost over the default package
# (issue 36 item 3; doc/performance.md section 7, "Over lossy textures"): per
# material, `btf compress` without levels (version 3, a lossy WebP texture where it
# wins) and with `--levels 4` (version 4: a lossy component's coarse levels lossy at
# the coarsest quality that keeps each level's CIELab at or below level 0's,
# package-format.md section 10.7), then both again with `--lossless`, and both
# under the budget search (`--max-error LEVELS_SEARCH_ERROR`, default 2.4).
# Prints bytes (chunk files + manifest), the levels' cost as a ratio over the same
# mode without levels, the coarse levels' own bytes, and `btf eval`'s CIELab at
# level 0 (the levels leave it unchanged). Tiles and knit at 128x128 (about 16 minutes
# on 2 cores), tiles at 256x256 unless LEVELS_LARGE=0 (about 23 minutes more), the
# thesis wool at 256x256 with LEVELS_LARGE=2 when ../shared has it.
# Run by bench/run.sh (results: bench/results/lossylevels.txt); needs `make build`
# and jq.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD=${BUILD:-build}
BTF=$BUILD/btf
[[ -x $BTF ]] || { echo "bench_lossylevels: $BTF is missing: run 'make build' first" >&2; exit 1; }
command -v jq >/dev/null || { echo "bench_lossylevels: needs jq" >&2; exit 1; }
SHARED=${BTF_SHARED:-../shared}
# Seeds no test uses; NAME=SOURCE.
mats=(tiles128=gen:tiles:128:3641 knit128=gen:knit:128:3642)
[[ ${LEVELS_LARGE:-1} == 0 ]] || mats+=(tiles256=gen:tiles:256:3651)
[[ ${LEVELS_LARGE:-1} == 2 && -f $SHARED/data/thesis-ubo2003/wool/meta.json ]] &&
    mats+=("wool256=$SHARED/data/thesis-ubo2003/wool")
[[ -n ${LEVELS_MATERIALS:-} ]] && read -r -a mats <<<"$LEVELS_MATERIALS"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/bench_lossylevels.XXXXXX")
trap 'rm -rf "$tmp"' EXIT

source bench/lib.sh
# Bytes of its coarse levels' texture files (level >= 1).
coarse() { jq -r '[.chunks[] | select((.level // 0) >= 1) | .files[] | select(startswith("tex-"))] | unique | .[]' \
    "$1/manifest.json" | (cd "$1" && xargs -r stat -c %s) | awk '{ s += $1 } END { print s + 0 }'; }
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", a / b }'; }

echo "# material mode: no levels B | --levels 4 B (coarse levels B) | ratio | Lab at level 0 without / with levels"
for m in "${mats[@]}"; do
    IFS== read -r name src <<<"$m"
    for mode in default lossless search; do
        flags=()
        [[ $mode == lossless ]] && flags=(--lossless)
        [[ $mode == search ]] && flags=(--max-error "${LEVELS_SEARCH_ERROR:-2.4}")
        echo "bench_lossylevels: $name $mode" >&2
        "$BTF" compress "$src" "$tmp/a" --no-thumbnail --quiet "${flags[@]}"
        "$BTF" compress "$src" "$tmp/b" --no-thumbnail --quiet --levels 4 "${flags[@]}"
        ba=$(package_bytes "$tmp/a") bb=$(package_bytes "$tmp/b") cb=$(coarse "$tmp/b")
        la=$("$BTF" eval "$src" "$tmp/a" --json --no-curve | jq -r .lab_mae)
        lb=$("$BTF" eval "$src" "$tmp/b" --json --no-curve | jq -r .lab_mae)
        lossy=0 # coarse texture files that are lossy WebPs ("VP8 " chunk at byte 12)
        for f in $(jq -r '.chunks[] | select((.level // 0) >= 1) | .files[] | select(endswith(".webp"))' \
            "$tmp/b/manifest.json"); do
            [[ $(head -c 16 "$tmp/b/$f" | tail -c 4) == "VP8 " ]] && lossy=$((lossy + 1))
        done
        echo "lossylevels_${name}_${mode}_bytes $ba B"
        echo "lossylevels_${name}_${mode}_levels_bytes $bb B"
        echo "lossylevels_${name}_${mode}_coarse_bytes $cb B"
        echo "lossylevels_${name}_${mode}_levels_ratio $(ratio "$bb" "$ba") x"
        echo "# $name $mode: $ba B | $bb B (coarse $cb B, $lossy coarse files lossy) | $(ratio "$bb" "$ba")x | Lab $(printf %.4f "$la") / $(printf %.4f "$lb")"
        rm -rf "$tmp/a" "$tmp/b"
    done
done
