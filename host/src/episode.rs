//! Algorithm 1 on real (or simulated) devices: capture, segment and track, FindAction,
//! push, until no push qualifies or the push budget is spent.
//!
//! # Contract
//!
//! [`run_episode`] captures frame 0, then for each frame: the [`Tracker`] gives the static
//! segmentation and the accumulated mask; FindAction runs on the static heatmap and the
//! depth; its push is turned into a robot command ([`command_for`]) and sent. The episode
//! stops, and says why ([`Stop`]), when FindAction finds no push, after
//! [`Config::max_pushes`] pushes, or when a planned push breaks the robot's limits: that
//! push is refused and never sent. The caller sees every frame, with what was decided, in
//! `on_frame` before the push is made.

use nalgebra::Point3;
use riseg_core::{
    Config, ImageView,
    action::{ActionReport, Push, find_action},
    owned::ActionBuf,
    pipeline::RisegLoop,
};

use crate::{
    camera::{Camera, CameraError, CameraFrame},
    flow::FlowEstimator,
    robot::{PushCommand, PushRefused, Robot, RobotError, RobotSetup, plan_push},
    segment::StaticSegmenter,
    tracker::{Observation, TrackError, Tracker},
};

/// Why an episode failed (a refused push is not a failure: see [`Stop::Refused`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EpisodeError {
    /// The camera gave no frame.
    #[error("camera: {0}")]
    Camera(#[from] CameraError),
    /// The robot could not make a push.
    #[error("robot: {0}")]
    Robot(#[from] RobotError),
    /// Segmentation, flow or UpdateMask failed.
    #[error(transparent)]
    Track(#[from] TrackError),
    /// FindAction refused its input.
    #[error("FindAction: {0}")]
    Action(riseg_core::Error),
    /// The caller's `on_frame` stopped the episode.
    #[error("{0}")]
    Caller(String),
}

/// Why an episode ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stop {
    /// FindAction found no pair of certain regions with an uncertain one between them.
    NoAction,
    /// [`Config::max_pushes`] pushes were made.
    PushBudget,
    /// The planned push broke the robot's limits and was not sent.
    Refused(PushRefused),
}

/// What the loop decided on one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Decision {
    /// Push: FindAction's push and the command sent to the robot.
    Push {
        /// FindAction's push (pixels and camera frame).
        push: Push,
        /// Where the pushed segment ends along the push line, camera frame, metres.
        edge_cam_m: Point3<f32>,
        /// The command, robot frame.
        command: PushCommand,
    },
    /// Stop here.
    Stop(Stop),
}

/// One frame of an episode, as `on_frame` sees it.
#[derive(Debug)]
pub struct EpisodeFrame<'a> {
    /// Frame index: the scene after `t` pushes.
    pub t: usize,
    /// The captured frame.
    pub frame: &'a CameraFrame,
    /// Static segmentation, accumulated mask, the UpdateMask step, timing.
    pub observation: &'a Observation,
    /// FindAction's clusters, pair and push.
    pub action: &'a ActionReport,
    /// What the loop does next.
    pub decision: Decision,
}

/// How an episode ended.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeSummary {
    /// Frames captured (pushes made + 1).
    pub frames: usize,
    /// Commands sent, in order.
    pub pushes: Vec<PushCommand>,
    /// Why it stopped.
    pub stop: Stop,
}

/// Runs Algorithm 1 (module docs). `on_frame` may return an error to abort.
///
/// # Errors
/// [`EpisodeError`] from the devices, the tracker, FindAction or `on_frame`.
pub fn run_episode<S, F>(
    camera: &mut impl Camera,
    robot: &mut impl Robot,
    tracker: &mut Tracker<S, F>,
    setup: &RobotSetup,
    mut on_frame: impl FnMut(&EpisodeFrame<'_>) -> Result<(), String>,
) -> Result<EpisodeSummary, EpisodeError>
where
    S: StaticSegmenter,
    F: FlowEstimator,
{
    tracker.reset();
    let cfg = *tracker.config();
    let mut state = RisegLoop::new(&cfg);
    let mut action_buf: Option<ActionBuf> = None;
    let mut pushes = Vec::new();
    let mut t = 0;
    loop {
        let captured = camera.capture()?;
        let observation = tracker.observe(captured.clone())?;
        let frame = &captured;
        let (w, h) = frame.size();
        let scratch = action_buf.get_or_insert_with(|| ActionBuf::new(&cfg, w, h));
        let action = find_action(
            &ImageView::packed(w, h, &observation.static_seg.heatmap)
                .map_err(EpisodeError::Action)?,
            &ImageView::packed(w, h, frame.depth_m.as_slice()).map_err(EpisodeError::Action)?,
            &frame.intrinsics,
            &cfg,
            scratch.view(),
        )
        .map_err(EpisodeError::Action)?;
        let decision = decide(
            &mut state,
            &cfg,
            &action,
            frame,
            &observation.mask,
            robot,
            setup,
        );
        on_frame(&EpisodeFrame {
            t,
            frame,
            observation: &observation,
            action: &action,
            decision,
        })
        .map_err(EpisodeError::Caller)?;
        match decision {
            Decision::Push { command, .. } => {
                robot.execute(&command)?;
                pushes.push(command);
                t += 1;
            }
            Decision::Stop(stop) => {
                return Ok(EpisodeSummary {
                    frames: t + 1,
                    pushes,
                    stop,
                });
            }
        }
    }
}

fn decide(
    state: &mut RisegLoop,
    cfg: &Config,
    action: &ActionReport,
    frame: &CameraFrame,
    mask: &[u16],
    robot: &impl Robot,
    setup: &RobotSetup,
) -> Decision {
    let budget_left = state.pushes_done() < cfg.max_pushes;
    match state.next(action.push()) {
        None if budget_left => Decision::Stop(Stop::NoAction),
        None => Decision::Stop(Stop::PushBudget),
        Some(push) => match command_for(&push, frame, mask, robot, setup) {
            Ok((edge_cam_m, command)) => Decision::Push {
                push,
                edge_cam_m,
                command,
            },
            Err(refused) => Decision::Stop(Stop::Refused(refused)),
        },
    }
}

/// Turns FindAction's `push` into a robot command: finds where the pushed segment of
/// `mask` ends along the push line ([`object_edge_px`]), back-projects that at the depth of
/// the pushed cluster's centre, and plans the level push through the hand-eye transform
/// ([`plan_push`]).
///
/// # Errors
/// [`PushRefused`] when the command breaks the robot's limits or is not finite.
pub fn command_for(
    push: &Push,
    frame: &CameraFrame,
    mask: &[u16],
    robot: &impl Robot,
    setup: &RobotSetup,
) -> Result<(Point3<f32>, PushCommand), PushRefused> {
    let (w, h) = frame.size();
    let edge_px = object_edge_px(mask, w, h, push).unwrap_or(push.start_px);
    let edge_cam_m = frame
        .intrinsics
        .back_project(edge_px[0], edge_px[1], push.start_cam_m.z);
    let command = plan_push(
        push,
        &edge_cam_m,
        &setup.robot_from_camera,
        &setup.geometry,
        &robot.limits(),
    )?;
    Ok((edge_cam_m, command))
}

/// Walks from the push's target (the pushed cluster's centre) back through its start, in
/// half-pixel steps, while the pixels keep the target's label in `mask`; returns the last
/// point inside. `None` when the target is background or outside the image.
#[must_use]
pub fn object_edge_px(mask: &[u16], width: usize, height: usize, push: &Push) -> Option<[f32; 2]> {
    let label_at = |p: [f32; 2]| -> Option<u16> {
        let (x, y) = (p[0].round(), p[1].round());
        if !(x >= 0.0 && y >= 0.0 && (x as usize) < width && (y as usize) < height) {
            return None;
        }
        mask.get(y as usize * width + x as usize).copied()
    };
    let target = push.target_px;
    let label = label_at(target).filter(|&l| l != 0)?;
    let (dx, dy) = (push.start_px[0] - target[0], push.start_px[1] - target[1]);
    let len = (dx * dx + dy * dy).sqrt();
    if !(len > 1e-3 && len.is_finite()) {
        return None;
    }
    let step = [0.5 * dx / len, 0.5 * dy / len];
    let mut inside = target;
    for i in 1..=2 * (width + height) {
        let p = [
            target[0] + step[0] * i as f32,
            target[1] + step[1] * i as f32,
        ];
        if label_at(p) != Some(label) {
            break;
        }
        inside = p;
    }
    Some(inside)
}
