#!/usr/bin/env bash
# tests/asan_reports.sh DIR - the end of `make asan`: prints every sanitizer report
# the processes of the run wrote under DIR (ASan, LeakSanitizer and UBSan write
# DIR/asan.PID or DIR/ubsan.PID through log_path) and exits 1 when there is any, 0
# when there is none.
#
# tests/asan_reports.sh --canary DIR - the canary's check (tests/test_sanitizer.c,
# run with BTF_LEAK_CANARY=1 and DIR as its log_path): exits 0 when LeakSanitizer
# reported the 162 bytes it leaks from canary_block, 1 (naming tests/lsan.supp) when
# nothing did: then the suppressions hide leaks made inside test processes.
set -uo pipefail
shopt -s nullglob
if [[ ${1:-} == --canary ]]; then
    dir=${2:?usage: tests/asan_reports.sh --canary DIR}
    for f in "$dir"/asan.*; do
        grep -q 'Direct leak of 162 byte' "$f" && grep -q canary_block "$f" &&
            { echo "asan: the canary's leak in a test process was reported"; exit 0; }
    done
    echo "asan: the canary's leak (tests/test_sanitizer.c) was not reported: tests/lsan.supp hides leaks made in test processes" >&2
    exit 1
fi
dir=${1:?usage: tests/asan_reports.sh DIR}
reports=()
for f in "$dir"/asan.* "$dir"/ubsan.*; do
    # a report names its kind (ERROR: LeakSanitizer / AddressSanitizer, "runtime error"
    # of UBSan, a WARNING); a file with only LeakSanitizer's statistics of suppressed
    # third-party leaks (tests/lsan.supp) is no report
    grep -q -E 'ERROR:|runtime error|WARNING:|SUMMARY:' "$f" && reports+=("$f")
done
if ((${#reports[@]} == 0)); then
    echo "asan: no sanitizer report from any process"
    exit 0
fi
for r in "${reports[@]}"; do
    echo "==== $r"
    cat "$r"
done
echo "asan: ${#reports[@]} sanitizer report(s) above (files in $dir)" >&2
exit 1
