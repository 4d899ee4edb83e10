//! `riseg bench`'s closed loop on one simulated scene, for the diagnostic examples: the
//! same tracker, settings and one-thread flow as the bench; `on_frame` sees every frame.

use std::collections::BTreeMap;

use riseg::{
    cli::{config::Settings, models::Models},
    io::scene::ObjectPose,
    rig::episode::{EpisodeFrame, run_episode},
    sim::{Layout, SimConfig, SimRig, SimScene},
};
use riseg_core::Pose;

/// A simulated frame's ground truth.
pub struct FrameTruth {
    /// The true label image.
    pub truth: Vec<u16>,
    /// The object poses as the scene lists them.
    pub pose_list: Vec<ObjectPose>,
    /// The same poses by label.
    pub poses: BTreeMap<u16, Pose>,
}

/// `f`'s ground truth (an error naming what the frame lacks).
pub fn frame_truth(f: &EpisodeFrame<'_>) -> Result<FrameTruth, String> {
    let truth = f.frame.truth.as_ref().ok_or("truth")?.as_slice().to_vec();
    let pose_list = f.frame.truth_poses.clone().ok_or("poses")?;
    let poses = pose_list
        .iter()
        .map(|p| (p.label, p.world_from_object))
        .collect();
    Ok(FrameTruth {
        truth,
        pose_list,
        poses,
    })
}

/// Runs the episode of simulator seed `seed` in family `layout`, calling `on_frame` on each
/// frame (its error ends the episode).
pub fn run_sim_episode(
    seed: u64,
    layout: Layout,
    on_frame: impl FnMut(&EpisodeFrame<'_>) -> Result<(), String>,
) -> anyhow::Result<()> {
    let sim = SimScene::with_config(seed, SimConfig::D415.with_layout(layout))?;
    let mut rig = SimRig::new(sim);
    let mut tracker = Models::default().tracker(&Settings::default(), Some(1))?;
    run_episode(
        &mut rig.camera,
        &mut rig.robot,
        &mut tracker,
        &rig.setup,
        on_frame,
    )?;
    Ok(())
}
