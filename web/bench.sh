#!/usr/bin/env bash
# Benchmark, not a test: one optical-flow call and one UpdateMask step (frames 0 -> 1 of the
# bundled packed scene, 640x480) in riseg-wasm, natively (the same Session code, one thread)
# and in headless Chromium; prints both medians and the wasm/native ratio.
set -euo pipefail
cd "$(dirname "$0")/.."
CACHE="${RISEG_CI_CACHE:-$HOME/.cache/riseg-ci}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$CACHE/target}"
RUNS="${RUNS:-7}"
web/build.sh >/dev/null
native="$(cargo run --quiet --release -p riseg-wasm --features js --example bench_stages -- web/scenes/packed "$RUNS")"
NATIVE="$native" RUNS="$RUNS" node web/bench/wasm-vs-native.js
