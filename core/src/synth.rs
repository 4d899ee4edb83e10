//! Exact synthetic scenes: flat box tops over a table, each moved by a known rigid motion.
//!
//! For tests, benchmarks and on-device self-checks, where the truth must be known exactly.
//! A scene is rendered by casting one ray per pixel against the box tops (oriented
//! rectangles) and a fronto-parallel table; the forward flow is exact: each pixel's 3-D
//! point is moved by its box's motion and projected. Nothing here allocates: images are
//! written into caller slices of `width·height` elements.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

use crate::{
    Error, Intrinsics, Pose,
    error::{Buffer, check_len},
    image::valid_depth,
    math::Real,
};

/// One box top: a rectangle in the box frame's x-y plane, centred on its origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SynthBox {
    /// Pose of the top face at `t`, camera frame (z of the frame = face normal).
    pub camera_from_box: Pose,
    /// Half sizes of the face along the box's x and y axes, metres.
    pub half_extent_m: [Real; 2],
    /// Motion from `t` to `t+1` in the camera frame: `p_t1 = motion · p_t`.
    pub motion: Pose,
    /// Instance label (non-zero).
    pub label: u16,
}

/// Boxes over a fronto-parallel table (label 0, never moves).
#[derive(Debug, Clone, Copy)]
pub struct SynthScene<'a> {
    /// The boxes.
    pub boxes: &'a [SynthBox],
    /// Depth of the table, metres.
    pub table_depth_m: Real,
    /// Camera intrinsics.
    pub intrinsics: Intrinsics,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
}

/// The synthetic scenes' camera: a D415's 615 px focal length at 640 px wide, scaled to
/// `width`, with the principal point at the image centre.
///
/// # Errors
/// [`Error::BadConfig`] for a width too small for a focal length (see
/// [`Intrinsics::check`]).
pub fn d415_like_camera(width: usize, height: usize) -> Result<Intrinsics, Error> {
    let f = 615.0 * width as Real / 640.0;
    Intrinsics::new(
        f,
        f,
        (width as Real - 1.0) / 2.0,
        (height as Real - 1.0) / 2.0,
    )
}

/// Five touching box tops 60 cm from the camera over a table at 66 cm: the first stays,
/// the others slide or turn a little (up to 1.2 cm, 8°), as after a 2 cm push. Labels 1
/// to 5 from left to right. The one step the benchmarks, the determinism digests and the
/// bare-metal example all run.
#[derive(Debug, Clone, Copy)]
pub struct TouchingBoxes {
    /// The boxes, each with its motion.
    pub boxes: [SynthBox; 5],
    /// The camera ([`d415_like_camera`]).
    pub intrinsics: Intrinsics,
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
}

impl TouchingBoxes {
    /// The scene at `width × height`.
    ///
    /// # Errors
    /// As [`d415_like_camera`].
    pub fn new(width: usize, height: usize) -> Result<Self, Error> {
        let intrinsics = d415_like_camera(width, height)?;
        let facing_camera =
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), core::f32::consts::PI);
        // (dx, dy, turn) of each box, metres and radians.
        let motions: [(Real, Real, Real); 5] = [
            (0.0, 0.0, 0.0),
            (0.0, 0.012, 0.0),
            (0.0, 0.0, 8f32.to_radians()),
            (0.006, -0.004, -5f32.to_radians()),
            (0.0, 0.0, 0.0),
        ];
        let mut label = 0u16;
        let boxes = motions.map(|(dx, dy, angle)| {
            let i = Real::from(label);
            label += 1;
            let centre = Vector3::new((i - 2.0) * 0.07, 0.0, 0.6 - 0.004 * i);
            let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle);
            let spin = Isometry3::from_parts(Translation3::from(centre - turn * centre), turn);
            SynthBox {
                camera_from_box: Isometry3::from_parts(Translation3::from(centre), facing_camera),
                half_extent_m: [0.035, 0.05],
                motion: Translation3::new(dx, dy, 0.0) * spin,
                label,
            }
        });
        Ok(Self {
            boxes,
            intrinsics,
            width,
            height,
        })
    }

    /// The scene to render.
    #[must_use]
    pub const fn scene(&self) -> SynthScene<'_> {
        SynthScene {
            boxes: &self.boxes,
            table_depth_m: 0.66,
            intrinsics: self.intrinsics,
            width: self.width,
            height: self.height,
        }
    }
}

/// Which moment to render.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Moment {
    /// Before the motion.
    Before,
    /// After every box moved by its motion.
    After,
}

impl SynthScene<'_> {
    fn check(&self, len: usize) -> Result<usize, Error> {
        self.intrinsics.check()?;
        let n = self
            .width
            .checked_mul(self.height)
            .ok_or(Error::BadImageLayout)?;
        check_len(Buffer::Pixels, n, len)?;
        Ok(n)
    }

    /// Nearest hit along the ray through pixel `(u, v)`: `(depth_m, label, box index)`.
    fn cast(&self, u: Real, v: Real, moment: Moment) -> (Real, u16, Option<usize>) {
        let k = &self.intrinsics;
        let dir = Vector3::new((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
        let mut best = (self.table_depth_m, 0, None);
        for (i, b) in self.boxes.iter().enumerate() {
            let pose = match moment {
                Moment::Before => b.camera_from_box,
                Moment::After => b.motion * b.camera_from_box,
            };
            let normal = pose.rotation * Vector3::z();
            let centre = pose.translation.vector;
            let denom = dir.dot(&normal);
            if denom.abs() < 1e-6 {
                continue;
            }
            let z = centre.dot(&normal) / denom;
            if !(z > 0.0 && z < best.0) {
                continue;
            }
            let local = pose.inverse_transform_vector(&(dir * z - centre));
            if local.x.abs() <= b.half_extent_m[0] && local.y.abs() <= b.half_extent_m[1] {
                best = (z, b.label, Some(i));
            }
        }
        best
    }

    /// Renders depth (metres) and labels at `moment` into row-major slices.
    ///
    /// # Errors
    /// [`Error::BufferTooSmall`] if a slice has fewer than `width·height` elements;
    /// errors of [`Intrinsics::check`].
    pub fn render(
        &self,
        moment: Moment,
        depth_m: &mut [f32],
        labels: &mut [u16],
    ) -> Result<(), Error> {
        let n = self.check(depth_m.len().min(labels.len()))?;
        let pixels = depth_m.iter_mut().zip(labels.iter_mut()).take(n);
        for (i, (z, l)) in pixels.enumerate() {
            let (u, v) = ((i % self.width) as Real, (i / self.width) as Real);
            (*z, *l, _) = self.cast(u, v, moment);
        }
        Ok(())
    }

    /// The exact forward flow from [`Moment::Before`] to [`Moment::After`], `[dx, dy]`
    /// per pixel: the point seen at each pixel, moved by its box's motion, projected.
    ///
    /// # Errors
    /// As [`SynthScene::render`].
    pub fn flow(&self, flow: &mut [[f32; 2]]) -> Result<(), Error> {
        let n = self.check(flow.len())?;
        let k = &self.intrinsics;
        for (i, f) in flow.iter_mut().take(n).enumerate() {
            let (u, v) = ((i % self.width) as Real, (i / self.width) as Real);
            *f = [0.0, 0.0];
            let (z, _, Some(b)) = self.cast(u, v, Moment::Before) else {
                continue;
            };
            let Some(motion) = self.boxes.get(b).map(|b| b.motion) else {
                continue;
            };
            let moved: Point3<Real> = motion * k.back_project(u, v, z);
            if let (Some(_), Some(px)) = (valid_depth(z), k.project(&moved)) {
                *f = [px.x - u, px.y - v];
            }
        }
        Ok(())
    }
}

/// Owned buffers of a rendered scene, for the crate's unit tests.
#[cfg(test)]
pub(crate) mod fixture {
    use std::{vec, vec::Vec};

    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

    use super::{Moment, SynthBox, SynthScene, d415_like_camera};
    use crate::{Intrinsics, Pose, math::Real};

    pub(crate) struct Rendered {
        pub width: usize,
        pub height: usize,
        pub intrinsics: Intrinsics,
        pub depth_t: Vec<f32>,
        pub depth_t1: Vec<f32>,
        pub labels_t: Vec<u16>,
        pub labels_t1: Vec<u16>,
        pub flow: Vec<[f32; 2]>,
    }

    /// A box top at `(x, y)` metres from the optical axis, `z` deep, facing the camera.
    pub(crate) fn box_at(x: Real, y: Real, z: Real, half: [Real; 2], label: u16) -> SynthBox {
        SynthBox {
            camera_from_box: Isometry3::from_parts(
                Translation3::new(x, y, z),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), core::f32::consts::PI),
            ),
            half_extent_m: half,
            motion: Pose::identity(),
            label,
        }
    }

    /// Rotation by `angle_rad` about the camera-frame axis through `centre` (axis = view z).
    pub(crate) fn spin_about(centre: Vector3<Real>, angle_rad: Real) -> Pose {
        let r = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), angle_rad);
        Isometry3::from_parts(Translation3::from(centre - r * centre), r)
    }

    pub(crate) fn render(boxes: &[SynthBox], width: usize, height: usize) -> Rendered {
        let intrinsics = d415_like_camera(width, height).unwrap();
        let scene = SynthScene {
            boxes,
            table_depth_m: 0.65,
            intrinsics,
            width,
            height,
        };
        let n = width * height;
        let mut r = Rendered {
            width,
            height,
            intrinsics,
            depth_t: vec![0.0; n],
            depth_t1: vec![0.0; n],
            labels_t: vec![0; n],
            labels_t1: vec![0; n],
            flow: vec![[0.0; 2]; n],
        };
        scene
            .render(Moment::Before, &mut r.depth_t, &mut r.labels_t)
            .unwrap();
        scene
            .render(Moment::After, &mut r.depth_t1, &mut r.labels_t1)
            .unwrap();
        scene.flow(&mut r.flow).unwrap();
        r
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Translation3;

    use super::fixture::{box_at, render};
    use super::*;

    #[test]
    fn flow_carries_each_point_to_where_the_box_is_rendered_after() {
        let mut b = box_at(0.0, 0.0, 0.6, [0.03, 0.02], 1);
        b.motion = Translation3::new(0.01, 0.0, 0.0).into();
        let r = render(&[b], 160, 120);
        // 1 cm at 0.6 m with f = 153.75 is 2.56 px.
        let centre = 60 * 160 + 80;
        assert_eq!(r.labels_t[centre], 1);
        assert!((r.flow[centre][0] - 0.01 * 153.75 / 0.6).abs() < 1e-3);
        assert_eq!(r.flow[0], [0.0, 0.0]);
        let u1 = (80.0 + r.flow[centre][0]).round() as usize;
        assert_eq!(r.labels_t1[60 * 160 + u1], 1);
        assert!((r.depth_t1[60 * 160 + u1] - 0.6).abs() < 1e-5);
    }

    #[test]
    fn short_buffers_are_errors() {
        let r = render(&[], 8, 8);
        let scene = SynthScene {
            boxes: &[],
            table_depth_m: 0.6,
            intrinsics: r.intrinsics,
            width: 8,
            height: 8,
        };
        let mut z = [0.0; 63];
        let mut l = [0; 64];
        assert!(matches!(
            scene.render(Moment::Before, &mut z, &mut l),
            Err(Error::BufferTooSmall { .. })
        ));
    }
}
