//! The perception half of Algorithm 1: static segmentation, optical flow and riseg-core's
//! UpdateMask, frame after frame, with the time each stage took.
//!
//! # Contract
//!
//! [`Tracker::observe`] takes the frames of one scene in order. The first frame's mask is
//! the static segmentation; every later frame's mask is UpdateMask of the previous mask,
//! the flow from the previous colour image and the new static segmentation. The tracker
//! keeps the previous frame and mask and nothing else: the same frames give the same masks
//! (the segmenter, the flow and the core are deterministic for their seeds). Frames of one
//! scene must share one size; a new scene starts with [`Tracker::reset`].
//!
//! [`Tracker::observe_given`] is the same step with the static segmentation, the flow or
//! both supplied by the caller ([`GivenInputs`]: computed elsewhere, such as MSMFormer
//! labels or RAFT flow read from files, or the simulator's exact flow); the tracker's own
//! segmenter or flow estimator runs only for what is not given. It is the one code path:
//! `observe` is `observe_given` with nothing given. A given segmentation or flow must be
//! the frame's size; flow can only be given for a frame that has a previous one. Unknown
//! flow is NaN (see [`crate::flow::is_known_flow`]): riseg-core neither tracks a body frame
//! through it nor carries a label along it.
//!
//! The core's buffers are sized on the first frame and reused (no allocation per step in
//! the core; the host allocates the flow field and the returned masks).
//!
//! [`Tracker::from_settings`] is the tracker every command runs ([`Settings`]: the built-in
//! segmenter and flow). A caller that times or shows the stages one by one (the browser
//! demo) runs [`Tracker::segmenter_mut`] and [`Tracker::flow_estimator`] itself, exactly as
//! `observe` would call them, and hands their outputs to [`Tracker::observe_given`]: the
//! masks are the same as `observe`'s, bit for bit.

use riseg_core::{
    Config, ImageView,
    frames::{BodyFrame, MotionInput},
    group::NO_GROUP,
    pipeline::{Stage, StepReport, update_mask_observed},
};

use crate::{
    flow::{DisFlow, FlowError, FlowEstimator, FlowParams},
    io::image::FlowImage,
    rig::camera::CameraFrame,
    rig::workspace::WorkspaceBuf,
    segment::{ClassicalSegmenter, SegmentError, Segmentation, SegmenterParams, StaticSegmenter},
};

/// The settings of everything that runs the algorithm (`riseg demo`, `bench`, `run`, the
/// browser demo), and what a settings file sets (`riseg --config`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// riseg-core's settings, `[core]`.
    pub core: Config,
    /// The built-in static segmenter's settings, `[segmenter]`.
    pub segmenter: SegmenterParams,
    /// The built-in optical flow's settings, `[flow]`.
    pub flow: FlowParams,
}

impl Default for Settings {
    /// [`Config::PAPER`], [`SegmenterParams::default`] and [`FlowParams::MEDIUM`]: what
    /// every command runs without `--config`.
    fn default() -> Self {
        Self {
            core: Config::PAPER,
            segmenter: SegmenterParams::default(),
            flow: FlowParams::MEDIUM,
        }
    }
}

/// Why a tracker step failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TrackError {
    /// The static segmenter failed.
    #[error("static segmentation: {0}")]
    Segment(#[from] SegmentError),
    /// The optical flow failed.
    #[error("optical flow: {0}")]
    Flow(#[from] FlowError),
    /// riseg-core refused the step.
    #[error("riseg-core: {0}")]
    Core(#[from] riseg_core::Error),
    /// The colour and depth images differ in size, or the frame differs from the previous.
    #[error("frame is {got:?} pixels (colour) but {expected:?} was expected ({what})")]
    FrameSize {
        /// Expected `(width, height)`.
        expected: (usize, usize),
        /// Found `(width, height)`.
        got: (usize, usize),
        /// Which comparison failed.
        what: &'static str,
    },
    /// A given static segmentation or flow is not the frame's size.
    #[error("the given {what} is {got:?} pixels but the frame is {expected:?}")]
    GivenSize {
        /// The frame's `(width, height)`.
        expected: (usize, usize),
        /// The given input's `(width, height)`.
        got: (usize, usize),
        /// "static segmentation" or "flow".
        what: &'static str,
    },
    /// A flow was given for a scene's first frame, which has no previous frame.
    #[error("a flow was given for the scene's first frame, which has no previous frame")]
    FlowWithoutPrevious,
}

/// Inputs of one frame that the caller already has; the tracker computes what is `None`
/// (module docs).
#[derive(Debug, Clone, Default)]
pub struct GivenInputs {
    /// The frame's static segmentation, instead of the tracker's segmenter.
    pub static_seg: Option<Segmentation>,
    /// The flow from the previous frame's colour image to this one's, instead of the
    /// tracker's estimator; NaN where unknown.
    pub flow: Option<FlowImage>,
}

/// Milliseconds each stage of one frame took (zero for stages that did not run, such as
/// flow on the first frame or a stage whose output was given).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// Static segmentation.
    pub segment_ms: f64,
    /// Optical flow from the previous frame.
    pub flow_ms: f64,
    /// CreateFrames.
    pub frames_ms: f64,
    /// CalcBFIFs.
    pub twists_ms: f64,
    /// GroupBFIFs.
    pub grouping_ms: f64,
    /// CorrectMask.
    pub mask_ms: f64,
}

impl StageTimes {
    /// The stage names, in the order of [`StageTimes::values`].
    pub const NAMES: [&'static str; 6] =
        ["segment", "flow", "frames", "twists", "grouping", "mask"];

    /// The six times in the order of [`StageTimes::NAMES`].
    #[must_use]
    pub const fn values(&self) -> [f64; 6] {
        [
            self.segment_ms,
            self.flow_ms,
            self.frames_ms,
            self.twists_ms,
            self.grouping_ms,
            self.mask_ms,
        ]
    }
}

/// A sampled body frame and the twist group it joined, for display.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroupedFrame {
    /// The frame (pixel and metric corners at `t` and `t+1`).
    pub frame: BodyFrame,
    /// Index of its group, or `None` when it joined none.
    pub group: Option<u16>,
    /// Whether its group moved (non-zero twist).
    pub moving: bool,
}

/// What UpdateMask did between the previous frame and this one.
#[derive(Debug, Clone)]
pub struct StepDetail {
    /// Flow from the previous colour image to this one.
    pub flow: FlowImage,
    /// The core's report, stage by stage.
    pub report: StepReport,
    /// The body frames of the step with their groups.
    pub frames: Vec<GroupedFrame>,
}

/// The tracker's output for one frame.
#[derive(Debug, Clone)]
pub struct Observation {
    /// The static segmenter's labels and heatmap for this frame.
    pub static_seg: Segmentation,
    /// The accumulated (RISeg) mask for this frame, row-major, 0 = background.
    pub mask: Vec<u16>,
    /// The UpdateMask step that produced `mask`; `None` on a scene's first frame.
    pub step: Option<StepDetail>,
    /// Time per stage.
    pub times: StageTimes,
}

#[derive(Debug)]
struct Previous {
    frame: CameraFrame,
    mask: Vec<u16>,
}

/// Static segmenter + flow + UpdateMask over the frames of one scene (module docs).
#[derive(Debug)]
pub struct Tracker<S, F> {
    segmenter: S,
    flow: F,
    cfg: Config,
    workspace: Option<(usize, usize, WorkspaceBuf)>,
    previous: Option<Previous>,
    /// The motion hint for the next frame's flow ([`Tracker::expect_motion_px`]).
    flow_hint: Option<[f32; 2]>,
}

impl Tracker<ClassicalSegmenter, DisFlow> {
    /// The built-in segmenter and flow with `settings`: what `riseg run` runs.
    ///
    /// # Errors
    /// [`TrackError`] naming the stage whose settings are invalid.
    pub fn from_settings(settings: &Settings) -> Result<Self, TrackError> {
        Self::new(
            ClassicalSegmenter::new(settings.segmenter)?,
            DisFlow::new(settings.flow)?,
            settings.core,
        )
    }
}

impl<S: StaticSegmenter, F: FlowEstimator> Tracker<S, F> {
    /// A tracker with these stages and riseg-core settings.
    ///
    /// # Errors
    /// [`TrackError::Core`] if `cfg` is invalid.
    pub fn new(segmenter: S, flow: F, cfg: Config) -> Result<Self, TrackError> {
        cfg.check()?;
        Ok(Self {
            segmenter,
            flow,
            cfg,
            workspace: None,
            previous: None,
            flow_hint: None,
        })
    }

    /// The riseg-core settings.
    #[must_use]
    pub const fn config(&self) -> &Config {
        &self.cfg
    }

    /// The static segmenter [`Tracker::observe`] runs (module docs).
    pub fn segmenter_mut(&mut self) -> &mut S {
        &mut self.segmenter
    }

    /// The flow estimator [`Tracker::observe`] runs (module docs).
    #[must_use]
    pub const fn flow_estimator(&self) -> &F {
        &self.flow
    }

    /// Forgets the previous frame: the next frame starts a new scene.
    pub fn reset(&mut self) {
        self.previous = None;
        self.flow_hint = None;
    }

    /// Tells the tracker that part of the scene should appear moved by about `hint_px`
    /// (`[dx, dy]`, pixels) in the next frame: the image motion of the push just made
    /// ([`crate::rig::episode::push_motion_px`]). The next [`Tracker::observe`] passes it
    /// to the flow estimator ([`FlowEstimator::estimate_with_hint`]) and forgets it;
    /// `None` forgets it now.
    pub fn expect_motion_px(&mut self, hint_px: Option<[f32; 2]>) {
        self.flow_hint = hint_px;
    }

    /// The last frame observed, if any: after [`Tracker::observe`] returns `Ok`, the frame
    /// it was given (lent back, so the caller need not keep a copy).
    #[must_use]
    pub fn last_frame(&self) -> Option<&CameraFrame> {
        self.previous.as_ref().map(|p| &p.frame)
    }

    /// The accumulated mask of the last frame observed, if any.
    #[must_use]
    pub fn last_mask(&self) -> Option<&[u16]> {
        self.previous.as_ref().map(|p| p.mask.as_slice())
    }

    /// Segments `frame`, and unless it is the scene's first, carries the mask forward to it
    /// (module docs). On error the tracker keeps its previous frame and mask.
    ///
    /// # Errors
    /// [`TrackError`] naming the stage that failed, or the size that does not match.
    pub fn observe(&mut self, frame: CameraFrame) -> Result<Observation, TrackError> {
        self.observe_given(frame, GivenInputs::default())
    }

    /// [`Tracker::observe`] with the static segmentation and/or the flow `given` (module
    /// docs). On error the tracker keeps its previous frame and mask.
    ///
    /// # Errors
    /// As [`Tracker::observe`]; [`TrackError::GivenSize`] if a given input is not the
    /// frame's size, [`TrackError::FlowWithoutPrevious`] if a flow is given for a scene's
    /// first frame.
    pub fn observe_given(
        &mut self,
        frame: CameraFrame,
        given: GivenInputs,
    ) -> Result<Observation, TrackError> {
        let (w, h) = frame.size();
        let depth_size = frame.depth_m.size();
        if depth_size != (w, h) {
            return Err(TrackError::FrameSize {
                expected: depth_size,
                got: (w, h),
                what: "colour against depth",
            });
        }
        if let Some(prev) = &self.previous
            && prev.frame.size() != (w, h)
        {
            return Err(TrackError::FrameSize {
                expected: prev.frame.size(),
                got: (w, h),
                what: "against the previous frame",
            });
        }
        let given_size = |what, got| {
            if got == (w, h) {
                Ok(())
            } else {
                Err(TrackError::GivenSize {
                    expected: (w, h),
                    got,
                    what,
                })
            }
        };
        if let Some(seg) = &given.static_seg {
            given_size("static segmentation", seg.size())?;
        }
        if let Some(flow) = &given.flow {
            given_size("flow", (flow.width(), flow.height()))?;
            if self.previous.is_none() {
                return Err(TrackError::FlowWithoutPrevious);
            }
        }
        let mut times = StageTimes::default();
        let static_seg = match given.static_seg {
            Some(seg) => seg,
            None => {
                let clock = Stopwatch::start();
                let seg = self.segmenter.segment(&frame.rgbd()?, &frame.intrinsics)?;
                times.segment_ms = clock.ms();
                seg
            }
        };

        let Some(prev) = &self.previous else {
            let mask = static_seg.labels.as_slice().to_vec();
            self.previous = Some(Previous {
                frame,
                mask: mask.clone(),
            });
            return Ok(Observation {
                static_seg,
                mask,
                step: None,
                times,
            });
        };

        let hint = self.flow_hint.take();
        let flow = match given.flow {
            Some(flow) => flow,
            None => {
                let clock = Stopwatch::start();
                let (a, b) = (prev.frame.rgb.view(), frame.rgb.view());
                let flow = match hint {
                    Some(h) => {
                        log::debug!("flow with the motion hint ({}, {}) px", h[0], h[1]);
                        self.flow.estimate_with_hint(a, b, h)?
                    }
                    None => self.flow.estimate(a, b)?,
                };
                times.flow_ms = clock.ms();
                flow
            }
        };

        let (ws_w, ws_h, ws) = match self.workspace.take() {
            Some(sized) if (sized.0, sized.1) == (w, h) => sized,
            _ => (w, h, WorkspaceBuf::new(&self.cfg, w, h)),
        };
        let ws = self.workspace.insert((ws_w, ws_h, ws));
        let input = MotionInput::new(
            ImageView::packed(w, h, &prev.mask)?,
            prev.frame.depth_m.view(),
            frame.depth_m.view(),
            flow.view(),
            frame.intrinsics,
        )?;
        let static_t1 = static_seg.labels.view();
        let mut mask = vec![0u16; w * h];
        let mut view = ws.2.view();
        let mut stage_clock = Stopwatch::start();
        let report = update_mask_observed(
            &input,
            &static_t1,
            &self.cfg,
            &mut view,
            &mut mask,
            |stage| {
                let spent = stage_clock.ms();
                match stage {
                    Stage::Frames => times.frames_ms = spent,
                    Stage::Twists => times.twists_ms = spent,
                    Stage::Grouping => times.grouping_ms = spent,
                    Stage::Mask => times.mask_ms = spent,
                }
                stage_clock = Stopwatch::start();
            },
        )?;
        let count = report.frames.count;
        let groups = view.groups.get(..report.grouping.count).unwrap_or(&[]);
        let frames = view
            .frames
            .iter()
            .zip(view.frame_group.iter())
            .take(count)
            .map(|(f, &g)| {
                let info = (g != NO_GROUP)
                    .then(|| groups.get(usize::from(g)))
                    .flatten();
                GroupedFrame {
                    frame: *f,
                    group: info.map(|_| g),
                    moving: info.is_some_and(|i| i.moving),
                }
            })
            .collect();
        self.previous = Some(Previous {
            frame,
            mask: mask.clone(),
        });
        Ok(Observation {
            static_seg,
            mask,
            step: Some(StepDetail {
                flow,
                report,
                frames,
            }),
            times,
        })
    }
}

/// Wall-clock time of a stage. `std::time::Instant` panics on wasm32-unknown-unknown, so
/// there every stage reads 0 ms: in the browser, timing is the caller's.
#[derive(Clone, Copy)]
struct Stopwatch {
    #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
    start: std::time::Instant,
}

impl Stopwatch {
    fn start() -> Self {
        Self {
            #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
            start: std::time::Instant::now(),
        }
    }

    /// Milliseconds since [`Stopwatch::start`].
    #[cfg(not(all(target_arch = "wasm32", target_os = "unknown")))]
    fn ms(self) -> f64 {
        self.start.elapsed().as_secs_f64() * 1e3
    }

    #[cfg(all(target_arch = "wasm32", target_os = "unknown"))]
    #[allow(clippy::unused_self)]
    fn ms(self) -> f64 {
        0.0
    }
}
