#!/usr/bin/env bash
# fuzz/parallel.sh - fuzz/run.sh once per target, FUZZ_JOBS targets at a time, each
# with its own summary and log, then one table of them all in FUZZ_SUMMARY (`make
# fuzz` and `make fuzz-deep` call it when FUZZ_JOBS is more than 1; fuzz-deep's
# default is every core). Every other setting (FUZZ_RUNS, FUZZ_SECONDS, FUZZ_NICE,
# FUZZ_CORPUS, ...) passes through to run.sh, whose header says what they do.
#
#   FUZZ_JOBS=2 FUZZ_RUNS=10000000 FUZZ_SECONDS=3600 bash fuzz/parallel.sh build-fuzz TARGET...
#
# Targets start in the order given, as lanes free up. The table lists them in that
# order; its "load" column is the machine's load when each ended (the other lanes
# count in it). Exit: 1 when any target failed (its run.sh output's tail is
# printed), 2 when one did not run at all, else 0.
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:?usage: fuzz/parallel.sh BUILD TARGET...}
shift
jobs=${FUZZ_JOBS:-$(nproc)}
summary=${FUZZ_SUMMARY:-$build/fuzz/summary.txt}
parts=$build/fuzz/parts
rm -rf "$parts" && mkdir -p "$parts" "$(dirname "$summary")"
export build parts
printf '%s\n' "$@" | xargs -P "$jobs" -I{} bash -c \
    'FUZZ_SUMMARY=$parts/{}.txt bash fuzz/run.sh "$build" {} >"$parts/{}.out" 2>&1 || echo $? >"$parts/{}.rc"'
rc=0
for t in "$@"; do
    [[ -f $parts/$t.rc ]] || continue
    tail -45 "$parts/$t.out"
    [[ -f $parts/$t.txt ]] && rc=$((rc > 1 ? rc : 1)) || rc=2
done
{
    head -2 "$parts/$1.txt" 2>/dev/null | sed "1s/\$/, $jobs targets at a time/"
    for t in "$@"; do sed -n 3p "$parts/$t.txt" 2>/dev/null || echo "$t: did not run"; done
} | tee "$summary"
echo "fuzz: summary in $summary"
exit $rc
