#!/bin/sh
# chromium-nice.sh - the browser of the tests (tests/e2e/util.mjs), started at a lower
# CPU priority (nice 10; its renderer and software-GL processes inherit it). The test
# host runs the emulated link (throttle.mjs) and btfd on the same two cores as the
# browser; in the field the network does not wait for the phone's CPU, so here the
# link and the server come first. CHROMIUM_BIN: another browser binary.
exec nice -n 10 "${CHROMIUM_BIN:-/usr/bin/chromium}" "$@"
