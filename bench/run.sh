#!/usr/bin/env bash
# bench/run.sh - builds every bench/bench_NAME.c against the built library and
# runs it; its stdout (`name value unit` lines) goes to bench/results/NAME.txt.
#
#   make bench                      # builds into build/, then runs this script
#   bash bench/run.sh [NAME...]     # only bench/bench_NAME.c (after `make build`)
#   BUILD=build-x bash bench/run.sh # use another build directory
#
# Compile flags and libraries mirror the Makefile's; progress goes to stderr.
# A results file is replaced only when its benchmark succeeds (temp + rename).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

BUILD=${BUILD:-build}
CC=${CC:-cc}
CXX=${CXX:-g++}
export BTF_SHARED=${BTF_SHARED:-$(cd .. && pwd)/shared}
export BTF_ROOT=${BTF_ROOT:-$(pwd)}

lib=$BUILD/codec/libbtfcodec.a
if [[ ! -f $lib ]]; then
    echo "bench: $lib is missing: run 'make build' (or make BUILD=$BUILD build) first" >&2
    exit 1
fi

PKGS="OpenImageIO libcjson lapacke openblas osmesa egl glesv2"
CFLAGS="-std=c11 -Wall -Wextra -Werror -O2 -g -D_DEFAULT_SOURCE -D_POSIX_C_SOURCE=200809L"
read -r -a pkg_cflags <<<"$(pkg-config --cflags $PKGS 2>/dev/null || true)"
read -r -a pkg_libs <<<"$(pkg-config --libs $PKGS 2>/dev/null || true)"

# The tool objects (generator, GL harness, ...) as the Makefile links them, minus main.
tools_obj=()
for f in tools/*.c; do
    [[ $f == tools/btf_main.c ]] && continue
    o=$BUILD/${f%.c}.o
    if [[ ! -f $o ]]; then
        echo "bench: $o is missing: run 'make build' first" >&2
        exit 1
    fi
    tools_obj+=("$o")
done

if (($#)); then
    srcs=()
    for n in "$@"; do srcs+=("bench/bench_${n#bench_}.c"); done
else
    srcs=(bench/bench_*.c)
fi

mkdir -p "$BUILD/bench" bench/results
failed=0
for src in "${srcs[@]}"; do
    [[ -f $src ]] || { echo "bench: $src not found" >&2; failed=1; continue; }
    base=$(basename "$src" .c)
    name=${base#bench_}
    exe=$BUILD/bench/$base
    echo "bench: building $exe" >&2
    $CC $CFLAGS -Icodec -Itools "${pkg_cflags[@]}" -c "$src" -o "$exe.o"
    $CXX -o "$exe" "$exe.o" "${tools_obj[@]}" "$lib" "${pkg_libs[@]}" -lstdc++ -lm -lpthread
    out=bench/results/$name.txt
    echo "bench: running $base -> $out" >&2
    {
        echo "# $name: $(date -u +%Y-%m-%dT%H:%M:%SZ), commit $(git rev-parse --short HEAD 2>/dev/null || echo none)"
        echo "# host: $(nproc) cpus, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//')"
    } >"$out.tmp"
    start=$(date +%s.%N)
    if "$exe" >>"$out.tmp"; then
        awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN { printf "bench_wall_time %.2f s\n", e - s }' >>"$out.tmp"
        mv "$out.tmp" "$out"
        cat "$out"
    else
        echo "bench: $base failed (exit $?); $out left unchanged" >&2
        rm -f "$out.tmp"
        failed=1
    fi
done
exit $failed
