#!/usr/bin/env bash
# bench/bench_lossydef.sh - lossy WebP textures as `btf compress` integrates them
# (issue 36 item 2; doc/performance.md section 11, "Integrated"): per material
# `btf compress` with --plain, --lossless (the default before) and the default (a
# component's texture lossy where the rate-distortion choice finds it cheaper), each
# without a thumbnail: CPU seconds (user + system of the process), bytes (chunk files +
# manifest) and `btf eval`'s CIELab (every texel and pair); then `--max-error E` (the
# thesis format's error at k 3, C 8, from section 11's first table) lossless and
# default, and the default with --full-search (every default k measured: what the
# search's pruning of k saves and whether it chose the same k). Ratios are default
# over lossless. Then the same two with `--avif` (lossy
# textures as AVIF instead of lossy WebP: doc/performance.md section 11, "AVIF"),
# ratios over the default. Tiles and knit at 64x64 (about 10 minutes), tiles at
# 256x256 unless LOSSYDEF_LARGE=0 (about 25 minutes more).
# Run by bench/run.sh (results: bench/results/lossydef.txt); needs `make build`, jq
# and GNU time.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD=${BUILD:-build}
BTF=$BUILD/btf
[[ -x $BTF ]] || { echo "bench_lossydef: $BTF is missing: run 'make build' first" >&2; exit 1; }
command -v jq >/dev/null || { echo "bench_lossydef: needs jq" >&2; exit 1; }
[[ -x /usr/bin/time ]] || { echo "bench_lossydef: needs GNU time (/usr/bin/time)" >&2; exit 1; }
tmp=$(mktemp -d "${TMPDIR:-/tmp}/bench_lossydef.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
mats=${LOSSYDEF_MATERIALS:-"tiles64=gen:tiles:64:3621=2.2555 knit64=gen:knit:64:3622=2.4768"}
[[ ${LOSSYDEF_LARGE:-1} == 0 ]] || mats+=" tiles256=gen:tiles:256:3631=2.4816"

# One package: NAME TAG SRC FLAGS...; prints its lines, sets bytes, lab, cpu.
one() {
    local name=$1 tag=$2 src=$3
    shift 3
    local out=$tmp/$name-$tag
    cpu=$( { /usr/bin/time -f "%U %S" "$BTF" compress "$src" "$out" --no-thumbnail --quiet "$@" >/dev/null; } 2>&1 |
        tail -1 | awk '{ printf "%.1f", $1 + $2 }')
    bytes=$(jq -r '[.chunks[].files[]] | unique | .[]' "$out/manifest.json" |
        (cd "$out" && xargs stat -c %s manifest.json) | awk '{ s += $1 } END { print s }')
    lab=$(printf %.4f "$("$BTF" eval "$src" "$out" --json --no-curve | jq -r .lab_mae)")
    lossy=$(jq -r '[.rd.tex_quality // [] | .[] | select(. >= 0)] | length' "$out/manifest.json")
    k=$(jq -r '.k' "$out/manifest.json")
    echo "lossydef_${name}_${tag}_cpu_s $cpu s"
    echo "lossydef_${name}_${tag}_bytes $bytes B"
    echo "lossydef_${name}_${tag}_lab $lab lab"
    echo "lossydef_${name}_${tag}_lossy_components $lossy count" # of those compressed (a budget's cut ones too)
    rm -rf "$out"
}

ratio() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.3f", a / b }'; }

for m in $mats; do
    IFS== read -r name src err <<<"$m"
    echo "bench_lossydef: $name" >&2
    one "$name" plain "$src" --plain
    pb=$bytes pc=$cpu
    one "$name" lossless "$src" --lossless
    lb=$bytes ll=$lab lc=$cpu
    one "$name" default "$src"
    echo "lossydef_${name}_bytes_ratio $(ratio "$bytes" "$lb") x"
    echo "lossydef_${name}_cpu_over_plain $(ratio "$cpu" "$pc") x"
    echo "# $name: plain $pb B, $pc s | lossless $lb B, Lab $ll, $lc s | default $bytes B, Lab $lab, $cpu s, $lossy lossy | $(ratio "$bytes" "$lb")x bytes, $(ratio "$cpu" "$pc")x plain's CPU"
    db=$bytes dl=$lab dc=$cpu
    one "$name" avif "$src" --avif
    echo "lossydef_${name}_avif_bytes_ratio $(ratio "$bytes" "$db") x"
    echo "# $name --avif: $bytes B, Lab $lab, $cpu s, $lossy lossy | $(ratio "$bytes" "$db")x the default's bytes (Lab $dl), $(ratio "$cpu" "$dc")x its CPU"
    one "$name" budget_lossless "$src" --max-error "$err" --lossless
    lb=$bytes lc=$cpu ll=$lab
    one "$name" budget_default "$src" --max-error "$err"
    echo "lossydef_${name}_budget_bytes_ratio $(ratio "$bytes" "$lb") x"
    echo "# $name --max-error $err: lossless $lb B (Lab $ll), $lc s | default $bytes B (Lab $lab), $cpu s, $lossy lossy | $(ratio "$bytes" "$lb")x bytes"
    db=$bytes dl=$lab dc=$cpu dk=$k
    one "$name" budget_full "$src" --max-error "$err" --full-search
    echo "lossydef_${name}_pruned_over_full_bytes $(ratio "$db" "$bytes") x"
    echo "lossydef_${name}_pruned_over_full_cpu $(ratio "$dc" "$cpu") x"
    echo "# $name --max-error $err --full-search (every k): $bytes B (Lab $lab), $cpu s, k $k | the default search (k $dk) $(ratio "$db" "$bytes")x its bytes, $(ratio "$dc" "$cpu")x its CPU"
    one "$name" budget_avif "$src" --max-error "$err" --avif
    echo "lossydef_${name}_budget_avif_bytes_ratio $(ratio "$bytes" "$db") x"
    echo "# $name --max-error $err --avif: $bytes B (Lab $lab), $cpu s, $lossy lossy | $(ratio "$bytes" "$db")x the default's bytes, $(ratio "$cpu" "$dc")x its CPU"
done
