//! Digests of one riseg-core UpdateMask step on a fixed synthetic input
//! (`riseg::testkit::SyntheticStep::touching_boxes` at [`WIDTH`]×[`HEIGHT`],
//! `Config::PAPER`), for comparing targets: DESIGN §2 promises that the same inputs and
//! seed give bit-identical outputs on x86_64 and wasm32.
//!
//! [`input_digest`] covers the synthetic input (depth, labels, flow bits), [`output_digest`]
//! the corrected mask and the bits of the step report (frame count, space origin, group
//! and label counts). Both are FNV-1a 64 over little-endian bytes ([`digest`], which the
//! bare-metal firmware of `firmware/` compiles too). The wasm32 build exports
//! them as `riseg_input_digest` and `riseg_output_digest` (no imports, no bindgen); `check.sh`
//! runs them under node and compares with the native binary's output.

pub mod digest;

use riseg::{rig::workspace::WorkspaceBuf, testkit::SyntheticStep};
use riseg_core::{Config, pipeline::update_mask};

/// Image width, pixels.
pub const WIDTH: usize = 160;
/// Image height, pixels.
pub const HEIGHT: usize = 120;

fn step() -> Option<SyntheticStep> {
    SyntheticStep::touching_boxes(WIDTH, HEIGHT).ok()
}

/// Digest of the synthetic input; `0` if it cannot be built.
#[must_use]
pub fn input_digest() -> u64 {
    let Some(s) = step() else { return 0 };
    digest::input(&s.depth_t, &s.depth_t1, &s.flow, &s.merged_t, &s.merged_t1)
}

/// Digest of the step's output; `0` if the step fails.
#[must_use]
pub fn output_digest() -> u64 {
    let Some(s) = step() else { return 0 };
    let (Ok(input), Ok(static_t1)) = (s.input(), s.static_t1()) else {
        return 0;
    };
    let cfg = Config::PAPER;
    let mut buf = WorkspaceBuf::new(&cfg, WIDTH, HEIGHT);
    let mut labels = vec![0u16; WIDTH * HEIGHT];
    let Ok(report) = update_mask(&input, &static_t1, &cfg, &mut buf.view(), &mut labels) else {
        return 0;
    };
    digest::output(&labels, &report)
}

/// [`input_digest`] for wasm hosts.
#[unsafe(no_mangle)]
pub extern "C" fn riseg_input_digest() -> u64 {
    input_digest()
}

/// [`output_digest`] for wasm hosts.
#[unsafe(no_mangle)]
pub extern "C" fn riseg_output_digest() -> u64 {
    output_digest()
}
