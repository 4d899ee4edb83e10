//! Simulated datasets in the scene folder format (`riseg gen`).
//!
//! Scene `i` of a dataset with seed `S` and scene family `L` ([`Layout`]) is simulated from
//! [`scene_seed`]`(S, i)` with [`SimConfig::D415`] drawing `L`: the initial frame, then
//! `pushes` scripted pushes ([`SimScene::scripted_push`], [`DEFAULT_PUSH_LEN_M`]: in a loose
//! scene one object of a touching pair across the line joining the pair; in a packed or
//! mixed scene a push that shears the pack), each followed by a frame. Every frame gets
//! labels and every object's pose (`poses.json`); every push gets the exact flow and an
//! `actions.json` entry in the camera frame.
//!
//! A simulated scene is kept only if it is a useful benchmark scene: every object is seen
//! by at least [`MIN_VISIBLE_PX`] pixels in every frame, every push finds a touching pair
//! and moves some object by more than [`MIN_PUSH_FLOW_PX`] of ground-truth flow, and no
//! object leaves the table. Otherwise the next attempt seed is tried
//! ([`first_usable_seed`], at most [`MAX_SCENE_ATTEMPTS`]); [`GeneratedScene::attempts`] says how many were needed. All of this is
//! deterministic, so the same dataset seed and family give the same files, byte for byte.
//!
//! Output layout: `OUT/scene_000/ …` (see [`crate::io::scene`]) and a preview per scene,
//! `OUT/preview/scene_000.png` ([`crate::cli::preview`]).

use std::{
    fs,
    path::{Path, PathBuf},
};

use crate::{
    cli::preview::preview,
    io::image::{Gray16Image, ImageIoError, RgbImage, write_rgb8},
    io::scene::{PushAction, Scene, SceneCamera, SceneError},
    sim::{
        DEFAULT_PUSH_LEN_M, Layout, MAX_SCENE_ATTEMPTS, ObjectBounds, ScriptedPush, SimConfig,
        SimError, SimFrame, SimScene, TABLE_HALF_EXTENTS_M, first_usable_seed, ground_truth_flow,
        scene_seed,
    },
};

/// Depth unit of generated scenes: millimetres.
pub const DEPTH_UNIT_M: f32 = 0.001;
/// Fewest pixels every object must show in every frame.
pub const MIN_VISIBLE_PX: usize = 150;
/// Every push must move some object by more than this much ground-truth flow, pixels.
pub const MIN_PUSH_FLOW_PX: f32 = 1.0;
/// Folder of the per-scene previews inside the output folder.
pub const PREVIEW_DIR: &str = "preview";

/// Why generating a dataset failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GenError {
    /// The simulator refused a request.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// Writing a scene failed.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Writing a preview failed.
    #[error(transparent)]
    Image(#[from] ImageIoError),
    /// The output folder could not be created.
    #[error("{}: cannot create folder: {source}", path.display())]
    CreateDir {
        /// The folder.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// No attempt gave a usable scene.
    #[error("seed {seed}: no usable scene in {attempts} attempts (last: {reason})")]
    NoValidScene {
        /// The scene seed.
        seed: u64,
        /// Attempts made.
        attempts: u32,
        /// Why the last attempt was rejected.
        reason: String,
    },
}

/// One simulated scene, ready to write.
#[derive(Debug, Clone)]
pub struct GeneratedScene {
    /// The scene in the folder format (depth in millimetres, labels, flow, actions, object
    /// poses).
    pub scene: Scene,
    /// Its preview picture.
    pub preview: RgbImage,
    /// The pushes in the world (table) frame.
    pub pushes: Vec<ScriptedPush>,
    /// Number of objects.
    pub objects: usize,
    /// Attempts needed (1 = the first simulation was usable).
    pub attempts: u32,
}

fn depth_to_units(frame: &SimFrame) -> Gray16Image {
    frame.depth_m.map(|&d| {
        let units = (d / DEPTH_UNIT_M).round();
        if units >= 1.0 {
            units.min(f32::from(u16::MAX)) as u16
        } else {
            0
        }
    })
}

fn visible_px(labels: &Gray16Image, label: u16) -> usize {
    labels.as_slice().iter().filter(|&&l| l == label).count()
}

fn on_table(bounds: &[ObjectBounds]) -> bool {
    bounds.iter().all(|b| {
        b.min_m.z > -0.002
            && b.min_m.x > -TABLE_HALF_EXTENTS_M[0]
            && b.max_m.x < TABLE_HALF_EXTENTS_M[0]
            && b.min_m.y > -TABLE_HALF_EXTENTS_M[1]
            && b.max_m.y < TABLE_HALF_EXTENTS_M[1]
    })
}

/// Simulates scene `seed` of family `layout` with `pushes` pushes (see the module docs).
///
/// # Errors
/// [`GenError::NoValidScene`] if no attempt was usable.
pub fn generate_scene(
    seed: u64,
    layout: Layout,
    pushes: usize,
) -> Result<GeneratedScene, GenError> {
    match first_usable_seed(seed, |s| simulate(s, layout, pushes))? {
        Ok(found) => Ok(GeneratedScene {
            attempts: found.attempts,
            ..found.value
        }),
        Err(reason) => Err(GenError::NoValidScene {
            seed,
            attempts: MAX_SCENE_ATTEMPTS,
            reason,
        }),
    }
}

/// One attempt: `Ok(Err(reason))` when the scene is not usable.
fn simulate(
    seed: u64,
    layout: Layout,
    pushes: usize,
) -> Result<Result<GeneratedScene, String>, GenError> {
    let mut sim = match SimScene::with_config(seed, SimConfig::D415.with_layout(layout)) {
        Ok(sim) => sim,
        Err(SimError::Placement { .. }) => return Ok(Err("no object placement".into())),
        Err(e) => return Err(e.into()),
    };
    let labels: Vec<u16> = sim.objects().iter().map(|o| o.label).collect();
    let hidden = |frame: &SimFrame| {
        labels
            .iter()
            .find(|&&l| visible_px(&frame.labels, l) < MIN_VISIBLE_PX)
            .copied()
    };
    let first = sim.render();
    if let Some(l) = hidden(&first) {
        return Ok(Err(format!("object {l} hardly visible initially")));
    }
    let mut frames = vec![first];
    let mut flows = Vec::with_capacity(pushes);
    let mut done = Vec::with_capacity(pushes);
    for k in 1..=pushes {
        let Some(push) = sim.scripted_push(DEFAULT_PUSH_LEN_M) else {
            return Ok(Err(format!("no touching pair to push before push {k}")));
        };
        sim.push(&push.command)?;
        if !on_table(&sim.object_bounds()) {
            return Ok(Err(format!("an object left the table in push {k}")));
        }
        let frame = sim.render();
        if let Some(l) = hidden(&frame) {
            return Ok(Err(format!("object {l} hardly visible after push {k}")));
        }
        let prev = &frames[frames.len() - 1];
        let flow = ground_truth_flow(
            &prev.intrinsics,
            &prev.world_from_camera,
            &prev.labels,
            &prev.true_depth_m,
            &prev.object_poses,
            &frame.object_poses,
        )?;
        let max_flow = flow
            .as_slice()
            .iter()
            .map(|[dx, dy]| (dx * dx + dy * dy).sqrt())
            .fold(0.0_f32, f32::max);
        if max_flow <= MIN_PUSH_FLOW_PX {
            return Ok(Err(format!("push {k} moved nothing visibly")));
        }
        flows.push(flow);
        frames.push(frame);
        done.push(push);
    }

    let config = sim.config();
    let k = config.intrinsics;
    let camera_from_world = sim.world_from_camera().inverse();
    let mut actions = Vec::with_capacity(done.len());
    for (p, number) in done.iter().zip(1u32..) {
        let start = camera_from_world * p.command.start_robot_m;
        let dir = camera_from_world.rotation * p.command.direction_robot;
        let Some(px) = k.project(&start) else {
            return Ok(Err(format!("push {number} starts behind the camera")));
        };
        actions.push(PushAction {
            push: number,
            start_px: [px.x, px.y],
            start_cam_m: [start.x, start.y, start.z],
            direction_cam: [dir.x, dir.y, dir.z],
            length_m: p.command.length_m,
        });
    }
    let poses = frames.iter().map(|f| f.object_poses.clone()).collect();
    let scene = Scene {
        camera: SceneCamera {
            width: config.width,
            height: config.height,
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            depth_unit_m: DEPTH_UNIT_M,
        },
        rgb: frames.iter().map(|f| f.rgb.clone()).collect(),
        depth: frames.iter().map(depth_to_units).collect(),
        labels: Some(frames.into_iter().map(|f| f.labels).collect()),
        flow: Some(flows),
        actions,
        poses: Some(poses),
    };
    Ok(Ok(GeneratedScene {
        preview: preview(&scene),
        scene,
        pushes: done,
        objects: labels.len(),
        attempts: 1,
    }))
}

/// The folder name of scene `index`: `scene_000`, `scene_001`, ….
#[must_use]
pub fn scene_dir_name(index: usize) -> String {
    format!("scene_{index:03}")
}

/// Generates `scenes` scenes of family `layout` from `seed` with `pushes` pushes each into
/// `out` (created if missing), calling `on_scene(index, &scene)` after each scene is
/// written.
///
/// # Errors
/// [`GenError::CreateDir`] if `out` cannot be created; [`SceneError::Exists`] (as
/// [`GenError::Scene`]) if a scene folder or preview it would write is already there
/// (checked before anything is written); simulation and write errors.
pub fn write_dataset(
    out: &Path,
    scenes: usize,
    seed: u64,
    layout: Layout,
    pushes: usize,
    mut on_scene: impl FnMut(usize, &GeneratedScene),
) -> Result<(), GenError> {
    let previews = out.join(PREVIEW_DIR);
    // Every destination is checked before anything is written: gen never replaces a file.
    for i in 0..scenes {
        let name = scene_dir_name(i);
        for path in [out.join(&name), previews.join(format!("{name}.png"))] {
            if fs::symlink_metadata(&path).is_ok() {
                return Err(SceneError::Exists { path }.into());
            }
        }
    }
    fs::create_dir_all(&previews).map_err(|source| GenError::CreateDir {
        path: previews.clone(),
        source,
    })?;
    for i in 0..scenes {
        let g = generate_scene(scene_seed(seed, i), layout, pushes)?;
        let name = scene_dir_name(i);
        g.scene.write(&out.join(&name))?;
        write_rgb8(&previews.join(format!("{name}.png")), &g.preview)?;
        on_scene(i, &g);
    }
    Ok(())
}

// --- the `riseg gen` command ----------------------------------------------------

mod command {
    use std::path::PathBuf;

    use crate::cli::generate::{PREVIEW_DIR, scene_dir_name, write_dataset};
    use anyhow::Context as _;
    use clap::Args;
    use indicatif::{ProgressBar, ProgressStyle};

    use crate::cli::LayoutArg;

    #[derive(Debug, Args)]
    pub(in crate::cli) struct GenArgs {
        /// Number of scenes to make (1 to 10000).
        #[arg(long, default_value_t = 1, value_parser = crate::cli::scene_count)]
        scenes: usize,
        /// Dataset seed; scene i is simulated from a seed derived from it and i.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Output folder (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// Pushes per scene (0 to 20); each scene has pushes + 1 frames.
        #[arg(long, default_value_t = 3, value_parser = crate::cli::push_count)]
        pushes: usize,
        /// Scene family: loose, packed or mixed (described above).
        #[arg(long, value_enum, default_value_t = LayoutArg::Loose)]
        layout: LayoutArg,
    }

    pub(in crate::cli) fn command(args: &GenArgs) -> anyhow::Result<()> {
        let GenArgs {
            scenes,
            seed,
            out,
            pushes,
            layout,
        } = args;
        let (scenes, seed, pushes, layout) = (*scenes, *seed, *pushes, layout.layout());
        let bar = ProgressBar::new(scenes as u64);
        bar.set_style(
            ProgressStyle::with_template("{bar:30} {pos}/{len} scenes  {elapsed}  {msg}")
                .context("progress bar template")?,
        );
        write_dataset(out, scenes, seed, layout, pushes, |i, g| {
            bar.set_message(format!(
                "{}: {} objects, {} pushes",
                scene_dir_name(i),
                g.objects,
                g.pushes.len()
            ));
            bar.inc(1);
        })
        .with_context(|| format!("generating {scenes} {layout} scenes into {}", out.display()))?;
        bar.finish();
        say!(
            "wrote {scenes} {layout} scenes to {}; previews in {}\n",
            out.display(),
            out.join(PREVIEW_DIR).display()
        )?;
        Ok(())
    }
}

pub(in crate::cli) use command::*;
