//! The step's inputs, rendered into caller buffers: riseg-core's
//! [`TouchingBoxes`](riseg_core::synth::TouchingBoxes), the scene the host's
//! `riseg::testkit::SyntheticStep::touching_boxes` renders into owned buffers, so the two
//! give bit-identical inputs; `run.sh` checks that through the input digest.

use riseg_core::{
    Error, Intrinsics,
    synth::{Moment, TouchingBoxes},
};

/// Borrowed input images of one step, `width·height` elements each, row-major.
#[derive(Debug)]
pub struct StepImages<'a> {
    /// Depth before the push, metres.
    pub depth_t: &'a mut [f32],
    /// Depth after the push, metres.
    pub depth_t1: &'a mut [f32],
    /// Every object merged into label 1 before the push (the accumulated mask).
    pub merged_t: &'a mut [u16],
    /// Every object merged into label 1 after the push (the static mask).
    pub merged_t1: &'a mut [u16],
    /// Exact forward flow, `[dx, dy]` pixels.
    pub flow: &'a mut [[f32; 2]],
}

/// riseg-core's [`TouchingBoxes`] step at `width × height`, rendered into `images` (both
/// moments and the exact flow), then every object merged into label 1, as the host's
/// `SyntheticStep::touching_boxes` does it with owned buffers.
///
/// # Errors
/// Those of [`TouchingBoxes::new`] and [`SynthScene::render`](riseg_core::synth::SynthScene::render):
/// a width too small for a camera, a buffer shorter than `width·height`.
pub fn touching_boxes(
    width: usize,
    height: usize,
    images: &mut StepImages<'_>,
) -> Result<Intrinsics, Error> {
    let boxes = TouchingBoxes::new(width, height)?;
    let scene = boxes.scene();
    scene.render(Moment::Before, images.depth_t, images.merged_t)?;
    scene.render(Moment::After, images.depth_t1, images.merged_t1)?;
    scene.flow(images.flow)?;
    for l in images
        .merged_t
        .iter_mut()
        .chain(images.merged_t1.iter_mut())
    {
        *l = u16::from(*l != 0);
    }
    Ok(boxes.intrinsics)
}
