#!/usr/bin/env bash
# tests/asan_reports.sh DIR - the end of `make asan`: prints every sanitizer report
# the processes of the run wrote under DIR (ASan, LeakSanitizer and UBSan write
# DIR/asan.PID or DIR/ubsan.PID through log_path) and exits 1 when there is any, 0
# when there is none.
set -uo pipefail
dir=${1:?usage: tests/asan_reports.sh DIR}
shopt -s nullglob
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
