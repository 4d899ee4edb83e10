//! Native twin of the firmware: one UpdateMask step on the host's
//! `SyntheticStep::touching_boxes(160, 120)` with `Config::PAPER` over a heap
//! `WorkspaceBuf`, printed as the firmware prints it: `input <hex> output <hex>`.
//!
//! The scene and workspace come from `riseg` (independent of the firmware's static
//! buffers and its own scene code); only the digest is shared, so equal lines mean equal
//! inputs and bit-identical outputs on x86_64 and the Cortex-M4F. Exits 1 if the step fails.

#[path = "../../src/digest.rs"]
mod digest;

use std::process::ExitCode;

use riseg::{rig::workspace::WorkspaceBuf, testkit::SyntheticStep};
use riseg_core::{Config, Error, pipeline::update_mask};

/// Image size, as in the firmware.
const WIDTH: usize = 160;
const HEIGHT: usize = 120;

fn digests() -> Result<(u64, u64), Error> {
    let s = SyntheticStep::touching_boxes(WIDTH, HEIGHT)?;
    let input = digest::input(&s.depth_t, &s.depth_t1, &s.flow, &s.merged_t, &s.merged_t1);
    let cfg = Config::PAPER;
    let mut ws = WorkspaceBuf::new(&cfg, WIDTH, HEIGHT);
    let mut labels = vec![0u16; WIDTH * HEIGHT];
    let report = update_mask(
        &s.input()?,
        &s.static_t1()?,
        &cfg,
        &mut ws.view(),
        &mut labels,
    )?;
    Ok((input, digest::output(&labels, &report)))
}

fn main() -> ExitCode {
    match digests() {
        Ok((input, output)) => {
            println!("input {input:016x} output {output:016x}");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("native step failed: {e}");
            ExitCode::FAILURE
        }
    }
}
