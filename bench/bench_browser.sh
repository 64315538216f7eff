#!/usr/bin/env bash
# bench/bench_browser.sh - the viewer's renderer against the thesis shader in headless
# Chromium, 1280x720, C = 8 (bench/bench_browser.mjs); run by bench/run.sh, which
# writes its stdout to bench/results/browser.txt. Needs `make build` (btf), `npm ci`
# (playwright-core) and Debian's chromium. Loopback only.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
BUILD=${BUILD:-build}
[[ -x $BUILD/btf ]] || { echo "bench_browser: $BUILD/btf is missing: run 'make build' first" >&2; exit 1; }
[[ -d node_modules/playwright-core ]] || { echo "bench_browser: run 'npm ci' first (playwright-core)" >&2; exit 1; }
BTF_BUILD=$(cd "$BUILD" && pwd) exec node bench/bench_browser.mjs
