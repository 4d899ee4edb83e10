//! The step's inputs, rendered into caller buffers: the same five touching box tops as the
//! host's `riseg::testkit::SyntheticStep::touching_boxes` (which needs a heap), built here
//! from riseg-core's own [`synth`](riseg_core::synth) renderer. Every number below is the
//! testkit's, so the two give bit-identical inputs; `run.sh` checks that through the
//! input digest.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use riseg_core::{
    Error, Intrinsics,
    synth::{Moment, SynthBox, SynthScene},
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

/// The testkit's camera: D415-like, focal length scaled to the width.
///
/// # Errors
/// Those of [`Intrinsics::new`] (a zero width gives a zero focal length).
pub fn intrinsics(width: usize, height: usize) -> Result<Intrinsics, Error> {
    let f = 615.0 * width as f32 / 640.0;
    Intrinsics::new(
        f,
        f,
        (width as f32 - 1.0) / 2.0,
        (height as f32 - 1.0) / 2.0,
    )
}

/// Five touching box tops 60 cm from the camera: the first stays, the others slide or turn
/// a little (up to 1.2 cm, 8°), as after a 2 cm push. Renders both moments and the flow
/// into `images`, then merges the true labels into one segment.
///
/// # Errors
/// Those of [`SynthScene::render`]: a buffer shorter than `width·height`.
pub fn touching_boxes(
    width: usize,
    height: usize,
    intrinsics: Intrinsics,
    images: &mut StepImages<'_>,
) -> Result<(), Error> {
    let facing_camera = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), core::f32::consts::PI);
    // (dx, dy, turn) of each box, metres and radians.
    let motions: [(f32, f32, f32); 5] = [
        (0.0, 0.0, 0.0),
        (0.0, 0.012, 0.0),
        (0.0, 0.0, 8f32.to_radians()),
        (0.006, -0.004, -5f32.to_radians()),
        (0.0, 0.0, 0.0),
    ];
    let mut index = 0u16;
    let boxes = motions.map(|(dx, dy, angle)| {
        let i = f32::from(index);
        index += 1;
        let centre = Vector3::new((i - 2.0) * 0.07, 0.0, 0.6 - 0.004 * i);
        let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle);
        let spin = Isometry3::from_parts(Translation3::from(centre - turn * centre), turn);
        SynthBox {
            camera_from_box: Isometry3::from_parts(Translation3::from(centre), facing_camera),
            half_extent_m: [0.035, 0.05],
            motion: Translation3::new(dx, dy, 0.0) * spin,
            label: index,
        }
    });
    let scene = SynthScene {
        boxes: &boxes,
        table_depth_m: 0.66,
        intrinsics,
        width,
        height,
    };
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
    Ok(())
}
