#!/usr/bin/env bash
# The browser tests: builds the wasm (web/build.sh) and the native `riseg` they compare
# against, then runs web/test/*.test.js in Debian's headless Chromium via playwright-core.
# Needs /usr/bin/chromium (apt-get install chromium) and `npm ci` run in web/; never
# downloads a browser. The screenshot goes to $ARTIFACTS (default web/test-artifacts/).
set -euo pipefail
cd "$(dirname "$0")/.."

CACHE="${RISEG_CI_CACHE:-$HOME/.cache/riseg-ci}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$CACHE/target}"
[ -x "${CHROMIUM:-/usr/bin/chromium}" ] || { echo "web/test.sh: no ${CHROMIUM:-/usr/bin/chromium}: apt-get install chromium" >&2; exit 1; }
[ -d web/node_modules/playwright-core ] || { echo "web/test.sh: run (cd web && npm ci) first" >&2; exit 1; }

web/build.sh
cargo build --quiet --release -p riseg
export RISEG_BIN="$CARGO_TARGET_DIR/release/riseg"
node --test --test-concurrency=1 web/test/browser.test.js
