//! `riseg run`: RISeg over recorded scenes whose pushes already happened, writing the
//! masks in the layout `riseg eval` reads.
//!
//! Frame 0's mask is its static segmentation; every later frame's mask comes from the
//! [`Tracker`] (flow from the previous frame, the new static segmentation, UpdateMask).
//! A scene's masks are all computed before any is written; each PNG is written
//! atomically, so a failure leaves no half-written file.

use std::path::{Path, PathBuf};

use crate::{
    camera::SceneReplay,
    flow::FlowEstimator,
    imageio::{Gray16Image, ImageIoError, ImageSizeError, write_gray16},
    scene::{LABEL_DIR, Scene, SceneError, frame_file_name},
    segment::StaticSegmenter,
    tracker::{TrackError, Tracker},
};

/// Why a run failed; every variant names the scene folder or file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RunError {
    /// The scene could not be read.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Tracking failed on a frame.
    #[error("{scene}, frame {frame}: {source}")]
    Track {
        /// The scene folder.
        scene: PathBuf,
        /// The frame that failed.
        frame: usize,
        /// The cause.
        source: TrackError,
    },
    /// A mask could not be written.
    #[error(transparent)]
    Write(#[from] ImageIoError),
    /// A mask did not match the scene's image size.
    #[error("{path}: {source}")]
    MaskSize {
        /// The mask file.
        path: PathBuf,
        /// The cause.
        source: ImageSizeError,
    },
    /// The output folder could not be made.
    #[error("creating {path}: {source}")]
    CreateDir {
        /// The folder.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// Replays a recorded scene (the pushes already happened) through `tracker` from frame 0:
/// the accumulated mask of every frame, in order. `on_frame(t)` is called after frame `t`.
///
/// # Errors
/// The frame that failed and the [`TrackError`].
pub fn replay_scene<S: StaticSegmenter, F: FlowEstimator>(
    tracker: &mut Tracker<S, F>,
    scene: &Scene,
    mut on_frame: impl FnMut(usize),
) -> Result<Vec<Vec<u16>>, (usize, TrackError)> {
    tracker.reset();
    let mut masks = Vec::with_capacity(scene.frames());
    for t in 0..scene.frames() {
        let Some(frame) = SceneReplay::frame(scene, t) else {
            break;
        };
        masks.push(tracker.observe(frame).map_err(|e| (t, e))?.mask);
        on_frame(t);
    }
    Ok(masks)
}

/// Reads the scene folder `dir`, replays it, and writes its masks to
/// `out/<dir's name>/label/NNNNNN.png`; returns how many were written. `on_frame(t)` is
/// called as frame `t` is done.
///
/// # Errors
/// [`RunError`] naming the folder or file that failed.
pub fn run_scene<S: StaticSegmenter, F: FlowEstimator>(
    tracker: &mut Tracker<S, F>,
    dir: &Path,
    out: &Path,
    on_frame: impl FnMut(usize),
) -> Result<usize, RunError> {
    let scene = Scene::read(dir)?;
    let masks =
        replay_scene(tracker, &scene, on_frame).map_err(|(frame, source)| RunError::Track {
            scene: dir.to_owned(),
            frame,
            source,
        })?;
    let name = dir.file_name().unwrap_or(dir.as_os_str());
    let label_dir = out.join(name).join(LABEL_DIR);
    std::fs::create_dir_all(&label_dir).map_err(|source| RunError::CreateDir {
        path: label_dir.clone(),
        source,
    })?;
    let count = masks.len();
    for (t, mask) in masks.into_iter().enumerate() {
        let path = label_dir.join(frame_file_name(t, "png"));
        let image = Gray16Image::from_vec(scene.camera.width, scene.camera.height, mask).map_err(
            |source| RunError::MaskSize {
                path: path.clone(),
                source,
            },
        )?;
        write_gray16(&path, &image)?;
    }
    Ok(count)
}
