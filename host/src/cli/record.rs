//! `--rerun FILE.rrd` of `riseg demo` and `riseg run`: every frame of the loop written to a
//! rerun recording (feature `rerun`; the file opens in the rerun viewer of the same
//! version, or reads back with the `rerun-sdk` wheel).
//!
//! # Contract
//!
//! One timeline, `push`: frame `t` (the scene after `t` pushes) is logged at `push = t`.
//! Under the root `ROOT` (`demo`, or the scene folder's name for `run`), every frame has:
//!
//! | entity | archetype | what |
//! | --- | --- | --- |
//! | `ROOT` | `ViewCoordinates` (static) | camera axes: x right, y down, z forward |
//! | `ROOT` | `AnnotationContext` (static) | class `k` in riseg's colour of label `k` |
//! | `ROOT/camera` | `Pinhole` (static) | the intrinsics (riseg's `cx`, `cy` + 0.5) |
//! | `ROOT/camera/rgb` | `Image` | colour |
//! | `ROOT/camera/depth` | `DepthImage` | depth, metres |
//! | `ROOT/camera/static` | `SegmentationImage` | the static segmenter's labels |
//! | `ROOT/camera/riseg` | `SegmentationImage` | RISeg's accumulated mask |
//! | `ROOT/camera/flow` | `Image` | flow from `t − 1` (Middlebury colours; `t > 0`) |
//! | `ROOT/camera/push` | `Arrows2D` | the push made from frame `t` (if any) |
//! | `ROOT/body_frames` | `Arrows3D` | the step's body frames, moved to frame `t`: two edges each, in the colour of their twist group (grey: none or static; `t > 0`), as in the demo's pictures |
//! | `ROOT/push` | `Arrows3D` | the push in the camera frame, metres (if any) |
//! | `ROOT/timing/STAGE` | `Scalars` | milliseconds of each stage ([`StageTimes::NAMES`](crate::rig::tracker::StageTimes::NAMES)) |
//!
//! Labels share rerun class ids, so one object keeps one colour in both masks and in every
//! frame it keeps its label.
//!
//! The recording is written to a hidden temporary file beside `FILE.rrd` and renamed to it
//! by [`Recording::finish`]: `FILE.rrd` is a complete recording or what it was before, and
//! a command that fails leaves no partial file. A folder that cannot hold the file and
//! logging errors (a full disk) end the command with the file's name. Without the feature,
//! [`Recording::create`] is an error that says how to build riseg with it; the commands
//! are otherwise the same.

use riseg_core::Intrinsics;

use crate::io::scene::PushAction;

pub use sink::Recording;

/// A push as drawn: start and end in the image (pixels) and in the camera frame (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PushArrow {
    /// Start, pixels.
    pub start_px: [f32; 2],
    /// End, pixels.
    pub end_px: [f32; 2],
    /// Start, camera frame, metres.
    pub start_cam_m: [f32; 3],
    /// End, camera frame, metres.
    pub end_cam_m: [f32; 3],
}

impl PushArrow {
    /// FindAction's push.
    #[must_use]
    pub fn from_push(push: &riseg_core::action::Push) -> Self {
        let start = push.start_cam_m;
        let end = start + push.direction_cam * push.length_m;
        Self {
            start_px: push.start_px,
            end_px: push.target_px,
            start_cam_m: [start.x, start.y, start.z],
            end_cam_m: [end.x, end.y, end.z],
        }
    }

    /// A recorded push (`actions.json`), its end projected with `k`; `None` when the end
    /// is behind the camera.
    #[must_use]
    pub fn from_action(action: &PushAction, k: &Intrinsics) -> Option<Self> {
        let [x, y, z] = action.start_cam_m;
        let [dx, dy, dz] = action.direction_cam;
        let l = action.length_m;
        let end = nalgebra::Point3::new(x + l * dx, y + l * dy, z + l * dz);
        let end_px = k.project(&end)?;
        Some(Self {
            start_px: action.start_px,
            end_px: [end_px.x, end_px.y],
            start_cam_m: action.start_cam_m,
            end_cam_m: [end.x, end.y, end.z],
        })
    }
}

#[cfg(feature = "rerun")]
mod sink {
    use std::path::{Path, PathBuf};

    use anyhow::Context as _;
    use re_sdk_types::{archetypes, components, datatypes};
    use riseg_core::Intrinsics;

    use super::PushArrow;
    use crate::{
        draw::{PUSH_COLOUR, body_frame_colour, label_colour},
        flow::viz::flow_to_rgb,
        rig::{camera::CameraFrame, tracker::Observation, tracker::StageTimes},
    };

    /// Class ids given a colour in the annotation context: labels above it are drawn by
    /// rerun's own palette.
    const MAX_CLASS_ID: u16 = 255;

    /// An open `.rrd` file sink (module docs).
    #[derive(Debug)]
    pub struct Recording {
        /// Dropped before `partial`: that ends rerun's writer thread, which closes the file.
        stream: re_sdk::RecordingStream,
        partial: Partial,
        path: PathBuf,
    }

    /// The file being written, `.NAME.partial` beside `NAME`; deleted when dropped, so
    /// nothing is left of a recording that was not finished (after `finish` renamed it,
    /// there is nothing to delete).
    #[derive(Debug)]
    struct Partial(PathBuf);

    impl Drop for Partial {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.0);
        }
    }

    fn rgb(c: [u8; 3]) -> components::Color {
        components::Color::from_rgb(c[0], c[1], c[2])
    }

    fn size_u32(frame: &CameraFrame) -> anyhow::Result<[u32; 2]> {
        let (w, h) = frame.size();
        Ok([u32::try_from(w)?, u32::try_from(h)?])
    }

    impl Recording {
        /// Creates (or replaces) the recording `path`.
        ///
        /// # Errors
        /// The file cannot be created.
        pub fn create(path: &Path) -> anyhow::Result<Self> {
            let context = || format!("--rerun {}", path.display());
            let Some(name) = path.file_name() else {
                anyhow::bail!("--rerun {}: not a file name", path.display());
            };
            let mut partial_name = std::ffi::OsString::from(".");
            partial_name.push(name);
            partial_name.push(".partial");
            let partial = Partial(path.with_file_name(partial_name));
            let stream = re_sdk::RecordingStreamBuilder::new("riseg")
                .save(&partial.0)
                .with_context(context)?;
            Ok(Self {
                stream,
                partial,
                path: path.to_owned(),
            })
        }

        /// Logs frame `t` under `root` (module docs): `push` is the push made from this frame.
        ///
        /// # Errors
        /// Writing to the file failed.
        pub fn frame(
            &self,
            root: &str,
            t: usize,
            frame: &CameraFrame,
            observation: &Observation,
            push: Option<&PushArrow>,
        ) -> anyhow::Result<()> {
            self.log_frame(root, t, frame, observation, push)
                .with_context(|| format!("--rerun {}: frame {t}", self.path.display()))
        }

        fn log_frame(
            &self,
            root: &str,
            t: usize,
            frame: &CameraFrame,
            observation: &Observation,
            push: Option<&PushArrow>,
        ) -> anyhow::Result<()> {
            let rec = &self.stream;
            let size = size_u32(frame)?;
            if t == 0 {
                self.log_static(root, &frame.intrinsics, size)?;
            }
            rec.set_time_sequence("push", i64::try_from(t)?);
            let cam = format!("{root}/camera");
            let rgb_bytes = frame.rgb.as_slice().as_flattened().to_vec();
            rec.log(
                format!("{cam}/rgb"),
                &archetypes::Image::from_rgb24(rgb_bytes, size),
            )?;
            let depth = frame
                .depth_m
                .as_slice()
                .iter()
                .flat_map(|d| d.to_le_bytes());
            rec.log(
                format!("{cam}/depth"),
                &archetypes::DepthImage::from_data_type_and_bytes(
                    depth.collect::<Vec<u8>>(),
                    size,
                    datatypes::ChannelDatatype::F32,
                )
                .with_meter(1.0),
            )?;
            for (name, labels) in [
                ("static", observation.static_seg.labels.as_slice()),
                ("riseg", observation.mask.as_slice()),
            ] {
                let bytes: Vec<u8> = labels.iter().flat_map(|l| l.to_le_bytes()).collect();
                let format =
                    components::ImageFormat::segmentation(size, datatypes::ChannelDatatype::U16);
                rec.log(
                    format!("{cam}/{name}"),
                    &archetypes::SegmentationImage::new(bytes, format),
                )?;
            }
            if let Some(step) = &observation.step {
                let picture = flow_to_rgb(&step.flow, None);
                let bytes = picture.as_slice().as_flattened().to_vec();
                rec.log(
                    format!("{cam}/flow"),
                    &archetypes::Image::from_rgb24(bytes, size),
                )?;
                let mut origins = Vec::with_capacity(2 * step.frames.len());
                let mut vectors = Vec::with_capacity(2 * step.frames.len());
                let mut colours = Vec::with_capacity(2 * step.frames.len());
                for f in &step.frames {
                    let [o, a, b] = f.frame.p_t1.map(|p| [p.x, p.y, p.z]);
                    let colour = body_frame_colour(f.group, f.moving);
                    for end in [a, b] {
                        origins.push(o);
                        vectors.push([end[0] - o[0], end[1] - o[1], end[2] - o[2]]);
                        colours.push(rgb(colour));
                    }
                }
                rec.log(
                    format!("{root}/body_frames"),
                    &archetypes::Arrows3D::from_vectors(vectors)
                        .with_origins(origins)
                        .with_colors(colours),
                )?;
            }
            if let Some(p) = push {
                let [x0, y0] = p.start_px;
                let [x1, y1] = p.end_px;
                rec.log(
                    format!("{cam}/push"),
                    &archetypes::Arrows2D::from_vectors([[x1 - x0, y1 - y0]])
                        .with_origins([[x0 + 0.5, y0 + 0.5]])
                        .with_colors([rgb(PUSH_COLOUR)]),
                )?;
                let [a, b] = [p.start_cam_m, p.end_cam_m];
                rec.log(
                    format!("{root}/push"),
                    &archetypes::Arrows3D::from_vectors([[b[0] - a[0], b[1] - a[1], b[2] - a[2]]])
                        .with_origins([a])
                        .with_colors([rgb(PUSH_COLOUR)]),
                )?;
            }
            for (name, ms) in StageTimes::NAMES.iter().zip(observation.times.values()) {
                rec.log(
                    format!("{root}/timing/{name}"),
                    &archetypes::Scalars::new([ms]),
                )?;
            }
            Ok(())
        }

        /// What does not change over the frames: axes, class colours, the pinhole.
        fn log_static(&self, root: &str, k: &Intrinsics, size: [u32; 2]) -> anyhow::Result<()> {
            let rec = &self.stream;
            rec.log_static(root, &archetypes::ViewCoordinates::RDF())?;
            let classes: Vec<(u16, String)> = (0..=MAX_CLASS_ID)
                .map(|id| {
                    (
                        id,
                        if id == 0 {
                            "background".to_owned()
                        } else {
                            format!("label {id}")
                        },
                    )
                })
                .collect();
            let context = archetypes::AnnotationContext::new(classes.iter().map(|(id, name)| {
                let [r, g, b] = label_colour(*id);
                (*id, name.as_str(), datatypes::Rgba32::from_rgb(r, g, b))
            }));
            rec.log_static(root, &context)?;
            // rerun measures pixels from the top-left corner, riseg from its centre.
            let pinhole = archetypes::Pinhole::from_focal_length_and_resolution(
                [k.fx, k.fy],
                [size[0] as f32, size[1] as f32],
            )
            .with_principal_point([k.cx + 0.5, k.cy + 0.5]);
            rec.log_static(format!("{root}/camera"), &pinhole)?;
            Ok(())
        }

        /// Flushes and closes the file and moves it to its path.
        ///
        /// # Errors
        /// A write failed, or the file could not be moved (then nothing is at the path).
        pub fn finish(self) -> anyhow::Result<()> {
            let Self {
                stream,
                partial,
                path,
            } = self;
            let context = || format!("--rerun {}", path.display());
            stream.flush_blocking().with_context(context)?;
            // The last handle: waits for the writer thread, which writes rerun's footer.
            drop(stream);
            std::fs::rename(&partial.0, &path).with_context(context)
        }
    }
}

#[cfg(not(feature = "rerun"))]
mod sink {
    use std::path::Path;

    use super::PushArrow;
    use crate::rig::{camera::CameraFrame, tracker::Observation};

    /// Never made: riseg was built without the `rerun` feature.
    #[derive(Debug)]
    pub struct Recording(core::convert::Infallible);

    impl Recording {
        /// Always an error naming the feature.
        ///
        /// # Errors
        /// Always.
        pub fn create(path: &Path) -> anyhow::Result<Self> {
            anyhow::bail!(
                "--rerun {}: this riseg was built without rerun; build it with \
                 `cargo build --release --features rerun`",
                path.display()
            )
        }

        /// Never called (no value exists).
        ///
        /// # Errors
        /// Never.
        pub fn frame(
            &self,
            _root: &str,
            _t: usize,
            _frame: &CameraFrame,
            _observation: &Observation,
            _push: Option<&PushArrow>,
        ) -> anyhow::Result<()> {
            match self.0 {}
        }

        /// Never called (no value exists).
        ///
        /// # Errors
        /// Never.
        pub fn finish(self) -> anyhow::Result<()> {
            match self.0 {}
        }
    }
}
