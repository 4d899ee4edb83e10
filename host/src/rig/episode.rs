//! Algorithm 1 on real (or simulated) devices: capture, segment and track, FindAction,
//! push, until no push qualifies or the push budget is spent.
//!
//! # Contract
//!
//! [`run_episode`] captures frame 0, then for each frame: the [`Tracker`] gives the static
//! segmentation and the accumulated mask; FindAction runs on the static heatmap, the depth
//! and the accumulated mask and plans the push (camera frame); [`plan_push`] maps it into
//! the robot frame and checks it against the robot's limits, and it is sent. The episode
//! stops, and says why ([`Stop`]), when FindAction finds no push, after
//! [`Config::max_pushes`] pushes, or when a planned push breaks the robot's limits: that
//! push is refused and never sent. The caller sees every frame, with what was decided, in
//! `on_frame` before the push is made.

use riseg_core::{
    Config, ImageView, Intrinsics,
    action::{ActionReport, Push, find_action},
    pipeline::RisegLoop,
};

use nalgebra::{Point3, Vector3};

use crate::{
    flow::FlowEstimator,
    io::scene::PushAction,
    rig::camera::{Camera, CameraError, CameraFrame},
    rig::robot::{PushCommand, PushRefused, Robot, RobotError, RobotSetup, plan_push},
    rig::tracker::{Observation, TrackError, Tracker},
    rig::workspace::ActionBuf,
    segment::StaticSegmenter,
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
        /// The same push in the robot frame, as sent.
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
        // The tracker keeps the frame (its next step's previous one) and lends it back.
        let observation = tracker.observe(camera.capture()?)?;
        let frame = tracker
            .last_frame()
            .expect("a successful observe keeps its frame");
        let action = find_action_on(frame, &observation, &cfg, &mut action_buf)
            .map_err(EpisodeError::Action)?;
        let decision = decide(&mut state, &cfg, &action, robot, setup);
        let intrinsics = frame.intrinsics;
        on_frame(&EpisodeFrame {
            t,
            frame,
            observation: &observation,
            action: &action,
            decision,
        })
        .map_err(EpisodeError::Caller)?;
        match decision {
            Decision::Push { push, command } => {
                let hint = push_motion_px(&push, command.length_m, &intrinsics);
                log::debug!(
                    "frame {t}: push from {:?} m along {:?}, {} m (robot frame)",
                    command.start_robot_m.coords.as_slice(),
                    command.direction_robot.as_slice(),
                    command.length_m
                );
                robot.execute(&command)?;
                tracker.expect_motion_px(hint);
                pushes.push(command);
                t += 1;
            }
            Decision::Stop(stop) => {
                log::debug!("frame {t}: stop, {stop:?}");
                return Ok(EpisodeSummary {
                    frames: t + 1,
                    pushes,
                    stop,
                });
            }
        }
    }
}

/// FindAction on `frame` as the loop runs it: on the static heatmap of `observation`, the
/// frame's depth and the accumulated mask. `buf` is sized on the first call and reused:
/// every frame given with one `buf` must have one size.
///
/// # Errors
/// riseg-core's error when FindAction refuses its input (a frame of another size than
/// `buf`'s first gives [`riseg_core::Error::BufferTooSmall`] or works in the larger buffers).
pub fn find_action_on(
    frame: &CameraFrame,
    observation: &Observation,
    cfg: &Config,
    buf: &mut Option<ActionBuf>,
) -> Result<ActionReport, riseg_core::Error> {
    let (w, h) = frame.size();
    let scratch = buf.get_or_insert_with(|| ActionBuf::new(cfg, w, h));
    find_action(
        &observation.static_seg.heatmap.view(),
        &frame.depth_m.view(),
        &ImageView::packed(w, h, &observation.mask)?,
        &frame.intrinsics,
        cfg,
        scratch.view(),
    )
}

fn decide(
    state: &mut RisegLoop,
    cfg: &Config,
    action: &ActionReport,
    robot: &impl Robot,
    setup: &RobotSetup,
) -> Decision {
    let budget_left = state.pushes_done() < cfg.max_pushes;
    match state.next(action.push()) {
        None if budget_left => Decision::Stop(Stop::NoAction),
        None => Decision::Stop(Stop::PushBudget),
        Some(push) => match plan_push(
            &push,
            &setup.robot_from_camera,
            &setup.geometry,
            &robot.limits(),
        ) {
            Ok(command) => Decision::Push { push, command },
            Err(refused) => Decision::Stop(Stop::Refused(refused)),
        },
    }
}

/// The image motion, pixels `[dx, dy]`, of a point at the push's start carried `length_m`
/// along its direction (camera frame): about where the pushed object shows up in the next
/// frame, the flow's motion hint ([`Tracker::expect_motion_px`]). The episode passes the
/// finger's whole travel (the command's length, approach included): on the simulator the
/// pushed boxes moved 22-38 mm for a 30 mm travel. `None` if either point is behind the
/// camera or the motion is not finite.
#[must_use]
pub fn push_motion_px(push: &Push, length_m: f32, intrinsics: &Intrinsics) -> Option<[f32; 2]> {
    motion_hint_px(push.start_cam_m, push.direction_cam, length_m, intrinsics)
}

/// [`push_motion_px`] of a recorded push (`actions.json`; its length is the finger's
/// travel, as `riseg gen` and `riseg run --live` record it): the hint a replay of the
/// scene gives the flow of frame `action.push`, equal to the one the live run gave.
#[must_use]
pub fn action_motion_px(action: &PushAction, intrinsics: &Intrinsics) -> Option<[f32; 2]> {
    let [x, y, z] = action.start_cam_m;
    let [dx, dy, dz] = action.direction_cam;
    motion_hint_px(
        Point3::new(x, y, z),
        Vector3::new(dx, dy, dz),
        action.length_m,
        intrinsics,
    )
}

fn motion_hint_px(
    start_cam_m: Point3<f32>,
    direction_cam: Vector3<f32>,
    length_m: f32,
    intrinsics: &Intrinsics,
) -> Option<[f32; 2]> {
    let from = intrinsics.project(&start_cam_m)?;
    let to = intrinsics.project(&(start_cam_m + direction_cam * length_m))?;
    let d = to - from;
    (d.x.is_finite() && d.y.is_finite()).then_some([d.x, d.y])
}

#[cfg(all(test, feature = "sim"))]
mod tests {
    use super::*;
    use crate::flow::{DisFlow, FlowError, FlowParams};
    use crate::io::image::FlowImage;
    use crate::segment::{ClassicalSegmenter, SegmenterParams};
    use crate::sim::{Layout, SimConfig, SimRig, SimScene};
    use core::cell::RefCell;

    /// The built-in flow, remembering the hint of every call (`None`: no hint).
    struct Recording {
        dis: DisFlow,
        hints: RefCell<Vec<Option<[f32; 2]>>>,
    }

    impl FlowEstimator for Recording {
        fn estimate(
            &self,
            first: ImageView<'_, [u8; 3]>,
            second: ImageView<'_, [u8; 3]>,
        ) -> Result<FlowImage, FlowError> {
            self.hints.borrow_mut().push(None);
            self.dis.estimate(first, second)
        }

        fn estimate_with_hint(
            &self,
            first: ImageView<'_, [u8; 3]>,
            second: ImageView<'_, [u8; 3]>,
            hint_px: [f32; 2],
        ) -> Result<FlowImage, FlowError> {
            self.hints.borrow_mut().push(Some(hint_px));
            self.dis.estimate_with_hint(first, second, hint_px)
        }
    }

    #[test]
    fn every_push_hands_its_image_motion_to_the_next_flow() {
        // Packed sim seed 6955321884595669168: its first push moves two boxes about 28 px
        // along (0.76, 0.65); the push's own line in the image is (0.41, 0.91).
        let sim = SimScene::with_config(
            6_955_321_884_595_669_168,
            SimConfig::D415.with_layout(Layout::Packed),
        )
        .unwrap();
        let mut rig = SimRig::new(sim);
        let flow = Recording {
            dis: DisFlow::new(FlowParams::MEDIUM).unwrap(),
            hints: RefCell::default(),
        };
        let mut tracker = Tracker::new(
            ClassicalSegmenter::new(SegmenterParams::default()).unwrap(),
            flow,
            Config::PAPER,
        )
        .unwrap();
        let summary = run_episode(
            &mut rig.camera,
            &mut rig.robot,
            &mut tracker,
            &rig.setup,
            |_| Ok(()),
        )
        .unwrap();
        let hints = tracker.flow_estimator().hints.borrow().clone();
        assert_eq!(hints.len(), summary.pushes.len(), "{hints:?}");
        assert!(!hints.is_empty());
        for h in &hints {
            let [x, y] = h.expect("every flow after a push has its hint");
            // A 3 cm travel at about 0.56 m is about 33 px.
            assert!((25.0..40.0).contains(&x.hypot(y)), "{hints:?}");
        }
        let [x, y] = hints[0].unwrap();
        assert!(
            (x - 13.3).abs() < 1.0 && (y - 29.9).abs() < 1.0,
            "{hints:?}"
        );
    }
}
