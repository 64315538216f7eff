#!/usr/bin/env bash
# bench/run.sh - runs every bench/bench_NAME.c program (built by `make bench`)
# and every bench/bench_NAME.sh script (which builds what it needs), and
# writes its stdout (`name value unit` lines) to bench/results/NAME.txt.
#
#   make bench                      # builds into build/, then runs this script
#   bash bench/run.sh [NAME...]     # only bench/bench_NAME.c (after `make bench`)
#   BUILD=build-x bash bench/run.sh # use another build directory
#
# Progress goes to stderr.
# A results file is replaced only when its benchmark succeeds (temp + rename).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

BUILD=${BUILD:-build}
export BTF_SHARED=${BTF_SHARED:-$(cd .. && pwd)/shared}
export BTF_ROOT=${BTF_ROOT:-$(pwd)}

if (($#)); then
    srcs=()
    for n in "$@"; do
        n=bench/bench_${n#bench_}
        if [[ -f $n.sh ]]; then srcs+=("$n.sh"); else srcs+=("$n.c"); fi
    done
else
    srcs=(bench/bench_*.c bench/bench_*.sh)
fi

mkdir -p "$BUILD/bench" bench/results
failed=0
for src in "${srcs[@]}"; do
    [[ -f $src ]] || { echo "bench: $src not found" >&2; failed=1; continue; }
    base=$(basename "${src%.sh}" .c)
    name=${base#bench_}
    exe=$BUILD/bench/$base
    cmd=("$exe")
    [[ $src == *.sh ]] && cmd=(env BUILD="$BUILD" bash "$src") # a script builds what it needs
    if [[ $src != *.sh && ! -x $exe ]]; then
        echo "bench: $exe is missing: run 'make bench' (it builds bench/*.c)" >&2
        failed=1
        continue
    fi
    out=bench/results/$name.txt
    echo "bench: running $base -> $out" >&2
    {
        echo "# $name: $(date -u +%Y-%m-%dT%H:%M:%SZ), commit $(git rev-parse --short HEAD 2>/dev/null || echo none)"
        echo "# host: $(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc) cpus, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//')"
    } >"$out.tmp"
    start=$(date +%s.%N)
    if "${cmd[@]}" >>"$out.tmp"; then
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
