#!/usr/bin/env bash
# bench/bench_link.sh - the browser viewer through a throttled link at 1, 4 and 16 Mbit/s
# (bench/bench_link.mjs: time to first frame, to complete, link utilisation); run by
# bench/run.sh, which writes its stdout to bench/results/link.txt. Needs `make build`
# (btf, btfd), `npm ci` (playwright-core) and Debian's chromium. Loopback only.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD=${BUILD:-build}
for f in "$BUILD/btf" "$BUILD/btfd"; do
    [[ -x $f ]] || { echo "bench_link: $f is missing: run 'make build' first" >&2; exit 1; }
done
[[ -d node_modules/playwright-core ]] || { echo "bench_link: run 'npm ci' first (playwright-core)" >&2; exit 1; }
BTF_BUILD=$(cd "$BUILD" && pwd) exec node bench/bench_link.mjs
