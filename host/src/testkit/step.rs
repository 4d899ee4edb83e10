//! Owned synthetic UpdateMask inputs for benchmarks, demos of the core, and reference
//! comparisons: touching box tops in a row, all merged into one segment, with exact depth
//! and flow from [`riseg_core::synth`].

use riseg_core::{
    Error, ImageView, Intrinsics,
    frames::MotionInput,
    synth::{Moment, TouchingBoxes},
};

/// One step's inputs at `width × height`, owned.
#[derive(Debug, Clone)]
pub struct SyntheticStep {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Camera intrinsics (D415-like, scaled to the width).
    pub intrinsics: Intrinsics,
    /// Depth before the push, metres.
    pub depth_t: Vec<f32>,
    /// Depth after the push, metres.
    pub depth_t1: Vec<f32>,
    /// True instance labels before the push.
    pub truth_t: Vec<u16>,
    /// True instance labels after the push.
    pub truth_t1: Vec<u16>,
    /// All objects merged into label 1 before the push (the accumulated mask).
    pub merged_t: Vec<u16>,
    /// All objects merged into label 1 after the push (the static mask).
    pub merged_t1: Vec<u16>,
    /// Exact forward flow, `[dx, dy]` pixels.
    pub flow: Vec<[f32; 2]>,
}

impl SyntheticStep {
    /// riseg-core's [`TouchingBoxes`]: five touching box tops 60 cm from the camera; the
    /// first stays, the others slide or turn a little (up to 1.2 cm, 8°), as after a 2 cm
    /// push.
    ///
    /// # Errors
    /// If `width·height` overflows or the width is too small for a camera.
    pub fn touching_boxes(width: usize, height: usize) -> Result<Self, Error> {
        let boxes = TouchingBoxes::new(width, height)?;
        let scene = boxes.scene();
        let intrinsics = boxes.intrinsics;
        let n = width.checked_mul(height).ok_or(Error::BadImageLayout)?;
        let mut step = Self {
            width,
            height,
            intrinsics,
            depth_t: vec![0.0; n],
            depth_t1: vec![0.0; n],
            truth_t: vec![0; n],
            truth_t1: vec![0; n],
            merged_t: Vec::new(),
            merged_t1: Vec::new(),
            flow: vec![[0.0; 2]; n],
        };
        scene.render(Moment::Before, &mut step.depth_t, &mut step.truth_t)?;
        scene.render(Moment::After, &mut step.depth_t1, &mut step.truth_t1)?;
        scene.flow(&mut step.flow)?;
        step.merged_t = step.truth_t.iter().map(|&l| u16::from(l != 0)).collect();
        step.merged_t1 = step.truth_t1.iter().map(|&l| u16::from(l != 0)).collect();
        Ok(step)
    }

    /// The core's view of the step, with the merged mask as the accumulated mask.
    ///
    /// # Errors
    /// None in practice: the buffers are sized by construction.
    pub fn input(&self) -> Result<MotionInput<'_>, Error> {
        let (w, h) = (self.width, self.height);
        MotionInput::new(
            ImageView::packed(w, h, &self.merged_t)?,
            ImageView::packed(w, h, &self.depth_t)?,
            ImageView::packed(w, h, &self.depth_t1)?,
            ImageView::packed(w, h, &self.flow)?,
            self.intrinsics,
        )
    }

    /// The static mask after the push (everything merged).
    ///
    /// # Errors
    /// None in practice: the buffer is sized by construction.
    pub fn static_t1(&self) -> Result<ImageView<'_, u16>, Error> {
        ImageView::packed(self.width, self.height, &self.merged_t1)
    }
}
