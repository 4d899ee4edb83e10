//! FNV-1a 64 over little-endian bytes of one step's inputs and outputs. `core` only: the
//! bare-metal firmware compiles this file too (`#[path]`), so the native, wasm32 and
//! Cortex-M digests differ only if the data do.

use riseg_core::pipeline::StepReport;

/// FNV-1a 64 state.
#[derive(Debug, Clone, Copy)]
struct Fnv(u64);

impl Fnv {
    const fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }

    fn bytes(mut self, bytes: &[u8]) -> Self {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
        self
    }

    fn f32s<'a>(self, values: impl IntoIterator<Item = &'a f32>) -> Self {
        values
            .into_iter()
            .fold(self, |h, v| h.bytes(&v.to_bits().to_le_bytes()))
    }

    fn u16s(self, values: &[u16]) -> Self {
        values.iter().fold(self, |h, v| h.bytes(&v.to_le_bytes()))
    }
}

/// Digest of the inputs: both depths, the flow, then both merged masks.
#[must_use]
pub fn input(
    depth_t: &[f32],
    depth_t1: &[f32],
    flow: &[[f32; 2]],
    merged_t: &[u16],
    merged_t1: &[u16],
) -> u64 {
    Fnv::new()
        .f32s(depth_t.iter().chain(depth_t1))
        .f32s(flow.iter().flatten())
        .u16s(merged_t)
        .u16s(merged_t1)
        .0
}

/// Digest of the output: the corrected mask, then the frame, sample, group and largest
/// label counts (as `u64`), then the bits of the space origin.
#[must_use]
pub fn output(labels_t1: &[u16], report: &StepReport) -> u64 {
    let counts = [
        report.frames.count,
        report.frames.sampled,
        report.grouping.count,
        usize::from(report.mask.max_label),
    ];
    counts
        .iter()
        .fold(Fnv::new().u16s(labels_t1), |h, &c| {
            h.bytes(&(c as u64).to_le_bytes())
        })
        .f32s(report.frames.space_origin.coords.iter())
        .0
}
