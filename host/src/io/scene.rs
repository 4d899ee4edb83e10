//! The scene folder: one recorded or simulated scene, its frames before and after each
//! push, optional ground truth, and the pushes.
//!
//! ```text
//! DATASET/
//!   scene_000/
//!     scene_camera.json   {"width": 640, "height": 480, "fx": 615.0, "fy": 615.0,
//!                          "cx": 319.5, "cy": 239.5, "depth_unit_m": 0.001}
//!     rgb/000000.png      8-bit RGB; frame t = the scene after t pushes (000000 = initial)
//!     depth/000000.png    16-bit, depth_unit_m units (millimetres), 0 = no reading,
//!                          65535 = saturated (no reading either)
//!     label/000000.png    16-bit instance ids, 0 = table/background (optional: ground truth)
//!     flow/000000.flo     forward flow from frame t to t+1 (optional: ground truth), Middlebury
//!     actions.json        [{"push": 1, "start_px": [u, v], "start_cam_m": [x, y, z],
//!                           "direction_cam": [dx, dy, dz], "length_m": 0.02}, ...]
//!     poses.json          {"frames": [[{"label": 1, "translation_m": [x, y, z],
//!                           "rotation_xyzw": [qx, qy, qz, qw]}, ...], ...]} (optional:
//!                          ground truth; every object's pose in the world = table frame,
//!                          z up, one list per frame)
//!   scene_001/ ...
//! ```
//!
//! Contract of [`Scene::read`] (the folder may come from any tool, not only riseg), and of
//! [`Scene::read_in`], the same reader over files held in memory ([`crate::io::files`]):
//! - `scene_camera.json` and `rgb/` are required; there must be at least one frame.
//!   Frames are named with six digits from `000000` without gaps; other files are ignored.
//!   A JSON file with an unknown or a missing field is an error naming the field.
//! - The camera is a camera: at most [`MAX_IMAGE_PIXELS`] pixels, focal lengths from 1/20 to
//!   100 times the longer side, the principal point on the image, a depth unit in (0, 1] m.
//!   A PNG is checked against the camera's size from its header, before it is decoded.
//! - `depth/` holds exactly as many frames as `rgb/`, all 16-bit (8-bit depth is refused);
//!   `label/` is optional, and when present holds as many frames as `rgb/` (8- or 16-bit);
//!   `flow/` is optional, and when present holds one `.flo` per push (frames − 1).
//! - `actions.json` holds one entry per push, numbered `1, 2, …` in order. It may be absent
//!   only when the scene has a single frame (no pushes). Each push has a non-zero direction
//!   and a length in (0, 1] m.
//! - [`Scene::read_frames`] reads only `scene_camera.json`, `rgb/` and `depth/`, for
//!   replaying (`riseg run`): files it does not use cannot stop it.
//! - `poses.json` is optional; when present it holds one list per frame (`frames[t]` = after
//!   `t` pushes) of object poses: labels from 1, each once per frame, finite numbers, and
//!   quaternions of norm within [`POSE_QUATERNION_TOLERANCE`] of 1 (normalised on reading
//!   unless already unit to `f32` precision, so a written file reads back bit for bit).
//! - Every image is the size `scene_camera.json` gives.
//! - Any violation is a [`SceneError`] whose message starts with the offending file or
//!   folder and says the problem.
//!
//! Contract of [`Scene::write`]: the scene is checked against the rules above first, then
//! written into a hidden temporary folder beside the destination, which is renamed to the
//! destination last, so a half-written scene never looks complete. An existing destination
//! is never overwritten.

use std::{
    fs, io,
    path::{Path, PathBuf},
};

use nalgebra::{Quaternion, Translation3, UnitQuaternion};
use riseg_core::{Intrinsics, Pose};
use serde::{Deserialize, Serialize};

use super::write_atomic;
use crate::io::files::{DiskFiles, Files};
use crate::io::image::{
    FlowImage, Gray16Image, Image, ImageIoError, MAX_IMAGE_PIXELS, RgbImage, read_flo_in,
    read_gray_widened_in, read_gray16_in, read_rgb8_in, write_flo, write_gray16, write_rgb8,
};

/// Intrinsics file name.
pub const CAMERA_FILE: &str = "scene_camera.json";
/// Pushes file name.
pub const ACTIONS_FILE: &str = "actions.json";
/// Ground-truth object poses file name.
pub const POSES_FILE: &str = "poses.json";
/// Largest difference of a `poses.json` quaternion's norm from 1.
pub const POSE_QUATERNION_TOLERANCE: f32 = 1e-3;
/// Colour frames folder.
pub const RGB_DIR: &str = "rgb";
/// Depth frames folder.
pub const DEPTH_DIR: &str = "depth";
/// Ground-truth instance labels folder.
pub const LABEL_DIR: &str = "label";
/// Ground-truth forward flow folder.
pub const FLOW_DIR: &str = "flow";
/// Heatmap folder of a static-segmentation folder (`riseg run --static-dir`, beside its
/// `label/`): 8-bit, 0-255, one per frame.
pub const HEAT_DIR: &str = "heat";

/// `scene_camera.json`: colour intrinsics (depth is aligned to colour) and the depth unit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneCamera {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// Focal length along x, pixels.
    pub fx: f32,
    /// Focal length along y, pixels.
    pub fy: f32,
    /// Principal point x, pixels (from the centre of the top-left pixel).
    pub cx: f32,
    /// Principal point y, pixels.
    pub cy: f32,
    /// Metres per depth-image unit (0.001: millimetres).
    pub depth_unit_m: f32,
}

impl SceneCamera {
    /// The pinhole intrinsics.
    #[must_use]
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics {
            fx: self.fx,
            fy: self.fy,
            cx: self.cx,
            cy: self.cy,
        }
    }

    /// Converts a depth-image value to metres. `0` (no return) and `65535` (saturated: the
    /// true depth is beyond what 16 bits hold) are no reading and become `0.0`.
    #[must_use]
    pub fn depth_m(&self, raw: u16) -> f32 {
        if raw == u16::MAX {
            0.0
        } else {
            f32::from(raw) * self.depth_unit_m
        }
    }

    /// Reads and checks a camera file (`scene_camera.json`), on its own: for tools that
    /// need one frame, not the whole scene.
    ///
    /// # Errors
    /// [`SceneError::Missing`], [`SceneError::Io`] or [`SceneError::Json`] naming `path`;
    /// [`SceneError::Invalid`] for an empty size, non-finite values, a non-positive focal
    /// length or depth unit.
    pub fn read(path: &Path) -> Result<Self, SceneError> {
        Self::read_in(&DiskFiles, path)
    }

    /// [`SceneCamera::read`] from `files`.
    ///
    /// # Errors
    /// As [`SceneCamera::read`].
    pub fn read_in(files: &impl Files, path: &Path) -> Result<Self, SceneError> {
        Self::from_json(path, &files.read(path).map_err(|e| io_error(path, e))?)
    }

    /// Parses and checks the contents of a camera file; `path` only names the file in
    /// errors. [`SceneCamera::read`] is this after reading the file.
    ///
    /// # Errors
    /// [`SceneError::Json`] or [`SceneError::Invalid`] as for [`SceneCamera::read`].
    pub fn from_json(path: &Path, bytes: &[u8]) -> Result<Self, SceneError> {
        let camera: Self = parse_json(path, bytes)?;
        match camera.problem() {
            Some(reason) => Err(invalid(path, reason)),
            None => Ok(camera),
        }
    }

    fn problem(&self) -> Option<String> {
        if self.width == 0 || self.height == 0 {
            return Some(format!(
                "image size {}x{} is empty",
                self.width, self.height
            ));
        }
        if ![self.fx, self.fy, self.cx, self.cy, self.depth_unit_m]
            .iter()
            .all(|v| v.is_finite())
        {
            return Some("a camera value is not finite".into());
        }
        if self.fx <= 0.0 || self.fy <= 0.0 {
            return Some(format!(
                "focal lengths must be positive (fx {}, fy {})",
                self.fx, self.fy
            ));
        }
        if self.depth_unit_m <= 0.0 || self.depth_unit_m > 1.0 {
            return Some(format!(
                "depth_unit_m must be in (0, 1] metres, found {}",
                self.depth_unit_m
            ));
        }
        if self.width.saturating_mul(self.height) > MAX_IMAGE_PIXELS {
            return Some(format!(
                "image size {}x{} is more than the {MAX_IMAGE_PIXELS} pixels riseg reads",
                self.width, self.height
            ));
        }
        // A horizontal field of view between about 1 and 170 degrees, and the principal
        // point on the image: anything else is a unit mistake (metres for pixels, a
        // normalised camera matrix), not a camera.
        let (w, h) = (self.width as f32, self.height as f32);
        let side = w.max(h);
        let fov_ok = |f: f32| f >= side / 20.0 && f <= 100.0 * side;
        if !fov_ok(self.fx) || !fov_ok(self.fy) {
            return Some(format!(
                "focal lengths fx {} and fy {} pixels do not fit a {}x{} camera \
                 (expected 1/20 to 100 times the longer side)",
                self.fx, self.fy, self.width, self.height
            ));
        }
        if !(0.0..=w).contains(&self.cx) || !(0.0..=h).contains(&self.cy) {
            return Some(format!(
                "principal point ({}, {}) lies off the {}x{} image",
                self.cx, self.cy, self.width, self.height
            ));
        }
        None
    }
}

/// One entry of `actions.json`: the push that turned frame `push − 1` into frame `push`.
///
/// Everything is in the colour camera's frame (x right, y down, z forward), so a scene
/// needs no hand-eye calibration to be read.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PushAction {
    /// Push number, from 1.
    pub push: u32,
    /// Where the push starts, in the image of frame `push − 1`, pixels `[u, v]`.
    pub start_px: [f32; 2],
    /// Where the push starts, camera frame, metres.
    pub start_cam_m: [f32; 3],
    /// Unit push direction, camera frame.
    pub direction_cam: [f32; 3],
    /// Push length, metres.
    pub length_m: f32,
}

/// A scene in memory: `frames()` frames, `frames() − 1` pushes.
///
/// `depth` holds raw depth-image values in [`SceneCamera::depth_unit_m`] units.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// Intrinsics and depth unit.
    pub camera: SceneCamera,
    /// Colour frames; frame `t` is the scene after `t` pushes.
    pub rgb: Vec<RgbImage>,
    /// Depth frames (raw units, 0 = no reading), one per colour frame.
    pub depth: Vec<Gray16Image>,
    /// Ground-truth instance labels (0 = table/background), one per frame, if known.
    pub labels: Option<Vec<Gray16Image>>,
    /// Ground-truth forward flow from frame `t` to `t + 1`, one per push, if known.
    pub flow: Option<Vec<FlowImage>>,
    /// The pushes, numbered from 1.
    pub actions: Vec<PushAction>,
    /// Ground-truth object poses, world (table) frame, one list per frame, if known.
    pub poses: Option<Vec<Vec<ObjectPose>>>,
}

/// Where one object is: its instance label and its body frame in the world (table) frame,
/// z up (the simulator's world frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjectPose {
    /// The object's instance label (as in the label images), from 1.
    pub label: u16,
    /// The object's body frame in the world frame, translation in metres.
    pub world_from_object: Pose,
}

/// One entry of `poses.json`.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PoseRecord {
    label: u16,
    translation_m: [f32; 3],
    rotation_xyzw: [f32; 4],
}

/// `poses.json`: `frames[t]` = the poses after `t` pushes.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PosesFile {
    frames: Vec<Vec<PoseRecord>>,
}

impl From<&ObjectPose> for PoseRecord {
    fn from(p: &ObjectPose) -> Self {
        let t = p.world_from_object.translation.vector;
        let q = p.world_from_object.rotation.coords;
        Self {
            label: p.label,
            translation_m: [t.x, t.y, t.z],
            rotation_xyzw: [q.x, q.y, q.z, q.w],
        }
    }
}

impl PoseRecord {
    /// The pose, or what is wrong with the record.
    fn pose(&self) -> Result<ObjectPose, String> {
        let [x, y, z, w] = self.rotation_xyzw;
        let finite = self
            .translation_m
            .iter()
            .chain(&self.rotation_xyzw)
            .all(|v| v.is_finite());
        if !finite {
            return Err(format!("object {} has a non-finite value", self.label));
        }
        let q = Quaternion::new(w, x, y, z);
        let norm = q.norm();
        if (norm - 1.0).abs() > POSE_QUATERNION_TOLERANCE {
            return Err(format!(
                "object {}: rotation_xyzw has norm {norm}, not 1",
                self.label
            ));
        }
        // Unit to f32 precision: kept as written, so written files read back exactly.
        let rotation = if (norm - 1.0).abs() <= 4.0 * f32::EPSILON {
            UnitQuaternion::new_unchecked(q)
        } else {
            UnitQuaternion::new_normalize(q)
        };
        let [tx, ty, tz] = self.translation_m;
        Ok(ObjectPose {
            label: self.label,
            world_from_object: Pose::from_parts(Translation3::new(tx, ty, tz), rotation),
        })
    }
}

/// What is wrong with a pose list of a `frames`-frame scene, if anything.
fn poses_problem(poses: &[Vec<ObjectPose>], frames: usize) -> Option<String> {
    if poses.len() != frames {
        return Some(format!(
            "{} frames of poses, expected {frames} (one per frame in rgb/)",
            poses.len()
        ));
    }
    for (t, frame) in poses.iter().enumerate() {
        for (i, p) in frame.iter().enumerate() {
            if p.label == 0 {
                return Some(format!("frame {t}: label 0 (objects are labelled from 1)"));
            }
            if frame[..i].iter().any(|q| q.label == p.label) {
                return Some(format!("frame {t}: object {} listed twice", p.label));
            }
            let iso = &p.world_from_object;
            let finite = iso
                .translation
                .vector
                .iter()
                .chain(iso.rotation.coords.iter())
                .all(|v| v.is_finite());
            if !finite {
                return Some(format!(
                    "frame {t}: object {} has a non-finite value",
                    p.label
                ));
            }
        }
    }
    None
}

/// Parses and checks the contents of `poses.json` of a `frames`-frame scene (the rules are
/// in the module docs); `path` only names the file in errors.
///
/// # Errors
/// [`SceneError::Json`] for malformed JSON, [`SceneError::Invalid`] for a rule broken.
pub fn poses_from_json(
    path: &Path,
    bytes: &[u8],
    frames: usize,
) -> Result<Vec<Vec<ObjectPose>>, SceneError> {
    let file: PosesFile = parse_json(path, bytes)?;
    let poses = file
        .frames
        .iter()
        .enumerate()
        .map(|(t, records)| {
            records
                .iter()
                .map(|r| {
                    r.pose()
                        .map_err(|why| invalid(path, format!("frame {t}: {why}")))
                })
                .collect::<Result<Vec<_>, _>>()
        })
        .collect::<Result<Vec<_>, _>>()?;
    match poses_problem(&poses, frames) {
        Some(reason) => Err(invalid(path, reason)),
        None => Ok(poses),
    }
}

/// Why a scene folder could not be read or written. The message starts with the file or
/// folder at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SceneError {
    /// An image file is missing, unreadable, corrupt, of the wrong format or size.
    #[error(transparent)]
    Image(#[from] ImageIoError),
    /// A required file or folder does not exist.
    #[error("{}: not found", path.display())]
    Missing {
        /// The missing file or folder.
        path: PathBuf,
    },
    /// The operating system refused an operation.
    #[error("{}: I/O error: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The OS error.
        source: io::Error,
    },
    /// A JSON file does not parse or does not have the expected fields.
    #[error("{}: malformed JSON: {source}", path.display())]
    Json {
        /// The JSON file.
        path: PathBuf,
        /// The parser's complaint (with line and column).
        source: serde_json::Error,
    },
    /// The content is well formed but breaks a rule of the layout (frame counts that
    /// disagree, gaps in frame numbers, bad camera values, misnumbered pushes).
    #[error("{}: {reason}", path.display())]
    Invalid {
        /// The file or folder at fault.
        path: PathBuf,
        /// Which rule it breaks.
        reason: String,
    },
    /// [`Scene::write`] refuses to replace an existing scene.
    #[error("{}: already exists; remove it or write elsewhere", path.display())]
    Exists {
        /// The destination.
        path: PathBuf,
    },
}

fn invalid(path: &Path, reason: impl Into<String>) -> SceneError {
    SceneError::Invalid {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

fn io_error(path: &Path, source: io::Error) -> SceneError {
    if source.kind() == io::ErrorKind::NotFound {
        SceneError::Missing {
            path: path.to_path_buf(),
        }
    } else {
        SceneError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// The file name of frame `t` with extension `ext` (`"png"`, `"flo"`).
#[must_use]
pub fn frame_file_name(t: usize, ext: &str) -> String {
    format!("{t:06}.{ext}")
}

/// The file of frame `t` in the sub-folder `sub` of the scene folder `dir`:
/// `dir/<sub>/NNNNNN.<ext>`.
#[must_use]
pub fn frame_file(dir: &Path, sub: &str, t: usize, ext: &str) -> PathBuf {
    dir.join(sub).join(frame_file_name(t, ext))
}

/// The colour and depth files of frame `t` in the scene folder `dir`:
/// `dir/rgb/NNNNNN.png` and `dir/depth/NNNNNN.png`.
#[must_use]
pub fn frame_paths(dir: &Path, t: usize) -> (PathBuf, PathBuf) {
    (
        frame_file(dir, RGB_DIR, t, "png"),
        frame_file(dir, DEPTH_DIR, t, "png"),
    )
}

/// Frame numbers of the `NNNNNN.ext` files in `dir`, sorted; `None` if `dir` does not exist.
fn frame_numbers(
    files: &impl Files,
    dir: &Path,
    ext: &str,
) -> Result<Option<Vec<usize>>, SceneError> {
    let names = match files.list(dir) {
        Ok(names) => names,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(io_error(dir, e)),
    };
    let mut numbers = Vec::new();
    for name in names {
        let Some(name) = name.to_str() else { continue };
        let Some(stem) = name
            .strip_suffix(ext)
            .and_then(|s| s.strip_suffix('.'))
            .filter(|s| s.len() == 6 && s.bytes().all(|b| b.is_ascii_digit()))
        else {
            continue;
        };
        if let Ok(t) = stem.parse::<usize>() {
            numbers.push(t);
        }
    }
    numbers.sort_unstable();
    Ok(Some(numbers))
}

/// Checks that `dir` holds exactly frames `0..count` (`expected = Some((count, why))`), or
/// (`None`) at least one frame without gaps; returns the count. A missing frame is reported
/// by its file name, a surplus frame likewise.
fn check_frames(
    dir: &Path,
    ext: &str,
    numbers: &[usize],
    expected: Option<(usize, &str)>,
) -> Result<usize, SceneError> {
    let count = match expected {
        Some((count, _)) => count,
        None if numbers.is_empty() => {
            return Err(invalid(dir, format!("no .{ext} frames")));
        }
        None => numbers.len(),
    };
    // `numbers` is sorted: the first index that differs from its position is a gap.
    if let Some(t) = (0..count).find(|&t| numbers.get(t) != Some(&t)) {
        return Err(SceneError::Missing {
            path: dir.join(frame_file_name(t, ext)),
        });
    }
    if let (Some(&extra), Some((_, why))) = (numbers.get(count), expected) {
        return Err(invalid(
            &dir.join(frame_file_name(extra, ext)),
            format!("one frame too many: expected {count} ({why})"),
        ));
    }
    Ok(count)
}

fn parse_json<T: serde::de::DeserializeOwned>(path: &Path, bytes: &[u8]) -> Result<T, SceneError> {
    serde_json::from_slice(bytes).map_err(|source| SceneError::Json {
        path: path.to_path_buf(),
        source,
    })
}

fn read_sized<T>(
    files: &impl Files,
    path: &Path,
    camera: &SceneCamera,
    read: impl Fn(&Path) -> Result<Image<T>, ImageIoError>,
) -> Result<Image<T>, SceneError> {
    Ok(crate::io::image::read_sized_in(
        files,
        path,
        camera.width,
        camera.height,
        read,
    )?)
}

/// `actions.json` of the scene folder `dir` in `files`, checked against its `frames`
/// frames; a scene of one frame may lack it.
fn read_actions_in(
    files: &impl Files,
    dir: &Path,
    frames: usize,
) -> Result<Vec<PushAction>, SceneError> {
    let path = dir.join(ACTIONS_FILE);
    if frames == 1 && !files.is_file(&path) {
        return Ok(Vec::new());
    }
    let bytes = files.read(&path).map_err(|e| io_error(&path, e))?;
    actions_from_json(&path, &bytes, frames - 1)
}

/// Parses and checks the contents of `actions.json` of a scene with `pushes` pushes (the
/// rules are in the module docs); `path` only names the file in errors.
///
/// # Errors
/// [`SceneError::Json`] for malformed JSON, [`SceneError::Invalid`] for a rule broken.
pub fn actions_from_json(
    path: &Path,
    bytes: &[u8],
    pushes: usize,
) -> Result<Vec<PushAction>, SceneError> {
    let actions: Vec<PushAction> = parse_json(path, bytes)?;
    check_actions(path, &actions, pushes)?;
    Ok(actions)
}

fn check_actions(path: &Path, actions: &[PushAction], pushes: usize) -> Result<(), SceneError> {
    if actions.len() != pushes {
        return Err(invalid(
            path,
            format!(
                "{} pushes listed, expected {pushes} (one per frame after the first)",
                actions.len()
            ),
        ));
    }
    for (i, a) in actions.iter().enumerate() {
        if a.push as usize != i + 1 {
            return Err(invalid(
                path,
                format!("entry {} has \"push\": {}, expected {}", i, a.push, i + 1),
            ));
        }
        let finite = a
            .start_px
            .iter()
            .chain(&a.start_cam_m)
            .chain(&a.direction_cam)
            .chain(core::iter::once(&a.length_m))
            .all(|v| v.is_finite());
        if !finite {
            return Err(invalid(
                path,
                format!("push {} has a non-finite value", a.push),
            ));
        }
        if !(a.length_m > 0.0 && a.length_m <= 1.0) {
            return Err(invalid(
                path,
                format!(
                    "push {} has \"length_m\": {}, expected more than 0 and at most 1 metre",
                    a.push, a.length_m
                ),
            ));
        }
        let [dx, dy, dz] = a.direction_cam;
        if libm::sqrtf(dx * dx + dy * dy + dz * dz) < 1e-6 {
            return Err(invalid(
                path,
                format!("push {} has a zero \"direction_cam\"", a.push),
            ));
        }
    }
    Ok(())
}

impl Scene {
    /// Number of frames (pushes + 1).
    #[must_use]
    pub fn frames(&self) -> usize {
        self.rgb.len()
    }

    /// Reads and checks a scene folder (see the module docs for the rules).
    ///
    /// # Errors
    /// A [`SceneError`] naming the first file or folder that breaks a rule.
    pub fn read(dir: &Path) -> Result<Self, SceneError> {
        Self::read_parts(&DiskFiles, dir, true)
    }

    /// [`Scene::read`] of the folder `dir` in `files`: the same rules and messages, for a
    /// scene held in memory ([`crate::io::files::MemoryFiles`]).
    ///
    /// # Errors
    /// As [`Scene::read`].
    pub fn read_in(files: &impl Files, dir: &Path) -> Result<Self, SceneError> {
        Self::read_parts(files, dir, true)
    }

    /// Reads and checks only what replaying a scene needs: the camera, colour and depth.
    /// `label/`, `flow/`, `actions.json` and `poses.json` are neither read nor checked
    /// (`labels`, `flow` and `poses` are `None`, `actions` empty), so a problem in a file
    /// the caller does not use cannot stop it.
    ///
    /// # Errors
    /// As [`Scene::read`], for those files.
    pub fn read_frames(dir: &Path) -> Result<Self, SceneError> {
        Self::read_parts(&DiskFiles, dir, false)
    }

    /// Reads and checks `actions.json` of the scene folder `dir` into `actions`, as
    /// [`Scene::read`] does, for a scene [`Scene::read_frames`] read.
    ///
    /// # Errors
    /// As [`Scene::read`], for that file.
    pub fn read_actions(&mut self, dir: &Path) -> Result<(), SceneError> {
        self.actions = read_actions_in(&DiskFiles, dir, self.frames())?;
        Ok(())
    }

    fn read_parts(files: &impl Files, dir: &Path, everything: bool) -> Result<Self, SceneError> {
        if !files.is_dir(dir) {
            return Err(SceneError::Missing {
                path: dir.to_path_buf(),
            });
        }
        let camera = SceneCamera::read_in(files, &dir.join(CAMERA_FILE))?;

        let rgb_dir = dir.join(RGB_DIR);
        let rgb_numbers =
            frame_numbers(files, &rgb_dir, "png")?.ok_or_else(|| SceneError::Missing {
                path: rgb_dir.clone(),
            })?;
        let n = check_frames(&rgb_dir, "png", &rgb_numbers, None)?;
        let per_frame = Some((n, "one per frame in rgb/"));

        let depth_dir = dir.join(DEPTH_DIR);
        let depth_numbers =
            frame_numbers(files, &depth_dir, "png")?.ok_or_else(|| SceneError::Missing {
                path: depth_dir.clone(),
            })?;
        check_frames(&depth_dir, "png", &depth_numbers, per_frame)?;

        let label_dir = dir.join(LABEL_DIR);
        let has_labels = match frame_numbers(files, &label_dir, "png")?.filter(|_| everything) {
            Some(numbers) => {
                check_frames(&label_dir, "png", &numbers, per_frame)?;
                true
            }
            None => false,
        };
        let flow_dir = dir.join(FLOW_DIR);
        let has_flow = match frame_numbers(files, &flow_dir, "flo")?.filter(|_| everything) {
            Some(numbers) => {
                check_frames(&flow_dir, "flo", &numbers, Some((n - 1, "one per push")))?;
                true
            }
            None => false,
        };

        let actions = if everything {
            read_actions_in(files, dir, n)?
        } else {
            Vec::new()
        };

        let poses_path = dir.join(POSES_FILE);
        let poses = if everything && files.is_file(&poses_path) {
            let bytes = files
                .read(&poses_path)
                .map_err(|e| io_error(&poses_path, e))?;
            Some(poses_from_json(&poses_path, &bytes, n)?)
        } else {
            None
        };

        let frame = |sub: &Path, t: usize, ext: &str| sub.join(frame_file_name(t, ext));
        let rgb = (0..n)
            .map(|t| {
                read_sized(files, &frame(&rgb_dir, t, "png"), &camera, |p| {
                    read_rgb8_in(files, p)
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let depth = (0..n)
            .map(|t| {
                read_sized(files, &frame(&depth_dir, t, "png"), &camera, |p| {
                    read_gray16_in(files, p)
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let labels = if has_labels {
            Some(
                (0..n)
                    .map(|t| {
                        read_sized(files, &frame(&label_dir, t, "png"), &camera, |p| {
                            read_gray_widened_in(files, p)
                        })
                    })
                    .collect::<Result<Vec<_>, _>>()?,
            )
        } else {
            None
        };
        let flow = if has_flow {
            Some(
                (0..n - 1)
                    .map(|t| {
                        read_sized(files, &frame(&flow_dir, t, "flo"), &camera, |p| {
                            read_flo_in(files, p)
                        })
                    })
                    .collect::<Result<Vec<_>, _>>()?,
            )
        } else {
            None
        };
        Ok(Self {
            camera,
            rgb,
            depth,
            labels,
            flow,
            actions,
            poses,
        })
    }

    /// Checks the in-memory scene against the layout's rules; `dir` is only used to name
    /// the error.
    fn check(&self, dir: &Path) -> Result<(), SceneError> {
        if let Some(reason) = self.camera.problem() {
            return Err(invalid(&dir.join(CAMERA_FILE), reason));
        }
        let n = self.rgb.len();
        if n == 0 {
            return Err(invalid(&dir.join(RGB_DIR), "no frames"));
        }
        let (w, h) = (self.camera.width, self.camera.height);
        let sizes_ok = |sub: &str, count: usize, dims: &mut dyn Iterator<Item = (usize, usize)>| {
            let path = dir.join(sub);
            let dims: Vec<(usize, usize)> = dims.collect();
            if dims.len() != count {
                return Err(invalid(
                    &path,
                    format!("{} frames, expected {count}", dims.len()),
                ));
            }
            match dims.iter().position(|&d| d != (w, h)) {
                Some(t) => Err(invalid(
                    &path,
                    format!(
                        "frame {t} is {}x{}, the camera is {w}x{h}",
                        dims[t].0, dims[t].1
                    ),
                )),
                None => Ok(()),
            }
        };
        sizes_ok(
            RGB_DIR,
            n,
            &mut self.rgb.iter().map(|i| (i.width(), i.height())),
        )?;
        sizes_ok(
            DEPTH_DIR,
            n,
            &mut self.depth.iter().map(|i| (i.width(), i.height())),
        )?;
        if let Some(labels) = &self.labels {
            sizes_ok(
                LABEL_DIR,
                n,
                &mut labels.iter().map(|i| (i.width(), i.height())),
            )?;
        }
        if let Some(flow) = &self.flow {
            sizes_ok(
                FLOW_DIR,
                n - 1,
                &mut flow.iter().map(|i| (i.width(), i.height())),
            )?;
        }
        check_actions(&dir.join(ACTIONS_FILE), &self.actions, n - 1)?;
        match self.poses.as_deref().and_then(|p| poses_problem(p, n)) {
            Some(reason) => Err(invalid(&dir.join(POSES_FILE), reason)),
            None => Ok(()),
        }
    }

    /// Writes the scene to the folder `dir`, which must not exist yet; its parent must.
    ///
    /// # Errors
    /// [`SceneError::Exists`] if `dir` exists; [`SceneError::Invalid`] if the scene breaks
    /// a layout rule (nothing is written then); I/O errors naming the file.
    pub fn write(&self, dir: &Path) -> Result<(), SceneError> {
        self.check(dir)?;
        if dir.exists() {
            return Err(SceneError::Exists {
                path: dir.to_path_buf(),
            });
        }
        let name = dir
            .file_name()
            .ok_or_else(|| invalid(dir, "a scene folder needs a name"))?
            .to_string_lossy()
            .into_owned();
        let parent = match dir.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let tmp = parent.join(super::temp_name(&name, "partial"));
        if tmp.exists() {
            // Left over from a crashed process that had the same id.
            fs::remove_dir_all(&tmp).map_err(|e| io_error(&tmp, e))?;
        }
        let result = self
            .write_contents(&tmp)
            .and_then(|()| fs::rename(&tmp, dir).map_err(|e| io_error(dir, e)));
        if result.is_err() {
            // Best effort: never leave a partial scene behind, even a hidden one.
            let _ = fs::remove_dir_all(&tmp);
        }
        result
    }

    fn write_contents(&self, root: &Path) -> Result<(), SceneError> {
        let mkdir = |p: &Path| fs::create_dir_all(p).map_err(|e| io_error(p, e));
        mkdir(root)?;
        let json = |path: &Path, bytes: serde_json::Result<Vec<u8>>| {
            let bytes = bytes.map_err(|source| SceneError::Json {
                path: path.to_path_buf(),
                source,
            })?;
            write_atomic(path, &bytes).map_err(|source| SceneError::Io {
                path: path.to_path_buf(),
                source,
            })
        };
        let camera_path = root.join(CAMERA_FILE);
        json(&camera_path, serde_json::to_vec_pretty(&self.camera))?;
        let actions_path = root.join(ACTIONS_FILE);
        json(&actions_path, serde_json::to_vec_pretty(&self.actions))?;
        if let Some(poses) = &self.poses {
            let file = PosesFile {
                frames: poses
                    .iter()
                    .map(|frame| frame.iter().map(PoseRecord::from).collect())
                    .collect(),
            };
            json(&root.join(POSES_FILE), serde_json::to_vec(&file))?;
        }

        let rgb_dir = root.join(RGB_DIR);
        mkdir(&rgb_dir)?;
        for (t, img) in self.rgb.iter().enumerate() {
            write_rgb8(&rgb_dir.join(frame_file_name(t, "png")), img)?;
        }
        let depth_dir = root.join(DEPTH_DIR);
        mkdir(&depth_dir)?;
        for (t, img) in self.depth.iter().enumerate() {
            write_gray16(&depth_dir.join(frame_file_name(t, "png")), img)?;
        }
        if let Some(labels) = &self.labels {
            let label_dir = root.join(LABEL_DIR);
            mkdir(&label_dir)?;
            for (t, img) in labels.iter().enumerate() {
                write_gray16(&label_dir.join(frame_file_name(t, "png")), img)?;
            }
        }
        if let Some(flow) = &self.flow {
            let flow_dir = root.join(FLOW_DIR);
            mkdir(&flow_dir)?;
            for (t, img) in flow.iter().enumerate() {
                write_flo(&flow_dir.join(frame_file_name(t, "flo")), img)?;
            }
        }
        Ok(())
    }
}

/// The scene folders of a dataset: sub-folders whose name starts with `scene_`, sorted by
/// name (hidden, half-written folders start with `.` and are skipped).
///
/// # Errors
/// [`SceneError::Missing`] or [`SceneError::Io`] naming `dataset`.
pub fn list_scenes(dataset: &Path) -> Result<Vec<PathBuf>, SceneError> {
    let mut scenes = Vec::new();
    for entry in fs::read_dir(dataset).map_err(|e| io_error(dataset, e))? {
        let entry = entry.map_err(|e| io_error(dataset, e))?;
        let is_scene = entry
            .file_name()
            .to_str()
            .is_some_and(|n| n.starts_with("scene_"));
        if is_scene && entry.path().is_dir() {
            scenes.push(entry.path());
        }
    }
    scenes.sort();
    Ok(scenes)
}
