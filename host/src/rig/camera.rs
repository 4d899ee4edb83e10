//! RGB-D frames and where they come from: the [`Camera`] trait, and [`SceneReplay`], which
//! plays a recorded scene folder back as a camera.

use riseg_core::Intrinsics;

use crate::{
    eval::ceiling::CeilingFrame,
    io::image::{DepthImage, Gray16Image, RgbImage},
    io::scene::{ObjectPose, Scene},
    segment::{RgbdFrame, SegmentError},
};

/// One RGB-D frame, owned: colour, depth in metres (`<= 0` or not finite: no reading) and
/// the intrinsics that go with them.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraFrame {
    /// 8-bit colour.
    pub rgb: RgbImage,
    /// Depth along the optical axis, metres, same size as `rgb`.
    pub depth_m: DepthImage,
    /// Pinhole intrinsics, pixels.
    pub intrinsics: Intrinsics,
    /// Ground-truth instance labels (0 = background), when the source knows them: the
    /// simulator, or a recording with a `label/` folder. Only for scoring.
    pub truth: Option<Gray16Image>,
    /// Every object's true pose when the frame was taken (world frame, labels as in
    /// `truth`), when the source knows them: the simulator, or a recording with a
    /// `poses.json`. Only for scoring (the motion ceiling, [`crate::eval::ceiling`]).
    pub truth_poses: Option<Vec<ObjectPose>>,
}

impl CameraFrame {
    /// `(width, height)` of the colour image, pixels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        self.rgb.size()
    }

    /// This frame with its static segmentation (row-major, the frame's size) as the motion
    /// ceiling's input; `None` when the frame has no ground-truth labels or no poses.
    #[must_use]
    pub fn ceiling_frame<'a>(&'a self, static_labels: &'a [u16]) -> Option<CeilingFrame<'a>> {
        let (width, height) = self.size();
        Some(CeilingFrame {
            width,
            height,
            truth: self.truth.as_ref()?.as_slice(),
            static_labels,
            poses: self.truth_poses.as_deref()?,
        })
    }

    /// The colour and depth images as a static segmenter's input.
    ///
    /// # Errors
    /// [`SegmentError`] when the colour and depth images differ in size (or are empty).
    pub fn rgbd(&self) -> Result<RgbdFrame<'_>, SegmentError> {
        let (w, h) = self.size();
        RgbdFrame::new(w, h, self.rgb.as_slice(), self.depth_m.as_slice())
    }
}

/// Why a camera gave no frame.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct CameraError(pub String);

/// Something that captures aligned RGB-D frames: the simulator, a recorded scene, or a
/// real sensor.
pub trait Camera {
    /// The next frame, taken once the scene is still.
    ///
    /// # Errors
    /// [`CameraError`] when no frame can be had (device gone, recording exhausted).
    fn capture(&mut self) -> Result<CameraFrame, CameraError>;
}

/// A borrowed camera is a camera (wrappers such as
/// [`RecordingCamera`](crate::rig::record::RecordingCamera) can borrow the device).
impl<C: Camera + ?Sized> Camera for &mut C {
    fn capture(&mut self) -> Result<CameraFrame, CameraError> {
        (**self).capture()
    }
}

/// A recorded scene played back frame by frame (frame `t` is the scene after `t` pushes).
#[derive(Debug, Clone)]
pub struct SceneReplay<'a> {
    scene: &'a Scene,
    next: usize,
}

impl<'a> SceneReplay<'a> {
    /// Plays `scene` from frame 0.
    #[must_use]
    pub const fn new(scene: &'a Scene) -> Self {
        Self { scene, next: 0 }
    }

    /// Frame `t` with depth converted to metres by the scene's depth unit, and the
    /// scene's ground-truth labels and poses of frame `t` when it has them.
    #[must_use]
    pub fn frame(scene: &Scene, t: usize) -> Option<CameraFrame> {
        let rgb = scene.rgb.get(t)?.clone();
        let depth_m = scene.depth.get(t)?.map(|&d| scene.camera.depth_m(d));
        Some(CameraFrame {
            rgb,
            depth_m,
            intrinsics: scene.camera.intrinsics(),
            truth: scene.labels.as_ref().and_then(|l| l.get(t)).cloned(),
            truth_poses: scene.poses.as_ref().and_then(|p| p.get(t)).cloned(),
        })
    }
}

impl Camera for SceneReplay<'_> {
    fn capture(&mut self) -> Result<CameraFrame, CameraError> {
        let frame = Self::frame(self.scene, self.next).ok_or_else(|| {
            CameraError(format!(
                "the recording has {} frames; all were played",
                self.scene.frames()
            ))
        })?;
        self.next += 1;
        Ok(frame)
    }
}
