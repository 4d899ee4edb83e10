//! Recording a live run as a scene folder that `riseg run` replays.
//!
//! # Contract
//!
//! [`RecordingCamera`] wraps any [`Camera`]. Each captured frame's depth is quantised to
//! the scene format's depth unit ([`DEPTH_UNIT_M`], a D415's native 1 mm) and converted
//! back exactly as a replay converts it ([`SceneCamera::depth_m`]); the loop is handed that
//! converted frame, and the recording keeps its colour, raw depth and (when the source
//! knows them) ground-truth labels and poses. So the loop sees exactly what a replay of the
//! recording gives, and a replay reproduces the run's masks bit for bit.
//!
//! [`RecordingCamera::scene`] returns what was recorded so far as a [`Scene`], with the
//! pushes made between the frames (FindAction's, camera frame); a push decided after the
//! last frame (the run stopped before the next capture) is not in it, as a scene has one
//! push fewer than frames. Every frame must have the first frame's size and intrinsics.

use riseg_core::{Intrinsics, action::Push};

use crate::{
    io::image::Gray16Image,
    io::scene::{ObjectPose, PushAction, Scene, SceneCamera},
    rig::camera::{Camera, CameraError, CameraFrame},
};

/// Metres per raw depth unit in a recording: 1 mm, the D415's default depth unit.
pub const DEPTH_UNIT_M: f32 = 0.001;

/// A camera whose frames are recorded (module docs).
#[derive(Debug)]
pub struct RecordingCamera<C> {
    inner: C,
    camera: Option<SceneCamera>,
    rgb: Vec<crate::io::image::RgbImage>,
    depth: Vec<Gray16Image>,
    labels: Vec<Option<Gray16Image>>,
    poses: Vec<Option<Vec<ObjectPose>>>,
}

impl<C: Camera> RecordingCamera<C> {
    /// Records the frames of `inner`.
    #[must_use]
    pub const fn new(inner: C) -> Self {
        Self {
            inner,
            camera: None,
            rgb: Vec::new(),
            depth: Vec::new(),
            labels: Vec::new(),
            poses: Vec::new(),
        }
    }

    /// Frames recorded so far.
    #[must_use]
    pub fn frames(&self) -> usize {
        self.rgb.len()
    }

    /// The recording as a scene (module docs): `pushes[t]` is the push made after frame `t`;
    /// pushes beyond the last frame are left out. `None` before the first frame.
    #[must_use]
    pub fn scene(&self, pushes: &[Push]) -> Option<Scene> {
        let camera = self.camera?;
        let actions = pushes
            .iter()
            .take(self.frames().saturating_sub(1))
            .zip(1..)
            .map(|(p, push)| PushAction {
                push,
                start_px: p.start_px,
                start_cam_m: p.start_cam_m.coords.into(),
                direction_cam: p.direction_cam.into(),
                length_m: p.length_m,
            })
            .collect();
        Some(Scene {
            camera,
            rgb: self.rgb.clone(),
            depth: self.depth.clone(),
            labels: self.labels.iter().cloned().collect(),
            flow: None,
            actions,
            poses: self.poses.iter().cloned().collect(),
        })
    }

    fn scene_camera(frame: &CameraFrame) -> SceneCamera {
        let (width, height) = frame.size();
        let Intrinsics { fx, fy, cx, cy } = frame.intrinsics;
        SceneCamera {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            depth_unit_m: DEPTH_UNIT_M,
        }
    }
}

/// The raw depth value of `depth_m` in [`DEPTH_UNIT_M`] units: 0 for no reading, 65535
/// (no reading on replay) beyond the 16-bit range.
fn quantise(depth_m: f32) -> u16 {
    if !(depth_m.is_finite() && depth_m > 0.0) {
        return 0;
    }
    let raw = (depth_m / DEPTH_UNIT_M).round();
    if raw >= f32::from(u16::MAX) {
        u16::MAX
    } else {
        raw as u16
    }
}

impl<C: Camera> Camera for RecordingCamera<C> {
    fn capture(&mut self) -> Result<CameraFrame, CameraError> {
        let mut frame = self.inner.capture()?;
        let camera = Self::scene_camera(&frame);
        match self.camera {
            None => self.camera = Some(camera),
            Some(first) if first != camera => {
                return Err(CameraError(format!(
                    "frame {} changed size or intrinsics ({camera:?}; the first frame had \
                     {first:?}); a recording needs one",
                    self.frames()
                )));
            }
            Some(_) => {}
        }
        let raw = frame.depth_m.map(|&d| quantise(d));
        frame.depth_m = raw.map(|&r| camera.depth_m(r));
        self.rgb.push(frame.rgb.clone());
        self.depth.push(raw);
        self.labels.push(frame.truth.clone());
        self.poses.push(frame.truth_poses.clone());
        Ok(frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::image::{DepthImage, RgbImage};

    struct Fixed(usize);

    impl Camera for Fixed {
        fn capture(&mut self) -> Result<CameraFrame, CameraError> {
            self.0 += 1;
            let fx = if self.0 == 3 { 600.0 } else { 615.0 };
            Ok(CameraFrame {
                rgb: RgbImage::from_vec(2, 1, vec![[1, 2, 3], [4, 5, 6]]).unwrap(),
                depth_m: DepthImage::from_vec(2, 1, vec![0.6004, f32::NAN]).unwrap(),
                intrinsics: Intrinsics {
                    fx,
                    fy: 615.0,
                    cx: 0.5,
                    cy: 0.0,
                },
                truth: None,
                truth_poses: None,
            })
        }
    }

    #[test]
    fn the_loop_sees_the_depth_a_replay_will_read_and_intrinsic_changes_are_refused() {
        let mut cam = RecordingCamera::new(Fixed(0));
        assert!(cam.scene(&[]).is_none());
        let f = cam.capture().unwrap();
        assert_eq!(f.depth_m.as_slice()[0], 600.0 * DEPTH_UNIT_M);
        assert_eq!(f.depth_m.as_slice()[1], 0.0);
        cam.capture().unwrap();
        let err = cam.capture().unwrap_err();
        assert!(err.0.contains("frame 2 changed"), "{err}");
        let scene = cam.scene(&[]).unwrap();
        assert_eq!(scene.frames(), 2);
        assert_eq!(scene.depth[0].as_slice(), &[600, 0]);
        assert!(scene.labels.is_none() && scene.poses.is_none());
        assert_eq!(quantise(70.0), u16::MAX);
    }
}
