//! `Vec`-backed storage for riseg-core's caller-provided [`Workspace`] and
//! [`ActionScratch`], sized once for a config and image size and reused across steps (no
//! allocation per step). riseg-core itself never allocates; this is the convenience for
//! callers with a heap.

// Spelled out (not the prelude's) because riseg-core's no_std tests compile this file too.
use std::{vec, vec::Vec};

use riseg_core::{
    Config, Pose, Real, Twist,
    action::{ActionScratch, ActionScratchLen},
    frames::{BodyFrame, FrameSample},
    group::{GroupInfo, GroupScratch},
    mask::{MaskScratch, SegmentSeeds},
    pipeline::{Workspace, WorkspaceLen},
};

/// Owns every buffer of a [`Workspace`]; [`WorkspaceBuf::view`] lends them to riseg-core.
#[derive(Debug)]
pub struct WorkspaceBuf {
    len: WorkspaceLen,
    samples: Vec<FrameSample>,
    frames: Vec<BodyFrame>,
    twists: Vec<Twist>,
    frame_labels: Vec<u16>,
    frame_group: Vec<u16>,
    groups: Vec<GroupInfo>,
    pair_bin: Vec<u8>,
    parent: Vec<u32>,
    links: Vec<u32>,
    attach: Vec<u32>,
    twist_lanes: Vec<Real>,
    key: Vec<u32>,
    source: Vec<u32>,
    segment: Vec<u32>,
    queue: Vec<u32>,
    segment_size: Vec<u32>,
    segment_target: Vec<u32>,
    segment_key: Vec<u32>,
    seeds: Vec<SegmentSeeds>,
    motions: Vec<Pose>,
}

impl WorkspaceBuf {
    /// Buffers for `cfg` at `width × height` ([`WorkspaceLen::bytes`] of memory).
    #[must_use]
    pub fn new(cfg: &Config, width: usize, height: usize) -> Self {
        let len = WorkspaceLen::for_config(cfg, width, height);
        let (n, px, seg) = (len.frames, len.mask.pixels, len.mask.segments);
        Self {
            len,
            samples: vec![FrameSample::EMPTY; n],
            frames: vec![BodyFrame::EMPTY; n],
            twists: vec![Twist::ZERO; n],
            frame_labels: vec![0; n],
            frame_group: vec![0; n],
            groups: vec![GroupInfo::default(); n],
            pair_bin: vec![0; len.group.pair_bin],
            parent: vec![0; len.group.per_frame],
            links: vec![0; len.group.per_frame],
            attach: vec![0; len.group.per_frame],
            twist_lanes: vec![0.0; len.group.twist_lanes],
            key: vec![0; px],
            source: vec![0; px],
            segment: vec![0; px],
            queue: vec![0; px],
            segment_size: vec![0; seg],
            segment_target: vec![0; seg],
            segment_key: vec![0; seg],
            seeds: vec![SegmentSeeds::default(); len.mask.seeds],
            motions: vec![Pose::identity(); len.mask.motions],
        }
    }

    /// The lengths these buffers were sized for.
    #[must_use]
    pub const fn len(&self) -> &WorkspaceLen {
        &self.len
    }

    /// Lends the buffers to [`riseg_core::pipeline::update_mask`].
    pub fn view(&mut self) -> Workspace<'_> {
        Workspace {
            samples: &mut self.samples,
            frames: &mut self.frames,
            twists: &mut self.twists,
            frame_labels: &mut self.frame_labels,
            frame_group: &mut self.frame_group,
            groups: &mut self.groups,
            group: GroupScratch {
                pair_bin: &mut self.pair_bin,
                parent: &mut self.parent,
                links: &mut self.links,
                attach: &mut self.attach,
                twist_lanes: &mut self.twist_lanes,
            },
            mask: MaskScratch {
                key: &mut self.key,
                source: &mut self.source,
                segment: &mut self.segment,
                queue: &mut self.queue,
                segment_size: &mut self.segment_size,
                segment_target: &mut self.segment_target,
                segment_key: &mut self.segment_key,
                seeds: &mut self.seeds,
                motions: &mut self.motions,
            },
        }
    }
}

/// Owns the buffers of FindAction's [`ActionScratch`].
#[derive(Debug, Clone)]
pub struct ActionBuf {
    certain: Vec<Real>,
    uncertain: Vec<Real>,
    dist2: Vec<Real>,
    nearest: Vec<u32>,
    row_counts: Vec<u32>,
    runs: Vec<u32>,
    row_runs: Vec<u32>,
}

impl ActionBuf {
    /// Buffers for `cfg` at `width × height`.
    #[must_use]
    pub fn new(cfg: &Config, width: usize, height: usize) -> Self {
        let len = ActionScratchLen::for_config(cfg, width, height);
        Self {
            certain: vec![0.0; len.certain],
            uncertain: vec![0.0; len.uncertain],
            dist2: vec![0.0; len.dist2],
            nearest: vec![0; len.nearest],
            row_counts: vec![0; len.row_counts],
            runs: vec![0; len.runs],
            row_runs: vec![0; len.row_runs],
        }
    }

    /// Lends the buffers to [`riseg_core::action::find_action`].
    pub fn view(&mut self) -> ActionScratch<'_> {
        ActionScratch {
            certain: &mut self.certain,
            uncertain: &mut self.uncertain,
            dist2: &mut self.dist2,
            nearest: &mut self.nearest,
            row_counts: &mut self.row_counts,
            runs: &mut self.runs,
            row_runs: &mut self.row_runs,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_fit_what_core_checks() {
        let cfg = Config::PAPER;
        let mut buf = WorkspaceBuf::new(&cfg, 64, 48);
        let len = *buf.len();
        assert_eq!(buf.view().check(&len), Ok(()));
        let bigger = WorkspaceLen::for_config(&cfg, 65, 48);
        assert!(buf.view().check(&bigger).is_err());
    }
}
