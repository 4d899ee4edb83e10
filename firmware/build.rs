//! Puts `memory.x` where cortex-m-rt's `link.x` finds it, and writes a linker map next to
//! the ELF (`target/thumbv7em-none-eabihf/<profile>/riseg-firmware.map`) for run.sh.

use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::copy("memory.x", out.join("memory.x")).expect("memory.x is next to Cargo.toml");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    // OUT_DIR is <profile dir>/build/<package>-<hash>/out.
    if let Some(profile_dir) = out.ancestors().nth(3) {
        let map = profile_dir.join("riseg-firmware.map");
        println!("cargo:rustc-link-arg-bins=-Map={}", map.display());
    }
}
