#!/usr/bin/env bash
# bench/bench_rd.sh - CIELab error at equal bytes against the thesis format (issue 14):
# per material, `btf export-thesis --k 3 --components 8` (the baseline: its bytes B
# and its error), then `btf compress --max-bytes B` as version 1 (equal-noise steps,
# raw 16-bit weights), as version 3 with PNG textures only (`--rd --png`, "v3png":
# rate-distortion steps, deflated weights) and as version 3 as written by default
# (each texture the smaller of PNG and lossless WebP), each measured by `btf eval`
# against the source (lab_mae: the thesis's CIELab error). Ratios are to the thesis
# in the same run. Beside them, the floor of the thesis format's own k and C: the
# error of `btf compress --k 3 --components 8 --bits 16 --center none` (16-bit
# textures and weights: the best rank-8 blocks' own error, by `btf eval`), so a
# ratio no 8-component k = 3 package can reach shows as such. Then lossy WebP
# against PNG for the component textures of the first material (below).
# Run by bench/run.sh (results: bench/results/rd.txt); needs `make build` and jq.
#   RD_MATERIALS="gen:tiles:64:4242 ..." bash bench/bench_rd.sh   # other materials
#   RD_LARGE=0 bash bench/bench_rd.sh       # skip the 256x256 material (2: add the thesis wool and corduroy at 256x256)
#   RD_VARIANTS=v3 RD_FLOOR=0 bash bench/bench_rd.sh   # only the default version 3, no floor
#                                           # and no lossy WebP run (a 256x256 material in ~30 min, not ~100)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD=${BUILD:-build}
BTF=$BUILD/btf
[[ -x $BTF ]] || { echo "bench_rd: $BTF is missing: run 'make build' first" >&2; exit 1; }
command -v jq >/dev/null || { echo "bench_rd: needs jq" >&2; exit 1; }
SHARED=${BTF_SHARED:-../shared}
# Seeds and sizes no test uses; NAME=SOURCE, or NAME=THESIS_DIR@SIZE.
mats=(tiles64=gen:tiles:64:4242 knit64=gen:knit:64:4243 stone64=gen:stone:64:4244)
for m in wool corduroy; do
    [[ -f $SHARED/data/thesis-ubo2003/$m/meta.json ]] && mats+=("${m}64=$SHARED/data/thesis-ubo2003/$m@64")
done
if [[ ${RD_LARGE:-1} != 0 ]]; then
    mats+=(tiles256=gen:tiles:256:5151)
    for m in wool corduroy; do
        [[ ${RD_LARGE:-1} == 2 && -f $SHARED/data/thesis-ubo2003/$m/meta.json ]] && mats+=("${m}256=$SHARED/data/thesis-ubo2003/$m")
    done
fi
[[ -n ${RD_MATERIALS:-} ]] && read -r -a mats <<<"$RD_MATERIALS"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/bench_rd.XXXXXX")
trap 'rm -rf "$tmp"' EXIT

source bench/lib.sh
echo "# material: thesis bytes / Lab | v1 (--max-bytes) bytes / Lab / ratio | v3png (--rd --png) | v3 (--rd --max-bytes) bytes / Lab / ratio / k, chunks | floor: 16-bit k 3, C 8 Lab (ratio)"
variants=${RD_VARIANTS:-v1 v3png v3}
first_v3=
for spec in "${mats[@]}"; do
    name=${spec%%=*} src=${spec#*=}
    [[ $name == "$spec" ]] && name=$(echo "$spec" | tr ':/' '--')
    echo "bench_rd: $name" >&2
    src=$(thesis_source "$src" "$tmp" "$name")
    tb=$(thesis_baseline "$src" "$tmp/$name-thesis")
    tl=$(whole_lab "$src" "$tmp/$name-thesis")
    for v in $variants; do
        case $v in
        v1) "$BTF" compress "$src" "$tmp/$name-v1" --max-bytes "$tb" --plain --quiet ;;
        v3png) "$BTF" compress "$src" "$tmp/$name-v3png" --max-bytes "$tb" --rd --png --quiet
            [[ -z $first_v3 ]] && first_v3=$tmp/$name-v3png first_src=$src ;;
        v3) "$BTF" compress "$src" "$tmp/$name-v3" --max-bytes "$tb" --rd --quiet ;;
        *) echo "bench_rd: unknown variant $v (v1, v3png, v3)" >&2; exit 2 ;;
        esac
    done
    row="# $name: $tb / $(printf %.3f "$tl")"
    for v in $variants; do
        d=$tmp/$name-$v
        b=$(find "$d" -type f -printf '%s\n' | awk '{s += $1} END {print s}')
        l=$(whole_lab "$src" "$d")
        r=$(awk -v a="$l" -v t="$tl" 'BEGIN { printf "%.3f", a / t }')
        echo "rd_${name}_${v}_bytes $b B"
        echo "rd_${name}_${v}_lab $(printf %.4f "$l") lab"
        echo "rd_${name}_${v}_lab_ratio $r x"
        row+=" | $b / $(printf %.3f "$l") / ${r}x"
    done
    [[ -d $tmp/$name-v3 ]] && row+=" / k $(jq .budget.k "$tmp/$name-v3/manifest.json"), $(jq .budget.chunks "$tmp/$name-v3/manifest.json") chunks"
    if [[ ${RD_FLOOR:-1} == 0 ]]; then
        echo "rd_${name}_thesis_bytes $tb B"
        echo "rd_${name}_thesis_lab $(printf %.4f "$tl") lab"
        echo "$row"
        continue
    fi
    # the floor at k 3, C 8: 16-bit steps, no centring (the best rank-8 blocks)
    "$BTF" compress "$src" "$tmp/$name-floor" --k 3 --components 8 --bits 16 --center none --plain --quiet
    fl=$(whole_lab "$src" "$tmp/$name-floor")
    rm -rf "$tmp/$name-floor"
    fr=$(awk -v a="$fl" -v t="$tl" 'BEGIN { printf "%.3f", a / t }')
    echo "rd_${name}_float8_lab $(printf %.4f "$fl") lab"
    echo "rd_${name}_float8_lab_ratio $fr x"
    row+=" | floor k 3, C 8: $(printf %.3f "$fl") (${fr}x)"
    echo "rd_${name}_thesis_bytes $tb B"
    echo "rd_${name}_thesis_lab $(printf %.4f "$tl") lab"
    echo "$row"
done

# Lossy WebP for the component textures (oiiotool; grey replicated into RGB, WebP has
# no 1-channel images): the first material's PNG-only version-3 package with every
# tex-JJ.png replaced by its WebP at quality Q (decoded back to grey PNG for btf eval;
# bytes = the WebP files + weights + manifest) against version 3 as written by
# default (PNG or lossless WebP per texture) at the same bytes.
if [[ -n $first_v3 ]] && command -v oiiotool >/dev/null && oiiotool --help 2>/dev/null | grep 'Output formats' | grep -q webp; then
    src=${first_src}
    echo "# webp: quality | lossy webp package bytes / Lab | v3 (--rd --max-bytes same) bytes / Lab"
    for q in 95 80; do
        d=$tmp/webp$q
        cp -r "$first_v3" "$d"
        b=$(find "$d" -type f ! -name 'tex-*' -printf '%s\n' | awk '{s += $1} END {print s}')
        for f in "$d"/tex-*.png; do
            oiiotool "$f" --ch Y,Y,Y --compression "webp:$q" -o "$tmp/t.webp"
            b=$((b + $(stat -c %s "$tmp/t.webp")))
            oiiotool "$tmp/t.webp" --ch R --chnames Y -d uint8 -o "$f"
        done
        l=$(whole_lab "$src" "$d")
        "$BTF" compress "$src" "$tmp/png$q" --max-bytes "$b" --rd --quiet
        pb=$(find "$tmp/png$q" -type f -printf '%s\n' | awk '{s += $1} END {print s}')
        pl=$(whole_lab "$src" "$tmp/png$q")
        echo "rd_webp_q${q}_bytes $b B"
        echo "rd_webp_q${q}_lab $(printf %.4f "$l") lab"
        echo "rd_webp_q${q}_png_bytes $pb B"
        echo "rd_webp_q${q}_png_lab $(printf %.4f "$pl") lab"
        echo "# webp q$q: $b / $(printf %.3f "$l") | $pb / $(printf %.3f "$pl")"
        rm -rf "$d" "$tmp/png$q"
    done
fi
