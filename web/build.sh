#!/usr/bin/env bash
# Builds web/pkg/ (riseg_wasm.js + riseg_wasm_bg.wasm) for the browser demo.
#
# The wasm32 standard library comes from Debian's rustc-web with build-std (the rustup
# toolchains here have no wasm32 std; ../shared/TOOLCHAIN.md), linked by wasm-ld. The JS
# glue comes from wasm-bindgen-cli of exactly the version of the `wasm-bindgen` crate in
# Cargo.lock, installed once into $CACHE/tools (outside the clone) and reused.
#
# The module uses WebAssembly SIMD (simd128: Chrome 91, Firefox 89, Safari 16.4 and later);
# LLVM vectorises the flow's loops with it (about 2x faster flow) without changing a bit of
# any result (the browser tests compare digests with native). Its build has a folder of its
# own, so the plain wasm32 builds of .ci/run do not rebuild std back and forth.
#
# Environment: RISEG_CI_CACHE (default ~/.cache/riseg-ci) holds the tools and the build;
# CROSS_TARGET_DIR overrides the wasm32 target folder (this build uses its simd128/).
set -euo pipefail
cd "$(dirname "$0")/.."

CACHE="${RISEG_CI_CACHE:-$HOME/.cache/riseg-ci}"
CROSS_TARGET_DIR="${CROSS_TARGET_DIR:-$CACHE/target-cross}"
TOOLS="$CACHE/tools"

for need in /usr/bin/rustc /usr/bin/cargo /usr/lib/llvm-22/bin/wasm-ld; do
  [ -x "$need" ] || { echo "web/build.sh: $need missing: apt-get install rustc-web cargo-web rust-web-src lld-22 (../shared/TOOLCHAIN.md)" >&2; exit 1; }
done

# The wasm-bindgen version Cargo.lock pins (the crate pins it with `=` in wasm/Cargo.toml).
version="$(awk '/^name = "wasm-bindgen"$/ { getline; gsub(/version = |"/, ""); print; exit }' Cargo.lock)"
[ -n "$version" ] || { echo "web/build.sh: no wasm-bindgen in Cargo.lock" >&2; exit 1; }
bindgen="$TOOLS/bin/wasm-bindgen"
if ! [ -x "$bindgen" ] || [ "$("$bindgen" --version)" != "wasm-bindgen $version" ]; then
  # Not --locked: the lock file of wasm-bindgen-cli 0.2.130 pins webpki-roots 1.0.11,
  # which the registry reachable here does not have; the tool's version is still exact.
  cargo install --quiet --root "$TOOLS" wasm-bindgen-cli --version "=$version" --force
fi

target="$CROSS_TARGET_DIR/simd128"
RUSTC=/usr/bin/rustc RUSTC_BOOTSTRAP=1 CARGO_TARGET_DIR="$target" \
  CARGO_TARGET_WASM32_UNKNOWN_UNKNOWN_RUSTFLAGS="-C target-feature=+simd128" \
  CARGO_TARGET_WASM32_UNKNOWN_UNKNOWN_LINKER=/usr/lib/llvm-22/bin/wasm-ld /usr/bin/cargo build \
  --quiet --release -p riseg-wasm --features js --target wasm32-unknown-unknown -Z build-std=std,panic_abort

"$bindgen" --target web --no-typescript --out-dir web/pkg \
  "$target/wasm32-unknown-unknown/release/riseg_wasm.wasm"
echo "built web/pkg: $(du -b web/pkg/riseg_wasm_bg.wasm | cut -f1) bytes of wasm"
