#!/usr/bin/env bash
# bench/bench_fullsize.sh - a full-size material (151 x 151 dome directions at
# 400 x 400 texels: 10.9 G samples, 10.9 GB as 8-bit RGB) generated as an image
# directory and compressed block by block: wall time, CPU, peak RSS and disk,
# with the peak RSS of the compression asserted <= 4 GiB (the bench fails
# otherwise, and its results file is left unchanged).
#
#   bash bench/run.sh fullsize                     # after `make bench` (or make build)
#   BENCH_FULL_SIZE=0 bash bench/run.sh fullsize   # only the small variant
#
# Baseline, in the same run: a small variant (BENCH_FULL_SMALL, default 100 x 100
# texels, the same 151 x 151 directions) compressed both view by view and with
# --in-memory (the whole material loaded first); the two packages must be
# identical, and the *_ratio lines compare the two. The full size is compressed
# view by view only (in memory it would need the 10.9 GB material plus the block).
# Needs about 0.7 x the raw size of free disk under BENCH_TMP (default $TMPDIR or
# /tmp) for the images; a size that does not fit is skipped with a message. Takes
# about 30 minutes on 2 cores at full size. Everything generated is deleted.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

BUILD=${BUILD:-build}
BTF=$BUILD/btf
FULL=${BENCH_FULL_SIZE:-400}
SMALL=${BENCH_FULL_SMALL:-100}
LIMIT_KB=$((4 * 1024 * 1024)) # 4 GiB
[[ -x $BTF ]] || make -s "$BTF" >&2
command -v /usr/bin/time >/dev/null || { echo "bench_fullsize: /usr/bin/time (GNU time) is missing" >&2; exit 1; }

root=${BENCH_TMP:-${TMPDIR:-/tmp}}
work=$(mktemp -d "$root/btf-fullsize-XXXXXX")
trap 'rm -rf "$work"' EXIT

# timed CMD...: runs CMD under GNU time; sets T_WALL (s), T_CPU (s), T_RSS (kB).
timed() {
    /usr/bin/time -f '%e %U %S %M' -o "$work/time" "$@" >"$work/out" 2>"$work/err" || {
        echo "bench_fullsize: failed: $*" >&2
        cat "$work/err" >&2
        return 1
    }
    read -r T_WALL user sys T_RSS <"$work/time"
    T_CPU=$(awk -v u="$user" -v s="$sys" 'BEGIN { printf "%.2f", u + s }')
}

mb() { awk -v k="$1" 'BEGIN { printf "%.1f", k / 1024 }'; }

# run SIZE BASELINE: generate, measure, compress (and the in-memory baseline when
# BASELINE is 1), check the memory bound, delete.
run() {
    local n=$1 baseline=$2 img=$work/img-$1 tag=fullsize_$1
    local raw=$((n * n * 3 * 151 * 151))
    local avail=$(($(df -Pk "$work" | awk 'NR == 2 { print $4 }') * 1024))
    if ((avail < raw * 7 / 10 + (1 << 30))); then
        echo "bench_fullsize: skipping ${n}x$n: $((raw / 1000000)) MB of samples, only $((avail / 1000000)) MB free under $root" >&2
        return 0
    fi
    echo "bench_fullsize: ${n}x$n x 151 x 151: generating ($((raw / 1000000)) MB of samples)" >&2
    timed "$BTF" gen knit "$img" --size "$n" --sampling dome151
    local disk=$(du -sk "$img" | cut -f1)
    echo "${tag}_samples $raw samples"
    echo "${tag}_gen_wall $T_WALL s"
    echo "${tag}_gen_cpu $T_CPU s"
    echo "${tag}_gen_peak_rss $(mb "$T_RSS") MB"
    echo "${tag}_source_disk $(mb "$disk") MB"
    echo "bench_fullsize: ${n}x$n: compressing view by view" >&2
    timed "$BTF" compress "$img" "$work/pkg-$n" --k 3 --components 8 --name knit --quiet
    local wall=$T_WALL rss=$T_RSS
    echo "${tag}_compress_wall $T_WALL s"
    echo "${tag}_compress_cpu $T_CPU s"
    echo "${tag}_compress_peak_rss $(mb "$T_RSS") MB"
    echo "${tag}_package_bytes $(du -sb "$work/pkg-$n" | cut -f1) bytes"
    awk -v r="$rss" -v s="$raw" 'BEGIN { printf "'"$tag"'_compress_rss_per_source_ratio %.4f x\n", r * 1024 / s }'
    if ((baseline)); then
        echo "bench_fullsize: ${n}x$n: compressing in memory (baseline)" >&2
        timed "$BTF" compress "$img" "$work/mem-$n" --k 3 --components 8 --name knit --quiet --in-memory
        echo "${tag}_inmemory_wall $T_WALL s"
        echo "${tag}_inmemory_cpu $T_CPU s"
        echo "${tag}_inmemory_peak_rss $(mb "$T_RSS") MB"
        awk -v a="$wall" -v b="$T_WALL" 'BEGIN { printf "'"$tag"'_wall_ratio_stream_vs_inmemory %.3f x\n", a / b }'
        awk -v a="$rss" -v b="$T_RSS" 'BEGIN { printf "'"$tag"'_rss_ratio_stream_vs_inmemory %.3f x\n", a / b }'
        if diff -r "$work/pkg-$n" "$work/mem-$n" >/dev/null; then
            echo "${tag}_packages_identical 1 bool"
        else
            echo "bench_fullsize: ${n}x$n: the view-by-view package differs from the in-memory one" >&2
            return 1
        fi
        rm -rf "$work/mem-$n"
    fi
    rm -rf "$img" "$work/pkg-$n"
    if ((rss > LIMIT_KB)); then
        echo "bench_fullsize: ${n}x$n: compression peak RSS $(mb "$rss") MB exceeds the 4096 MB bound" >&2
        return 1
    fi
    echo "${tag}_compress_within_4gib 1 bool"
    eval "WALL_$n=$wall"
}

run "$SMALL" 1
if ((FULL > 0)); then
    run "$FULL" 0
    if [[ -n ${WALL_400:-} && $FULL == 400 ]]; then # time per sample, full size against the small run
        awk -v a="$WALL_400" -v b="$(eval echo "\$WALL_$SMALL")" -v f="$(((400 * 400) / (SMALL * SMALL)))" \
            'BEGIN { printf "fullsize_400_compress_wall_per_sample_ratio_vs_small %.3f x\n", a / b / f }'
    fi
fi
