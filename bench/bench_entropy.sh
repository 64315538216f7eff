#!/usr/bin/env bash
# bench/bench_entropy.sh - would a stronger general-purpose entropy coder pay for
# itself (issue 36 item 2; doc/performance.md section 11, "Other coders")? Per
# material, the default package (version 3) and one with `--levels 3` (version 4):
# the zlib weight files (`wt-*.z`, `wt-*.pz`) inflated and coded again with zstd -19, zstd
# --ultra -22 and xz -9e (only those: weights kept as a lossless image, version 3's
# `wt-JJ.webp` and version 4's `wt-JJ-8.webp`, doc/package-format.md sections 5.5 and
# 5.2, are counted apart and not recoded, so a package whose weights are all WebP has
# no zlib group: "none"); and the
# lossless residual level textures (`tex-*-dN.*`,
# PNG or lossless WebP) as raw 8-bit planes (oiiotool -> PGM) through zstd --ultra
# -22. The coding is lossless, so the error is the package's own: the question is
# bytes only. Prints each group's bytes as stored and recoded, and what the best
# recoding would save of the whole package (chunk files + manifest). About 3 minutes
# on 2 cores. Run by bench/run.sh (results: bench/results/entropy.txt); needs `make
# build`, jq, zstd, xz and oiiotool (make setup installs them).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD=${BUILD:-build}
BTF=$BUILD/btf
[[ -x $BTF ]] || { echo "bench_entropy: $BTF is missing: run 'make build' first" >&2; exit 1; }
for t in jq zstd xz oiiotool python3; do
    command -v "$t" >/dev/null || { echo "bench_entropy: needs $t (make setup installs it)" >&2; exit 1; }
done
# Seeds no test uses; NAME=SOURCE.
mats=(tiles64=gen:tiles:64:3661 knit64=gen:knit:64:3662 stone128=gen:stone:128:3663)
[[ -n ${ENTROPY_MATERIALS:-} ]] && read -r -a mats <<<"$ENTROPY_MATERIALS"
tmp=$(mktemp -d "${TMPDIR:-/tmp}/bench_entropy.XXXXXX")
trap 'rm -rf "$tmp"' EXIT

source bench/lib.sh
size() { stat -c %s "$1"; }
# weights DIR: stored zlib bytes, then zstd -19, zstd -22, xz -9e of the inflated files
# (wt-*.webp weights are no zlib stream: skipped here, counted by webp_weights)
weights() {
    local z=0 a=0 b=0 x=0 f raw=$tmp/raw
    for f in "$1"/wt-*.z "$1"/wt-*.pz; do # the zlib codings (doc/package-format.md 5.3, 5.4, 9.3)
        [[ -e $f ]] || continue
        python3 -c 'import sys, zlib; sys.stdout.buffer.write(zlib.decompress(open(sys.argv[1], "rb").read()))' "$f" >"$raw"
        z=$((z + $(size "$f")))
        a=$((a + $(zstd -q -19 -c "$raw" | wc -c)))
        b=$((b + $(zstd -q --ultra -22 -c "$raw" | wc -c)))
        x=$((x + $(xz -9e -c "$raw" | wc -c)))
    done
    echo "$z $a $b $x"
}
# webp_weights DIR: how many wt-*.webp weights files and their bytes (not recoded)
webp_weights() {
    local n=0 s=0 f
    for f in "$1"/wt-*.webp; do
        [[ -e $f ]] || continue
        n=$((n + 1)) s=$((s + $(size "$f")))
    done
    echo "$n $s"
}
# levels DIR: stored bytes of the residual level textures, then zstd -22 of their raw planes
levels() {
    local s=0 r=0 f pgm=$tmp/plane.pgm
    for f in "$1"/tex-*-d[0-9]*.*; do
        [[ -e $f ]] || continue
        oiiotool "$f" --ch R -d uint8 -o "$pgm"
        s=$((s + $(size "$f")))
        r=$((r + $(zstd -q --ultra -22 -c "$pgm" | wc -c)))
    done
    echo "$s $r"
}
pct() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%+.1f%%", 100 * (a - b) / b }'; }

echo "# material package: bytes | weights zlib B: zstd -19 / zstd -22 / xz -9e (change) [+ N wt-*.webp of B, not recoded] | residual levels stored B: zstd -22 of raw planes (change) | best recoding saves of the package"
for m in "${mats[@]}"; do
    IFS== read -r name src <<<"$m"
    for mode in v3 v4; do
        flags=()
        [[ $mode == v4 ]] && flags=(--levels 3)
        echo "bench_entropy: $name $mode" >&2
        rm -rf "$tmp/p"
        "$BTF" compress "$src" "$tmp/p" --no-thumbnail --quiet "${flags[@]}"
        read -r z a b x <<<"$(weights "$tmp/p")"
        read -r wn ws <<<"$(webp_weights "$tmp/p")"
        read -r ls lr <<<"$(levels "$tmp/p")"
        total=$(package_bytes "$tmp/p")
        best=$(printf '%s\n' "$a" "$b" "$x" | sort -n | head -1)
        saved=$((z - best))
        ((lr < ls)) && saved=$((saved + ls - lr))
        webp=
        ((wn > 0)) && webp=" + $wn wt-*.webp of $ws B"
        echo "$name $mode: $total | $z: $a / $b / $x ($( ((z > 0)) && pct "$best" "$z" || echo none))$webp | $ls: $lr ($( ((ls > 0)) && pct "$lr" "$ls" || echo none)) | $(awk -v s="$saved" -v t="$total" 'BEGIN { printf "%.1f%%", 100 * s / t }')"
    done
done
