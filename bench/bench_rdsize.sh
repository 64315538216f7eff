#!/usr/bin/env bash
# bench/bench_rdsize.sh - smaller packages at equal error (issue 14): per material,
# `btf compress` as version 1 (equal-noise steps, raw 16-bit weights) and with `--rd`
# (version 3: rate-distortion steps for the same added error, deflated weights),
# k = 3, C = 8; bytes of the chunk files and the errors `btf eval` measures; the
# ratios are version 3 over version 1 in the same run. Run by bench/run.sh
# (results: bench/results/rdsize.txt); needs `make build` and jq.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD=${BUILD:-build}
BTF=$BUILD/btf
[[ -x $BTF ]] || { echo "bench_rdsize: $BTF is missing: run 'make build' first" >&2; exit 1; }
command -v jq >/dev/null || { echo "bench_rdsize: needs jq" >&2; exit 1; }
tmp=$(mktemp -d "${TMPDIR:-/tmp}/bench_rdsize.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
echo "# material: v1 bytes / RMSE / Lab | v3 bytes / RMSE / Lab | v3/v1 bytes, RMSE"
for spec in tiles64=gen:tiles:64:4242 knit64=gen:knit:64:4243 stone64=gen:stone:64:4244 knit128=gen:knit:128:4245; do
    name=${spec%%=*} src=${spec#*=}
    echo "bench_rdsize: $name" >&2
    row="# $name:"
    for v in v1 v3; do
        flag=(--plain)
        [[ $v == v3 ]] && flag=(--rd)
        b=$("$BTF" compress "$src" "$tmp/$name-$v" "${flag[@]}" --json | jq .bytes)
        read -r rmse lab < <("$BTF" eval "$src" "$tmp/$name-$v" --json --no-curve | jq -r '"\(.rgb_rmse) \(.lab_mae)"')
        echo "rdsize_${name}_${v}_bytes $b B"
        echo "rdsize_${name}_${v}_rmse $(printf %.4f "$rmse") rgb"
        echo "rdsize_${name}_${v}_lab $(printf %.4f "$lab") lab"
        eval "${v}_b=$b ${v}_r=$rmse"
        row+=" $b / $(printf %.3f "$rmse") / $(printf %.3f "$lab") |"
    done
    rb=$(awk -v a="$v3_b" -v b="$v1_b" 'BEGIN { printf "%.3f", a / b }')
    rr=$(awk -v a="$v3_r" -v b="$v1_r" 'BEGIN { printf "%.4f", a / b }')
    echo "rdsize_${name}_bytes_ratio $rb x"
    echo "rdsize_${name}_rmse_ratio $rr x"
    echo "$row ${rb}x, ${rr}x"
    rm -rf "$tmp/$name-v1" "$tmp/$name-v3"
done
