#!/usr/bin/env bash
# bench/bench_search.sh - what the budget search costs (issue 14: "within 3x one
# plain compress"): per material, the wall time of `btf compress` with its defaults,
# of `btf compress --rd` (each the median of 3, alternating), of the version-1
# search `--max-bytes N` and of the version-3 search `--rd --max-bytes N` (N = the
# thesis format's bytes at k = 3, C = 8, as bench_rd.sh uses), wall and CPU time,
# one after another in this script; the ratios are each search over the plain
# compresses. Then both searches again with --full-search (every candidate on the
# whole material, not on its centre window): their cost, and the CIELab error each
# package reached (the manifest's budget.lab), screened over whole. Seeds no test
# uses.
# SEARCH_LARGE=1 adds tiles at 256x256 (about half an hour); SEARCH_FULL=0 leaves the
# --full-search comparison out (SEARCH_MATERIALS="tiles256=gen:tiles:256:5151"
# SEARCH_FULL=0: the 256x256 cost alone, about 9 minutes). Run by bench/run.sh
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

# "WALL CPU" seconds of one command (CPU: user + system time, its threads included,
# steadier than the wall time when the host is busy); its errors shown if it fails.
measure() {
    local TIMEFORMAT='%R %U %S' t
    if ! t=$({ time "$@" >/dev/null 2>"$tmp/err"; } 2>&1); then
        cat "$tmp/err" >&2
        return 1
    fi
    awk '{ printf "%.1f %.1f", $1, $2 + $3 }' <<<"$t"
}

# The middle of three numbers.
median3() { printf '%s\n' "$@" | sort -g | sed -n 2p; }

# a / b to two decimals.
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", a / b }'; }

# The result lines of one measured pair: search_NAME_KEY_seconds WALL and
# search_NAME_KEY_cpu_seconds CPU.
seconds_lines() { printf 'search_%s_%s_seconds %s s\nsearch_%s_%s_cpu_seconds %s s\n' "$1" "$2" "$3" "$1" "$2" "$4"; }

# The same for a pair of ratios: search_NAME_KEY WALL, search_NAME_KEY_cpu CPU.
ratio_lines() { printf 'search_%s_%s %s x\nsearch_%s_%s_cpu %s x\n' "$1" "$2" "$3" "$1" "$2" "$4"; }

echo "# wall s (CPU s): plain, the median of 3 | search | plain --rd, the median of 3 | search --rd | search / its plain, wall (CPU) | search --rd / plain --rd | chosen by search --rd"
for spec in "${mats[@]}"; do
    name=${spec%%=*} src=${spec#*=}
    echo "bench_search: $name" >&2
    "$BTF" export-thesis "$src" "$tmp/$name-thesis" --k 3 --components 8 >/dev/null
    tb=$(find "$tmp/$name-thesis" -type f -printf '%s\n' | awk '{s += $1} END {print s}')
    pw=() pc=() rw=() rc=()
    for i in 1 2 3; do # the plain compresses alternate, so a slow spell hits both
        read -r w c <<<"$(measure "$BTF" compress "$src" "$tmp/$name-plain" --plain --quiet)"
        pw+=("$w") pc+=("$c")
        read -r w c <<<"$(measure "$BTF" compress "$src" "$tmp/$name-rd" --rd --quiet)"
        rw+=("$w") rc+=("$c")
    done
    read -r tpw tpc <<<"$(median3 "${pw[@]}") $(median3 "${pc[@]}")"
    read -r trw trc <<<"$(median3 "${rw[@]}") $(median3 "${rc[@]}")"
    read -r tvw tvc <<<"$(measure "$BTF" compress "$src" "$tmp/$name-v1" --max-bytes "$tb" --plain --quiet)"
    read -r tsw tsc <<<"$(measure "$BTF" compress "$src" "$tmp/$name-search" --rd --max-bytes "$tb" --quiet)"
    # the same searches measuring every candidate on the whole material, not on its
    # centre window: what the window costs in error (the compressor's own CIELab of
    # the package as written, its 256-texel subsample)
    if [[ ${SEARCH_FULL:-1} != 0 ]]; then
        read -r tfvw tfvc <<<"$(measure "$BTF" compress "$src" "$tmp/$name-v1full" --max-bytes "$tb" --full-search --plain --quiet)"
        read -r tfsw tfsc <<<"$(measure "$BTF" compress "$src" "$tmp/$name-full" --rd --max-bytes "$tb" --full-search --quiet)"
    fi
    blab() { jq -r '.budget.lab' "$1/manifest.json"; }
    lv=$(blab "$tmp/$name-v1") ls=$(blab "$tmp/$name-search")
    chosen=$(jq -r '.budget | "k \(.k) \(.components) components \(.rd_steps // "equal-noise") \(.center // "none") \(.chunks) chunks"' \
        "$tmp/$name-search/manifest.json")
    v1w=$(ratio "$tvw" "$tpw") v1c=$(ratio "$tvc" "$tpc")   # the version-1 search over plain
    rdw=$(ratio "$tsw" "$trw") rdc=$(ratio "$tsc" "$trc")   # the --rd search over plain --rd
    plw=$(ratio "$tsw" "$tpw") plc=$(ratio "$tsc" "$tpc")   # the --rd search over plain
    seconds_lines "$name" plain "$tpw" "$tpc"
    seconds_lines "$name" v1 "$tvw" "$tvc"
    ratio_lines "$name" v1_over_plain "$v1w" "$v1c"
    seconds_lines "$name" plain_rd "$trw" "$trc"
    seconds_lines "$name" rd "$tsw" "$tsc"
    ratio_lines "$name" rd_over_plain_rd "$rdw" "$rdc"
    ratio_lines "$name" rd_over_plain "$plw" "$plc"
    printf 'search_%s_v1_lab %s\nsearch_%s_rd_lab %s\n' "$name" "$lv" "$name" "$ls"
    echo "# $name: $tpw ($tpc) | $tvw ($tvc) | $trw ($trc) | $tsw ($tsc) |" \
        "${v1w}x (${v1c}x), ${plw}x (${plc}x) | ${rdw}x (${rdc}x) | $chosen"
    if [[ ${SEARCH_FULL:-1} != 0 ]]; then
        lfv=$(blab "$tmp/$name-v1full") lfs=$(blab "$tmp/$name-full")
        fvw=$(ratio "$tfvw" "$tpw") fvc=$(ratio "$tfvc" "$tpc") # the whole-material searches over plain
        fsw=$(ratio "$tfsw" "$tpw") fsc=$(ratio "$tfsc" "$tpc")
        seconds_lines "$name" v1_full "$tfvw" "$tfvc"
        ratio_lines "$name" v1_full_over_plain "$fvw" "$fvc"
        seconds_lines "$name" rd_full "$tfsw" "$tfsc"
        ratio_lines "$name" rd_full_over_plain "$fsw" "$fsc"
        printf 'search_%s_v1_full_lab %s\nsearch_%s_v1_lab_over_full %s x\n' "$name" "$lfv" "$name" "$(ratio "$lv" "$lfv")"
        printf 'search_%s_rd_full_lab %s\nsearch_%s_rd_lab_over_full %s x\n' "$name" "$lfs" "$name" "$(ratio "$ls" "$lfs")"
        echo "# $name, candidates on the whole material: v1 ${fvw}x (${fvc}x), CIELab $lfv against $lv;" \
            "--rd ${fsw}x (${fsc}x), CIELab $lfs against $ls"
    fi
    rm -rf "$tmp/$name"-*
done
