//! `riseg bench`'s closed loop on one simulated scene, for the diagnostic examples: the
//! same tracker, settings and one-thread flow as the bench; `on_frame` sees every frame.

use riseg::{
    cli::{config::Settings, models::Models},
    rig::episode::{EpisodeFrame, run_episode},
    sim::{Layout, SimConfig, SimRig, SimScene},
};

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
