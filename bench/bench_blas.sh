#!/usr/bin/env bash
# bench/bench_blas.sh - OpenBLAS's own thread pool beside the codec's OpenMP threads
# (doc/performance.md section 4, "BLAS threads"): `btf compress` (no thumbnail) of
# generated tiles with OPENBLAS_NUM_THREADS=$(nproc) (a pool per core, OpenBLAS's
# default) against the command's default (one BLAS thread; OpenMP shares out the
# rest), each the median of BLAS_RUNS (default 3) alternating runs: wall seconds and
# CPU (user + system), on an idle machine, beside one busy process at normal priority
# and beside one busy process per core at nice 19 (what a host that also runs a
# server or a fuzzer sees); `--plain` and the default at 64x64, the default at
# 256x256 idle only (BLAS_LARGE=0: without). About 11 minutes on 2 cores.
# Run by bench/run.sh (results: bench/results/blas.txt); needs `make build` and GNU time.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD=${BUILD:-build}
BTF=$BUILD/btf
[[ -x $BTF ]] || { echo "bench_blas: $BTF is missing: run 'make build' first" >&2; exit 1; }
[[ -x /usr/bin/time ]] || { echo "bench_blas: needs GNU time (/usr/bin/time)" >&2; exit 1; }
runs=${BLAS_RUNS:-3}
cores=$(env -u OMP_NUM_THREADS -u OMP_THREAD_LIMIT nproc) # nproc alone follows OMP_NUM_THREADS
tmp=$(mktemp -d "${TMPDIR:-/tmp}/bench_blas.XXXXXX")
hogs=()
stop_hogs() {
    if ((${#hogs[@]})); then
        kill "${hogs[@]}" 2>/dev/null || true
        wait "${hogs[@]}" 2>/dev/null || true
    fi
    hogs=()
}
trap 'stop_hogs; rm -rf "$tmp"' EXIT

# Busy processes: N at nice level NICE (each a shell loop: one core's worth).
start_hogs() {
    for ((i = 0; i < $1; i++)); do
        nice -n "$2" bash -c 'while :; do :; done' &
        hogs+=($!)
    done
}

# One compress: "wall cpu" of SRC FLAGS... with the given OPENBLAS_NUM_THREADS ("" = unset).
once() {
    local threads=$1 src=$2
    shift 2
    rm -rf "$tmp/out"
    local e=(env)
    [[ -n $threads ]] && e+=(OPENBLAS_NUM_THREADS="$threads")
    { "${e[@]}" /usr/bin/time -f "%e %U %S" "$BTF" compress "$src" "$tmp/out" --no-thumbnail --quiet "$@" >/dev/null; } 2>&1 |
        tail -1 | awk '{ printf "%.2f %.2f", $1, $2 + $3 }'
}

median() { sort -n | awk '{ a[NR] = $1 } END { print a[int((NR + 1) / 2)] }'; }

# NAME SRC FLAGS...: both settings alternating, medians, the ratios pool / one thread.
case_() {
    local name=$1 src=$2
    shift 2
    local pw=() pc=() ow=() oc=() r
    for ((i = 0; i < runs; i++)); do
        read -r w c <<<"$(once "$cores" "$src" "$@")"
        pw+=("$w") pc+=("$c")
        read -r w c <<<"$(once "" "$src" "$@")"
        ow+=("$w") oc+=("$c")
    done
    local a b c d
    a=$(printf '%s\n' "${pw[@]}" | median) b=$(printf '%s\n' "${pc[@]}" | median)
    c=$(printf '%s\n' "${ow[@]}" | median) d=$(printf '%s\n' "${oc[@]}" | median)
    echo "blas_${name}_pool_wall_s $a s"
    echo "blas_${name}_pool_cpu_s $b s"
    echo "blas_${name}_one_wall_s $c s"
    echo "blas_${name}_one_cpu_s $d s"
    echo "blas_${name}_wall_ratio $(awk -v x="$a" -v y="$c" 'BEGIN { printf "%.3f", x / y }') x"
    echo "blas_${name}_cpu_ratio $(awk -v x="$b" -v y="$d" 'BEGIN { printf "%.3f", x / y }') x"
    echo "# $name: a BLAS pool of $cores $a s wall, $b s CPU | one BLAS thread $c s wall, $d s CPU"
}

tiles64=gen:tiles:64:3621
for load in idle busy nice19; do
    echo "bench_blas: $load" >&2
    case $load in
    busy) start_hogs 1 0 ;;
    nice19) start_hogs "$cores" 19 ;;
    esac
    case_ "${load}_plain64" "$tiles64" --plain
    case_ "${load}_default64" "$tiles64"
    stop_hogs
done
if [[ ${BLAS_LARGE:-1} != 0 ]]; then
    echo "bench_blas: idle 256x256" >&2
    case_ idle_default256 gen:tiles:256:3631
fi
