#!/usr/bin/env bash
# Native vs wasm32 determinism of riseg-core (issue 15 item 5, DESIGN §2): builds the
# digest crate natively and for wasm32-unknown-unknown (Debian rustc-web with build-std,
# see TOOLCHAIN.md), runs the wasm under node, and fails unless both print the same
# input and output digests. Set CARGO_TARGET_DIR to build elsewhere.
set -euo pipefail
cd "$(dirname "$0")"
target="${CARGO_TARGET_DIR:-target}"

native="$(cargo run --release --quiet)"
RUSTC=/usr/bin/rustc RUSTC_BOOTSTRAP=1 CARGO_TARGET_DIR="$target/wasm" \
  CARGO_TARGET_WASM32_UNKNOWN_UNKNOWN_LINKER=/usr/lib/llvm-22/bin/wasm-ld \
  /usr/bin/cargo build --release --quiet --lib --target wasm32-unknown-unknown \
  -Z build-std=std,panic_abort
wasm="$target/wasm/wasm32-unknown-unknown/release/riseg_determinism.wasm"
wasm_out="$(node -e '
  const bytes = require("fs").readFileSync(process.argv[1]);
  WebAssembly.instantiate(bytes, {}).then(({ instance: { exports: e } }) => {
    const hex = (v) => BigInt.asUintN(64, v).toString(16).padStart(16, "0");
    console.log(`input ${hex(e.riseg_input_digest())} output ${hex(e.riseg_output_digest())}`);
  });
' "$wasm")"
printf 'native: %s\nwasm32: %s\n' "$native" "$wasm_out"
case "$native" in
  *0000000000000000*) echo "determinism: a digest is 0, so the step failed" >&2; exit 1 ;;
esac
if [ "$native" != "$wasm_out" ]; then
  echo "determinism: native and wasm32 digests differ" >&2
  exit 1
fi
echo "determinism: native and wasm32 agree"
