#!/usr/bin/env bash
# fuzz/run.sh - runs built libFuzzer targets one at a time and prints one summary
# table: executions, executions per second, coverage (cov: edges, ft: features),
# corpus size and the machine's load average when the target ended.
# `make fuzz` calls it after building them (fuzz/build.mk); by hand:
#
#   FUZZ_SECONDS=60 FUZZ_RUNS=0 bash fuzz/run.sh build-fuzz package_mem thesis_mem
#
# Each target NAME runs as build-fuzz/fuzz/fuzz_NAME on fuzz/corpus/NAME (new inputs
# land there; FUZZ_CORPUS=DIR: DIR/NAME instead, e.g. a copy for a measurement
# that leaves the saved corpora alone), for FUZZ_SECONDS, or until FUZZ_RUNS
# executions when that is > 0 (whichever comes first), its log in
# build-fuzz/fuzz/log/NAME.txt. The disk targets' scratch directories go under
# FUZZ_TMPDIR (tmpfs: no disk, no fsync cost).
# The table goes to stdout and to FUZZ_SUMMARY (default build-fuzz/fuzz/summary.txt).
#
# The codec's OpenMP regions (and OpenBLAS) run on FUZZ_THREADS threads, default 1:
# an input is small, and starting a parallel region costs more than sharing its
# work (thesis_mem runs 1.6 times as fast on one thread as on two).
#
# FUZZ_FLAGS adds libFuzzer flags to every run: -entropic=0 (no rare-feature
# weighting of the inputs) runs the package readers twice as fast, libFuzzer's
# bookkeeping of that weighting being most of their time.
#
# ASan unwinds allocation stacks with frame pointers (ASAN_OPTIONS from
# FUZZ_ASAN_OPTIONS, default empty): fast_unwind_on_malloc=0 would give the full
# stacks a leak inside a library without frame pointers needs to match
# tests/lsan.supp, but costs 30 times the executions of the image readers. A target
# stopped by a leak has its leak input rerun with full stacks: when the
# suppressions cover it there, the row says "suppressed leak" (the run ended early)
# instead of failing.
# Exit: 0 when every target ran clean, 1 when one crashed or broke a contract (its
# log's tail is printed; libFuzzer left the input as build-fuzz/fuzz/crash-*).
set -uo pipefail
cd "$(dirname "$0")/.."
root=$PWD
build=${1:?usage: fuzz/run.sh BUILD TARGET...}
shift
seconds=${FUZZ_SECONDS:-60}
runs=${FUZZ_RUNS:-0}
rss=${FUZZ_RSS_MB:-2048}
tmp=${FUZZ_TMPDIR:-/tmp}
asan=${FUZZ_ASAN_OPTIONS:-}
flags=${FUZZ_FLAGS:-} # more libFuzzer flags, e.g. -entropic=0
threads=${FUZZ_THREADS:-1}
lsan=suppressions=$root/tests/lsan.supp
corpus=$(cd "${FUZZ_CORPUS:-fuzz/corpus}" && pwd)
summary=${FUZZ_SUMMARY:-$build/fuzz/summary.txt}
mkdir -p "$build/fuzz/log" "$(dirname "$summary")"

# The last value of libFuzzer's "stat::NAME: V" lines in a log.
stat() { sed -n "s/^stat::$1: *//p" "$2" | tail -1; }
# "cov ft" of the last status line ("#N ... cov: C ft: F ...").
coverage() { grep -o 'cov: [0-9]* ft: [0-9]*' "$1" | tail -1 | awk '{print $2, $4}'; }

rows=() failed=0
for t in "$@"; do
    bin=$build/fuzz/fuzz_$t log=$build/fuzz/log/$t.txt
    [[ -x $bin ]] || { echo "fuzz: $bin is not built (make fuzz builds it)" >&2; exit 2; }
    maxlen=65536
    [[ $t == request ]] && maxlen=20000 # the parser's own limit is below
    args=(-max_total_time="$seconds" -rss_limit_mb="$rss" -malloc_limit_mb="$rss" -max_len=$maxlen
          -print_final_stats=1)
    bound="$seconds s"
    ((runs > 0)) && args+=(-runs="$runs") bound+=" or $runs runs"
    args+=($flags)
    echo "fuzz: $t for $bound"
    start=$(date +%s.%N)
    (cd "$build/fuzz" && TMPDIR=$tmp ASAN_OPTIONS=$asan LSAN_OPTIONS=$lsan OMP_NUM_THREADS=$threads \
        OPENBLAS_NUM_THREADS=$threads \
        "./fuzz_$t" "${args[@]}" "$corpus/$t" >"log/$t.txt" 2>&1)
    rc=$?
    wall=$(echo "$(date +%s.%N) - $start" | bc)
    execs=$(stat number_of_executed_units "$log") rate=$(stat average_exec_per_sec "$log")
    read -r cov ft <<<"$(coverage "$log")"
    result=ok
    leak=$(sed -n 's/.*Test unit written to \(.*leak-[0-9a-f]*\)$/\1/p' "$log" | tail -1)
    if ((rc != 0)) && [[ -n $leak ]] && (cd "$build/fuzz" && TMPDIR=$tmp LSAN_OPTIONS=$lsan \
        ASAN_OPTIONS=fast_unwind_on_malloc=0 "./fuzz_$t" "$leak" >>"log/$t.txt" 2>&1); then
        rc=0 result="suppressed leak ($leak)"
    fi
    if ((rc != 0)); then
        result="FAILED (rc $rc)" failed=1
        tail -40 "$log"
    fi
    load=$(cut -d' ' -f1 /proc/loadavg) # other work on the machine slows a target down
    rows+=("$(printf '%-13s %11s %8.0f %9s %6s %7s %7s %5s  %s' "$t" "${execs:-?}" "$wall" "${rate:-?}" "${cov:-?}" \
        "${ft:-?}" "$(ls "$corpus/$t" | wc -l)" "$load" "$result")")
done

{
    echo "# make fuzz: FUZZ_SECONDS=$seconds FUZZ_RUNS=$runs, $(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores, scratch in $tmp"
    printf '%-13s %11s %8s %9s %6s %7s %7s %5s  %s\n' target execs seconds exec/s cov ft corpus load result
    printf '%s\n' "${rows[@]}"
} | tee "$summary"
echo "fuzz: summary in $summary"
exit $failed
