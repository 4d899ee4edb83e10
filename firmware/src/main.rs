//! Bare-metal riseg-core: one UpdateMask step at 160×120 on a Cortex-M4F, from static
//! buffers, with no allocator linked (the crate is built with `-Z build-std=core` only).
//!
//! Runs under `qemu-system-arm -M mps2-an386 -icount shift=0` with semihosting (see
//! `run.sh`): renders the testkit's touching-boxes step with riseg-core's `synth`, runs
//! [`update_mask`] with [`Config::PAPER`] over a [`Workspace`] of `static` arrays sized by
//! [`WorkspaceLen::for_config`], and prints the input and output digests (the line
//! `determinism/` prints for the same step computed natively with `riseg`'s testkit), the step report's
//! counts, the instructions each part took (see [`clock`]), the workspace size and the
//! deepest stack use (see [`stack`]). Exits 0 on success and 1 on any error.

#![no_std]
#![no_main]

mod clock;
#[path = "../../determinism/src/digest.rs"]
mod digest;
mod scene;
mod stack;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use riseg_core::{
    Config, Error, ImageView, Pose, Twist,
    frames::{BodyFrame, FrameSample, MotionInput},
    group::{GroupInfo, GroupScratch},
    mask::{MaskScratch, SegmentSeeds},
    pipeline::{Stage, StepReport, Workspace, WorkspaceLen, update_mask_observed},
};

use crate::{
    clock::{ClockError, InsnClock},
    scene::StepImages,
};

/// Image width, pixels.
const WIDTH: usize = 160;
/// Image height, pixels.
const HEIGHT: usize = 120;
/// Pixels per image.
const PIXELS: usize = WIDTH * HEIGHT;
/// The step's configuration.
const CFG: Config = Config::PAPER;
/// Element counts of every workspace slice, from riseg-core's own length query.
const LEN: WorkspaceLen = WorkspaceLen::for_config(&CFG, WIDTH, HEIGHT);
/// Frames (samples) per step.
const N: usize = LEN.frames;

// Scratch contents do not matter on entry (riseg-core writes before it reads, as hosts
// reuse one workspace for every step), so every array starts all-zero and lands in .bss:
// no flash is spent on initial values.
const ZERO_POSE: Pose = Isometry3::from_parts(
    Translation3::new(0.0, 0.0, 0.0),
    UnitQuaternion::new_unchecked(Quaternion::new(0.0, 0.0, 0.0, 0.0)),
);
const ZERO_GROUP: GroupInfo = GroupInfo {
    frames: 0,
    twist: Twist::ZERO,
    moving: false,
    label: 0,
};
const ZERO_SEEDS: SegmentSeeds = SegmentSeeds {
    segment: 0,
    group: 0,
    seeds: 0,
    label: 0,
};

/// Why the run failed.
#[derive(Debug, Clone, Copy)]
enum Failure {
    /// riseg-core refused the step.
    Core(Error),
    /// The instruction count cannot be trusted.
    Clock(ClockError),
}

impl core::fmt::Display for Failure {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Core(e) => write!(f, "riseg-core: {e}"),
            Self::Clock(e) => write!(f, "instruction clock: {e}"),
        }
    }
}

impl From<Error> for Failure {
    fn from(e: Error) -> Self {
        Self::Core(e)
    }
}

impl From<ClockError> for Failure {
    fn from(e: ClockError) -> Self {
        Self::Clock(e)
    }
}

/// Instructions each part took.
#[derive(Debug, Default)]
struct Counts {
    scene: u64,
    step: u64,
    /// Readings after CreateFrames, CalcBFIFs, GroupBFIFs and CorrectMask.
    stages: [u64; 4],
}

#[entry]
fn main() -> ! {
    static mut DEPTH_T: [f32; PIXELS] = [0.0; PIXELS];
    static mut DEPTH_T1: [f32; PIXELS] = [0.0; PIXELS];
    static mut MERGED_T: [u16; PIXELS] = [0; PIXELS];
    static mut MERGED_T1: [u16; PIXELS] = [0; PIXELS];
    static mut FLOW: [[f32; 2]; PIXELS] = [[0.0; 2]; PIXELS];
    static mut LABELS_T1: [u16; PIXELS] = [0; PIXELS];
    static mut SAMPLES: [FrameSample; N] = [FrameSample::EMPTY; N];
    static mut FRAMES: [BodyFrame; N] = [BodyFrame::EMPTY; N];
    static mut TWISTS: [Twist; N] = [Twist::ZERO; N];
    static mut FRAME_LABELS: [u16; N] = [0; N];
    static mut FRAME_GROUP: [u16; N] = [0; N];
    static mut GROUPS: [GroupInfo; N] = [ZERO_GROUP; N];
    static mut PAIR_BIN: [u8; LEN.group.pair_bin] = [0; LEN.group.pair_bin];
    static mut PARENT: [u32; LEN.group.per_frame] = [0; LEN.group.per_frame];
    static mut LINKS: [u32; LEN.group.per_frame] = [0; LEN.group.per_frame];
    static mut ATTACH: [u32; LEN.group.per_frame] = [0; LEN.group.per_frame];
    static mut TWIST_LANES: [f32; LEN.group.twist_lanes] = [0.0; LEN.group.twist_lanes];
    static mut KEY: [u32; LEN.mask.pixels] = [0; LEN.mask.pixels];
    static mut SOURCE: [u32; LEN.mask.pixels] = [0; LEN.mask.pixels];
    static mut SEGMENT: [u32; LEN.mask.pixels] = [0; LEN.mask.pixels];
    static mut QUEUE: [u32; LEN.mask.pixels] = [0; LEN.mask.pixels];
    static mut SEGMENT_SIZE: [u32; LEN.mask.segments] = [0; LEN.mask.segments];
    static mut SEGMENT_TARGET: [u32; LEN.mask.segments] = [0; LEN.mask.segments];
    static mut SEGMENT_KEY: [u32; LEN.mask.segments] = [0; LEN.mask.segments];
    static mut SEEDS: [SegmentSeeds; LEN.mask.seeds] = [ZERO_SEEDS; LEN.mask.seeds];
    static mut MOTIONS: [Pose; LEN.mask.motions] = [ZERO_POSE; LEN.mask.motions];

    hprintln!(
        "riseg-firmware: UpdateMask {}x{}, Config::PAPER, workspace {} bytes (WorkspaceLen::bytes)",
        WIDTH,
        HEIGHT,
        LEN.bytes()
    );
    let Some(peripherals) = cortex_m::Peripherals::take() else {
        hprintln!("error: core peripherals already taken");
        exit(false)
    };
    let mut clock = InsnClock::new(peripherals.SYST);
    match clock.calibrate() {
        Ok(insns) => hprintln!(
            "calibration: 2000002-instruction loop read as {} instructions",
            insns
        ),
        Err(e) => {
            hprintln!("error: {}", Failure::from(e));
            exit(false)
        }
    }

    let mut images = StepImages {
        depth_t: DEPTH_T,
        depth_t1: DEPTH_T1,
        merged_t: MERGED_T,
        merged_t1: MERGED_T1,
        flow: FLOW,
    };
    let mut ws = Workspace {
        samples: SAMPLES,
        frames: FRAMES,
        twists: TWISTS,
        frame_labels: FRAME_LABELS,
        frame_group: FRAME_GROUP,
        groups: GROUPS,
        group: GroupScratch {
            pair_bin: PAIR_BIN,
            parent: PARENT,
            links: LINKS,
            attach: ATTACH,
            twist_lanes: TWIST_LANES,
        },
        mask: MaskScratch {
            key: KEY,
            source: SOURCE,
            segment: SEGMENT,
            queue: QUEUE,
            segment_size: SEGMENT_SIZE,
            segment_target: SEGMENT_TARGET,
            segment_key: SEGMENT_KEY,
            seeds: SEEDS,
            motions: MOTIONS,
        },
    };
    let mut counts = Counts::default();
    match step(&mut clock, &mut images, &mut ws, LABELS_T1, &mut counts) {
        Ok(report) => {
            print_result(&images, LABELS_T1, &report, &counts);
            exit(true)
        }
        Err(e) => {
            hprintln!("error: {}", e);
            exit(false)
        }
    }
}

/// Renders the inputs, then runs the step; fills `counts`.
fn step(
    clock: &mut InsnClock,
    images: &mut StepImages<'_>,
    ws: &mut Workspace<'_>,
    labels_t1: &mut [u16],
    counts: &mut Counts,
) -> Result<StepReport, Failure> {
    let (rendered, insns) = clock.measure(|| scene::touching_boxes(WIDTH, HEIGHT, images))?;
    let intrinsics = rendered?;
    counts.scene = insns;
    let input = MotionInput::new(
        ImageView::packed(WIDTH, HEIGHT, &*images.merged_t)?,
        ImageView::packed(WIDTH, HEIGHT, &*images.depth_t)?,
        ImageView::packed(WIDTH, HEIGHT, &*images.depth_t1)?,
        ImageView::packed(WIDTH, HEIGHT, &*images.flow)?,
        intrinsics,
    )?;
    let static_t1 = ImageView::packed(WIDTH, HEIGHT, &*images.merged_t1)?;
    let stages = &mut counts.stages;
    let (report, insns) = clock.measure(|| {
        update_mask_observed(&input, &static_t1, &CFG, ws, labels_t1, |stage| {
            let i = match stage {
                Stage::Frames => 0,
                Stage::Twists => 1,
                Stage::Grouping => 2,
                Stage::Mask => 3,
            };
            if let Some(s) = stages.get_mut(i) {
                *s = InsnClock::since_start();
            }
        })
    })?;
    counts.step = insns;
    Ok(report?)
}

fn print_result(images: &StepImages<'_>, labels_t1: &[u16], report: &StepReport, counts: &Counts) {
    // The line `determinism/` prints natively: run.sh compares them.
    hprintln!(
        "input {:016x} output {:016x}",
        digest::input(
            images.depth_t,
            images.depth_t1,
            images.flow,
            images.merged_t,
            images.merged_t1
        ),
        digest::output(labels_t1, report)
    );
    hprintln!(
        "report: {} frames from {} samples, {} groups ({} from mixed splits), {} segments ({} split, {} merged), max label {}",
        report.frames.count,
        report.frames.sampled,
        report.grouping.count,
        report.grouping.mixed_splits,
        report.mask.segments,
        report.mask.split_segments,
        report.mask.merged_segments,
        report.mask.max_label
    );
    let mut pixels = [0u32; 8];
    for &l in labels_t1 {
        if let Some(p) = pixels.get_mut(usize::from(l)) {
            *p += 1;
        }
    }
    hprintln!("pixels per label 0..7: {:?}", pixels);
    let [frames, twists, grouping, mask] = counts.stages;
    hprintln!(
        "instructions: update_mask {} (frames {}, twists {}, grouping {}, mask {}); scene render {}",
        counts.step,
        frames,
        twists.saturating_sub(frames),
        grouping.saturating_sub(twists),
        mask.saturating_sub(grouping),
        counts.scene
    );
    hprintln!("stack: {} bytes at its deepest", stack::high_water_bytes());
}

/// Ends the QEMU run through semihosting with exit status 0 or 1.
fn exit(success: bool) -> ! {
    debug::exit(if success {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
    hprintln!("panic: {}", info);
    exit(false)
}
