//! Sets `cfg(vector_lanes)` where `wide`'s 128-bit types are vector registers: SSE2,
//! WebAssembly's simd128, and NEON on aarch64 (`wide`'s own conditions). Elsewhere (the
//! Cortex-M4F firmware, 32-bit ARM) its lanes are arrays run one by one, and the core
//! takes the paths that cost fewer instructions there. The choice never changes a result.

use std::env;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(vector_lanes)");
    println!("cargo::rerun-if-changed=build.rs");
    let features = env::var("CARGO_CFG_TARGET_FEATURE").unwrap_or_default();
    let has = |feature: &str| features.split(',').any(|f| f == feature);
    let aarch64 = env::var("CARGO_CFG_TARGET_ARCH").is_ok_and(|arch| arch == "aarch64");
    if has("sse2") || has("simd128") || (has("neon") && aarch64) {
        println!("cargo::rustc-cfg=vector_lanes");
    }
}
