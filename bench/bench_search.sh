#!/usr/bin/env bash
# bench/bench_search.sh - what the budget search costs (issue 14: "within 3x one
# plain compress"): per material, the wall time of `btf compress` with its defaults,
# of `btf compress --rd`, and of the search `--rd --max-bytes N` (N = the thesis
# format's bytes at k = 3, C = 8, as bench_rd.sh uses), one after another in this
# script; the ratios are the search over each plain compress. Seeds no test uses.
# SEARCH_LARGE=1 adds tiles at 256x256 (about half an hour). Run by bench/run.sh
# (results: bench/results/search.txt); needs `make build` and jq.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD=${BUILD:-build}
BTF=$BUILD/btf
[[ -x $BTF ]] || { echo "bench_search: $BTF is missing: run 'make build' first" >&2; exit 1; }
command -v jq >/dev/null || { echo "bench_search: needs jq" >&2; exit 1; }
mats=(tiles128=gen:tiles:128:6161 stone128=gen:stone:128:6162)
[[ ${SEARCH_LARGE:-0} != 0 ]] && mats+=(tiles256=gen:tiles:256:5151)
[[ -n ${SEARCH_MATERIALS:-} ]] && read -r -a mats <<<"$SEARCH_MATERIALS"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/bench_search.XXXXXX")
trap 'rm -rf "$tmp"' EXIT

# Wall seconds of one command.
seconds() {
    local s e
    s=$(date +%s.%N)
    "$@" >/dev/null
    e=$(date +%s.%N)
    awk -v s="$s" -v e="$e" 'BEGIN { printf "%.1f", e - s }'
}

echo "# material: plain s | plain --rd s | search (--rd --max-bytes thesis bytes) s | search / plain, search / plain --rd | chosen"
for spec in "${mats[@]}"; do
    name=${spec%%=*} src=${spec#*=}
    echo "bench_search: $name" >&2
    "$BTF" export-thesis "$src" "$tmp/$name-thesis" --k 3 --components 8 >/dev/null
    tb=$(find "$tmp/$name-thesis" -type f -printf '%s\n' | awk '{s += $1} END {print s}')
    tp=$(seconds "$BTF" compress "$src" "$tmp/$name-plain" --quiet)
    tr=$(seconds "$BTF" compress "$src" "$tmp/$name-rd" --rd --quiet)
    ts=$(seconds "$BTF" compress "$src" "$tmp/$name-search" --rd --max-bytes "$tb" --quiet)
    chosen=$(jq -r '.budget | "k \(.k) \(.components) components \(.rd_steps // "equal-noise") \(.center // "none") \(.chunks) chunks"' \
        "$tmp/$name-search/manifest.json")
    r1=$(awk -v a="$ts" -v b="$tp" 'BEGIN { printf "%.2f", a / b }')
    r2=$(awk -v a="$ts" -v b="$tr" 'BEGIN { printf "%.2f", a / b }')
    echo "search_${name}_plain_seconds $tp s"
    echo "search_${name}_plain_rd_seconds $tr s"
    echo "search_${name}_seconds $ts s"
    echo "search_${name}_over_plain $r1 x"
    echo "search_${name}_over_plain_rd $r2 x"
    echo "# $name: $tp | $tr | $ts | ${r1}x, ${r2}x | $chosen"
    rm -rf "$tmp/$name"-*
done
