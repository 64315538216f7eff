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
# The table goes to stdout and to FUZZ_SUMMARY (default build-fuzz/fuzz/summary.txt);
# its "10M in" is 10 million executions at the target's rate. Each target has its
# own -max_len and flags (target_settings below); FUZZ_NICE=N runs them under
# nice -n N (make fuzz-deep: 19).
#
# The codec's OpenMP regions (and OpenBLAS) run on FUZZ_THREADS threads, default 1:
# an input is small, and starting a parallel region costs more than sharing its
# work (thesis_mem runs 1.6 times as fast on one thread as on two).
#
# FUZZ_FLAGS adds libFuzzer flags to every run (after the target's own).
#
# FUZZ_FORK=N (N > 0) runs each target in libFuzzer's fork mode: N worker processes
# under one parent, which merges their finds into the corpus (a slow target on every
# core: give FUZZ_JOBS=1 with it). Its parent prints no final stats, so the row's
# executions are its last status line's count ("#N: cov: ..."), the rate that over
# the wall time. FUZZ_RUNS bounds it too: the parent stops its workers once their
# executions together pass it ("fuzzed for N iterations, wrapping up soon"), so the
# count can end a little above.
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
fork=${FUZZ_FORK:-0}
nice=${FUZZ_NICE:+nice -n $FUZZ_NICE} # a deep run gives way to other work on the machine
lsan=suppressions=$root/tests/lsan.supp
corpus=$(cd "${FUZZ_CORPUS:-fuzz/corpus}" && pwd)
summary=${FUZZ_SUMMARY:-$build/fuzz/summary.txt}
mkdir -p "$build/fuzz/log" "$(dirname "$summary")"

# The last value of libFuzzer's "stat::NAME: V" lines in a log.
stat() { sed -n "s/^stat::$1: *//p" "$2" | tail -1; }
# "cov ft" of the last status line ("#N ... cov: C ft: F ...").
coverage() { grep -o 'cov: [0-9]* ft: [0-9]*' "$1" | tail -1 | awk '{print $2, $4}'; }

# Per target: maxlen (libFuzzer's -max_len: the largest input worth mutating, which
# bounds the cost of one execution, as the parsers' work grows with their input) and
# tflags/tenv (more libFuzzer flags, more environment), each justified below.
target_settings() {
    tflags=() tenv=()
    case $1 in
    # 1 024 listed directions (the reader's limit, a count check) take 20 KB; a ring
    # table of 32 rings 2 KB, a list of 150 directions 4 KB, and the triangulation's
    # cost grows with the list. Its 64 x 64 lookup table is most of an accepted list's
    # time (made once per list since the interpolation keeps the check's table).
    dirset) maxlen=8192 ;;
    # the manifest of a 64x64 package is 16 KB, the largest saved input 20 KB
    manifest) maxlen=24576 ;;
    # a DFMF08FC header, its direction tables and a few small factor blocks; the
    # largest saved input is 9 KB and the reader's limits are header values
    dfmf) maxlen=16384 ;;
    # one byte and one file of a 16x16 package (textures, weights, manifest): the
    # largest is 4 KB; libFuzzer's rare-feature weighting (entropic) is most of the
    # time of these readers, -entropic=0 (plain weighting) doubles their rate
    package | package_mem) maxlen=8192 tflags=(-entropic=0) ;;
    # meta.json, R.png or 0.png of a package with C 2, N 7, k 7, S 4: under 1 KB
    thesis | thesis_mem) maxlen=4096 tflags=(-entropic=0) ;;
    # a file name (NAME_MAX is 255)
    ubo2003_name) maxlen=1024 ;;
    # the bytes of a BTF of at most 4 x 4 texels and 12 x 12 directions (6 912
    # samples) are cycled through, so a longer input only repeats them; -entropic=0
    # as for the package readers: 207 against 181 executions per CPU second (25 s
    # each, the same coverage)
    roundtrip) maxlen=4096 tflags=(-entropic=0) ;;
    # a .glb/.gltf of a few parts; the largest saved model is 7 KB
    gltf) maxlen=32768 ;;
    # an .hdr of up to 512 x 256 run-length coded. OpenImageIO tries every other
    # reader it has (DICOM, FITS, ...) on a file its .hdr reader refuses, nine tenths
    # of the time of this target and none of it the project's code: this stops it
    # after the reader the name picks (measured: 870 -> 8 600 executions a second)
    hdr) maxlen=32768 tenv=(OPENIMAGEIO_OPTIONS=try_all_readers=0) ;;
    # the request parser's own limit is below
    request) maxlen=20000 ;;
    *) maxlen=65536 ;;
    esac
}

# 10 million executions at a rate of $1 a second, as "5m", "1h45m" or "2d3h".
to_10m() {
    local s
    (($1 > 0)) || { echo -; return; }
    s=$((10000000 / $1))
    if ((s < 3600)); then echo "$(((s + 59) / 60))m"
    elif ((s < 86400)); then echo "$((s / 3600))h$(((s % 3600) / 60))m"
    else echo "$((s / 86400))d$(((s % 86400) / 3600))h"; fi
}

rows=() failed=0
for t in "$@"; do
    bin=$build/fuzz/fuzz_$t log=$build/fuzz/log/$t.txt
    [[ -x $bin ]] || { echo "fuzz: $bin is not built (make fuzz builds it)" >&2; exit 2; }
    target_settings "$t"
    args=(-max_total_time="$seconds" -rss_limit_mb="$rss" -malloc_limit_mb="$rss" -max_len=$maxlen
          -print_final_stats=1 "${tflags[@]}")
    bound="$seconds s"
    ((runs > 0)) && args+=(-runs="$runs") bound+=" or $runs runs"
    ((fork > 0)) && args+=(-fork="$fork") bound+=", $fork processes"
    args+=($flags)
    echo "fuzz: $t for $bound: ${tenv[*]} ${args[*]}"
    start=$(date +%s.%N)
    (cd "$build/fuzz" && env TMPDIR=$tmp ASAN_OPTIONS=$asan LSAN_OPTIONS=$lsan OMP_NUM_THREADS=$threads \
        OPENBLAS_NUM_THREADS=$threads "${tenv[@]}" \
        $nice "./fuzz_$t" "${args[@]}" "$corpus/$t" >"log/$t.txt" 2>&1)
    rc=$?
    wall=$(echo "$(date +%s.%N) - $start" | bc)
    if ((fork > 0)); then # the parent's last status line: "#N: cov: C ft: F corp: ..."
        execs=$(sed -n 's/^#\([0-9]*\): cov:.*/\1/p' "$log" | tail -1)
        rate=$(awk -v n="${execs:-0}" -v w="$wall" 'BEGIN { printf "%d", (w > 0 ? n / w : 0) }')
    else
        execs=$(stat number_of_executed_units "$log") rate=$(stat average_exec_per_sec "$log")
    fi
    read -r cov ft <<<"$(coverage "$log")"
    result=ok
    leak=$(sed -n 's/.*Test unit written to \(.*leak-[0-9a-f]*\)$/\1/p' "$log" | tail -1)
    if ((rc != 0)) && [[ -n $leak ]] && (cd "$build/fuzz" && env TMPDIR=$tmp LSAN_OPTIONS=$lsan \
        ASAN_OPTIONS=fast_unwind_on_malloc=0 "${tenv[@]}" "./fuzz_$t" "$leak" >>"log/$t.txt" 2>&1); then
        rc=0 result="suppressed leak ($leak)"
    fi
    if ((rc != 0)); then
        result="FAILED (rc $rc)" failed=1
        tail -40 "$log"
    fi
    load=$(cut -d' ' -f1 /proc/loadavg) # other work on the machine slows a target down
    rows+=("$(printf '%-13s %11s %8.0f %9s %8s %6s %7s %7s %7s %5s  %s' "$t" "${execs:-?}" "$wall" "${rate:-?}" \
        "$(to_10m "${rate:-0}")" "${cov:-?}" "${ft:-?}" "$(ls "$corpus/$t" | wc -l)" "$maxlen" "$load" "$result")")
done

{
    echo "# make fuzz: FUZZ_SECONDS=$seconds FUZZ_RUNS=$runs FUZZ_FORK=$fork, $(date -u +%Y-%m-%dT%H:%MZ), $(nproc) cores, scratch in $tmp"
    printf '%-13s %11s %8s %9s %8s %6s %7s %7s %7s %5s  %s\n' target execs seconds exec/s "10M in" cov ft corpus \
        max_len load result
    printf '%s\n' "${rows[@]}"
} | tee "$summary"
echo "fuzz: summary in $summary"
exit $failed
