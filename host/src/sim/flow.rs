//! Exact forward optical flow between two frames, from the simulated object poses.

use nalgebra::Point3;
use riseg_core::{Intrinsics, Pose};

use super::{ObjectPose, SimError};
use crate::io::image::{DepthImage, FlowImage, Gray16Image, Image};

/// Flow value stored where a moved point falls behind the camera (Middlebury's
/// "unknown" convention: any component above 1e9). It does not occur on a tabletop.
pub const UNKNOWN_FLOW_PX: f32 = 1e10;

/// The forward flow from frame `t` to frame `t + 1` caused by the objects' motion.
///
/// For each pixel `(u, v)` of frame `t` with label `l > 0`: back-project it with the exact
/// depth `true_depth_m` to `p` (camera frame), move `p` by that object's motion
/// `camera_from_world · world_from_object_{t+1} · world_from_object_tⁱ⁻¹ · world_from_camera`,
/// project, and store the pixel displacement. Table/background pixels (label 0) and pixels
/// without depth get zero flow. The camera does not move between frames.
///
/// `labels` and `true_depth_m` are frame `t`'s ground truth; `before` and `after` are the
/// objects' poses at `t` and `t + 1` (the same labels in both, any order).
///
/// # Errors
/// [`SimError::SizeMismatch`] if `labels` and `true_depth_m` differ in size;
/// [`SimError::UnknownLabel`] if a label in the image has no pose in `before` or `after`.
pub fn ground_truth_flow(
    intrinsics: &Intrinsics,
    world_from_camera: &Pose,
    labels: &Gray16Image,
    true_depth_m: &DepthImage,
    before: &[ObjectPose],
    after: &[ObjectPose],
) -> Result<FlowImage, SimError> {
    if (labels.width(), labels.height()) != (true_depth_m.width(), true_depth_m.height()) {
        return Err(SimError::SizeMismatch {
            labels: (labels.width(), labels.height()),
            depth: (true_depth_m.width(), true_depth_m.height()),
        });
    }
    // Motion in the camera frame for every label that occurs, indexed by label.
    let max_label = labels.as_slice().iter().copied().max().unwrap_or(0);
    let mut motion: Vec<Option<Pose>> = vec![None; usize::from(max_label) + 1];
    let find = |poses: &[ObjectPose], label: u16| {
        poses
            .iter()
            .find(|p| p.label == label)
            .map(|p| p.world_from_object)
            .ok_or(SimError::UnknownLabel(label))
    };
    let camera_from_world = world_from_camera.inverse();
    for &label in labels.as_slice() {
        let slot = &mut motion[usize::from(label)];
        if label == 0 || slot.is_some() {
            continue;
        }
        let world_motion = find(after, label)? * find(before, label)?.inverse();
        *slot = Some(camera_from_world * world_motion * world_from_camera);
    }

    let (lab, depth) = (labels.as_slice(), true_depth_m.as_slice());
    let width = labels.width();
    Ok(Image::from_fn(labels.width(), labels.height(), |x, y| {
        let i = y * width + x;
        let (z, m) = (depth[i], motion[usize::from(lab[i])]);
        match m {
            Some(m) if z > 0.0 => {
                let (u, v) = (x as f32, y as f32);
                let p: Point3<f32> = m * intrinsics.back_project(u, v, z);
                intrinsics
                    .project(&p)
                    .map_or([UNKNOWN_FLOW_PX; 2], |q| [q.x - u, q.y - v])
            }
            _ => [0.0, 0.0],
        }
    }))
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    use super::*;

    fn k() -> Intrinsics {
        Intrinsics::new(500.0, 500.0, 3.5, 2.5).unwrap()
    }

    #[test]
    fn translation_parallel_to_the_image_gives_the_expected_flow() {
        // Camera looking straight down from 0.5 m: world x = camera x, world y = −camera y.
        let world_from_camera = Pose::from_parts(
            Translation3::new(0.0, 0.0, 0.5),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), core::f32::consts::PI),
        );
        let labels = Gray16Image::from_fn(8, 6, |x, _| u16::from(x >= 4));
        let depth = DepthImage::from_fn(8, 6, |_, _| 0.5);
        let before = [ObjectPose {
            label: 1,
            world_from_object: Pose::identity(),
        }];
        let after = [ObjectPose {
            label: 1,
            world_from_object: Pose::translation(0.002, 0.001, 0.0),
        }];
        let flow =
            ground_truth_flow(&k(), &world_from_camera, &labels, &depth, &before, &after).unwrap();
        for y in 0..6 {
            for x in 0..8 {
                let f = flow.get(x, y).unwrap();
                let want = if x >= 4 { [2.0, -1.0] } else { [0.0, 0.0] };
                assert!(
                    (f[0] - want[0]).abs() < 1e-3 && (f[1] - want[1]).abs() < 1e-3,
                    "{f:?}"
                );
            }
        }
        // No motion, no flow; a label without a pose is an error.
        let still = ground_truth_flow(&k(), &world_from_camera, &labels, &depth, &before, &before);
        assert!(still.unwrap().as_slice().iter().all(|f| f == &[0.0, 0.0]));
        let missing = ground_truth_flow(&k(), &world_from_camera, &labels, &depth, &before, &[]);
        assert!(matches!(missing, Err(SimError::UnknownLabel(1))));
    }
}
