#![doc = include_str!("../README.md")]
#![no_std]
#![deny(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod action;
pub mod camera;
mod error;
pub mod frames;
pub mod group;
pub mod image;
pub mod mask;
pub mod math;
#[cfg(test)]
mod no_panic;
pub mod pipeline;
pub mod rng;
pub mod se3;
pub mod split;
pub mod synth;
mod union_find;
// Core's tests use the host's `Vec`-backed workspace, compiled from its one source; the
// alias lets that file's `riseg_core::` paths resolve here.
#[cfg(test)]
extern crate self as riseg_core;
#[cfg(test)]
#[path = "../../host/src/rig/workspace.rs"]
mod test_workspace;

pub use camera::{Intrinsics, MAX_CAMERA_PX, MIN_FOCAL_PX};
pub use error::{Buffer, Error};
pub use image::{ImageView, ImageViewMut};
pub use math::Real;
pub use se3::{Pose, Twist};

/// Every tunable of the algorithm, with the paper's defaults in [`Config::PAPER`].
///
/// `#[non_exhaustive]`: outside the crate, start from [`Config::PAPER`] and assign fields.
///
/// With the `serde` feature, `Config` (de)serialises field by field under these names;
/// a missing field keeps its [`Config::PAPER`] value and an unknown one is an error.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(
    feature = "serde",
    derive(serde::Serialize, serde::Deserialize),
    serde(default, deny_unknown_fields)
)]
#[non_exhaustive]
pub struct Config {
    // --- CreateFrames -------------------------------------------------------------------
    /// Pixels sampled per step (paper `n`); each can be the origin of at most one frame.
    pub frame_samples: usize,
    /// Largest distance between the three points of a frame (paper `d_c`), metres. Small
    /// enough that most frames sit on one object, large enough for a usable lever arm.
    pub frame_max_side_m: Real,
    /// Smallest distance between two points of a frame, metres: below it, depth and flow
    /// noise (about 1 mm) dominates the frame's rotation.
    pub frame_min_side_m: Real,
    /// Smallest sine of the triangle's angle at the origin (0.3 ≈ 17°): flatter triangles
    /// give a poorly defined z axis.
    pub frame_min_sin: Real,
    /// Largest depth step across the four pixels used to interpolate depth at `t+1`,
    /// metres; above it the point sits on a depth edge and the frame is dropped.
    pub depth_edge_m: Real,
    /// Radius of the window whose readings are fitted by a plane to denoise the depth of
    /// a frame's points, pixels (`0`: single readings).
    pub depth_window_px: u32,
    /// Readings of the window farther than this from the point's own depth are left out
    /// of the fit (another surface), metres.
    pub depth_window_tol_m: Real,
    /// Largest change of any side of a frame's triangle between `t` and `t+1`, metres. A
    /// rigid body keeps its distances, so a larger change means flow or depth error, or a
    /// frame straddling two bodies that moved differently: the frame is dropped.
    pub frame_rigid_tol_m: Real,

    // --- Twists and GroupBFIFs ----------------------------------------------------------
    /// Length that converts rotation to distance in [`Twist::distance`], metres (about an
    /// object's size, so a rotation counts like the displacement it causes on the object).
    pub length_scale_m: Real,
    /// Noise floor: a frame whose twist norm is below it counts as static, and pairs across
    /// segments count as evidence only when both frames move. About twice the median twist
    /// noise that 0.3 mm point noise gives a 3 cm frame.
    pub static_below_m: Real,
    /// Upper end of the binned KDE of pairwise twist distances, metres; larger distances
    /// fall in the last bin (they are "different bodies" in any case).
    pub kde_range_m: Real,
    /// Gaussian kernel bandwidth of the KDE, metres (about the twist noise).
    pub kde_bandwidth_m: Real,
    /// Posterior probability of "same rigid body" above which two frames link.
    pub link_posterior: Real,
    /// Groups with fewer frames are treated as noise and seed nothing.
    pub min_group_frames: u32,

    // --- CorrectMask --------------------------------------------------------------------
    /// Segments smaller than this after intersecting the carried and static masks join
    /// their largest neighbour, pixels.
    pub min_segment_px: u32,
    /// Largest distance between observed and rigid-motion-predicted flow for a pixel to
    /// join a group while regions grow, pixels.
    pub grow_tol_px: Real,
    /// Twist distance below which two moving groups from different segments count as one
    /// body and their segments merge where they touch (over-segmentation; beyond the
    /// paper), metres; `0` turns the merge off. Off in [`Config::PAPER`]: objects pushed
    /// together move alike, and on the simulated benchmarks the merge joined touching
    /// objects that the static segmenter had right (loose seed 4, push 3: 92.5 % of
    /// objects found with it at 2 mm, 94.1 % without; no other seed of either family got
    /// worse without it).
    pub merge_twist_m: Real,

    // --- FindAction ---------------------------------------------------------------------
    /// Heatmap value from which a pixel is "certain" (paper `l_u`), 0-255.
    pub certain_from: u8,
    /// Heatmap value from which a pixel is "uncertain" (paper `l_l`); below it is table.
    pub uncertain_from: u8,
    /// Most clusters of either class: the largest k tried by the elbow method for the
    /// uncertain k-means, and the most certain clusters kept.
    pub max_clusters: usize,
    /// Pixels drawn (seeded) from each class for clustering; bounds the cost on large
    /// images.
    pub kmeans_samples: usize,
    /// Lloyd iterations per k-means run.
    pub kmeans_iters: u32,
    /// Connected certain regions that cover less than this, seen from the camera at their
    /// mean depth, are fragments and not clusters, square metres.
    pub region_min_area_m2: Real,
    /// A connected certain region whose 3-D extent along its long axis exceeds this is
    /// more than one object and is split, metres. An object's certain region is the
    /// object less its rim and uncertain bands; one of at most 7 cm stays below 7 cm.
    pub region_max_len_m: Real,
    /// Size of one object's certain region when an oversized region is split, metres:
    /// `round(L / region_cell_m)` pieces along an axis of length `L`. A packed box of
    /// 4-7 cm leaves a certain region of about 3.5-6.5 cm.
    pub region_cell_m: Real,
    /// Largest metric distance between the two certain cluster centres of a pair (paper
    /// `d_a`), metres.
    pub pair_max_m: Real,
    /// Largest metric distance from an uncertain centre to the pair's connecting segment
    /// (paper `d_b`), metres: about half an object's width, so the uncertain band is
    /// between the two objects and not beside them.
    pub uncertain_max_m: Real,
    /// Push length (paper `d_push`), metres.
    pub push_len_m: Real,
    /// Which push singles out a still-merged object (beyond the paper), as a fraction of
    /// the pair's centre spacing: a certain cluster ahead of the pushed one, on the object
    /// the push crosses, counts as carried when its centre lies off the push's line by
    /// less than this. Of all pushes of all qualifying pairs, FindAction makes the one
    /// whose predicted moved set (the pushed cluster and those it carries) splits the
    /// most pairs of clusters that share a label in the accumulated mask, then the one
    /// that carries the fewest; with no such split, the paper's choice. `0` turns this
    /// off (the paper's choice: the first qualifying pair with a push).
    pub push_carry_frac: Real,

    // --- Loop (Algorithm 1) -------------------------------------------------------------
    /// Most pushes the loop makes before it stops.
    pub max_pushes: u32,
    /// Seed of the in-crate PRNG; same inputs and seed give bit-identical output.
    pub seed: u64,
}

impl Config {
    /// Paper defaults (`l_u` 150, `l_l` 120, `d_a` 10 cm, `d_push` 2 cm, `n` 1000) and
    /// riseg's documented choices for what the paper leaves open.
    pub const PAPER: Self = Self {
        frame_samples: 1000,
        frame_max_side_m: 0.03,
        frame_min_side_m: 0.005,
        frame_min_sin: 0.3,
        depth_edge_m: 0.01,
        depth_window_px: 2,
        depth_window_tol_m: 0.003,
        frame_rigid_tol_m: 0.004,
        length_scale_m: 0.05,
        static_below_m: 0.005,
        kde_range_m: 0.08,
        kde_bandwidth_m: 0.001,
        link_posterior: 0.5,
        min_group_frames: 5,
        min_segment_px: 150,
        grow_tol_px: 2.0,
        merge_twist_m: 0.0,
        certain_from: 150,
        uncertain_from: 120,
        max_clusters: 8,
        kmeans_samples: 2000,
        kmeans_iters: 20,
        region_min_area_m2: 0.5e-4,
        region_max_len_m: 0.08,
        region_cell_m: 0.05,
        pair_max_m: 0.10,
        uncertain_max_m: 0.03,
        push_len_m: 0.02,
        push_carry_frac: 0.6,
        max_pushes: 3,
        seed: 0,
    };

    /// Checks every field against its documented range.
    ///
    /// # Errors
    /// [`Error::BadConfig`] naming no field (the enum carries no strings): a length is not
    /// finite and positive, a count is zero, `uncertain_from >= certain_from`, or
    /// `link_posterior` is outside `(0, 1)`, or `push_carry_frac` is outside `[0, 2]`.
    pub fn check(&self) -> Result<(), Error> {
        let lengths = [
            self.frame_max_side_m,
            self.depth_edge_m,
            self.depth_window_tol_m,
            self.frame_rigid_tol_m,
            self.length_scale_m,
            self.static_below_m,
            self.kde_range_m,
            self.kde_bandwidth_m,
            self.grow_tol_px,
            self.pair_max_m,
            self.uncertain_max_m,
            self.region_min_area_m2,
            self.region_max_len_m,
            self.region_cell_m,
            self.push_len_m,
        ];
        let ok = lengths.iter().all(|v| v.is_finite() && *v > 0.0)
            && self.frame_min_side_m.is_finite()
            && (0.0..self.frame_max_side_m).contains(&self.frame_min_side_m)
            && self.frame_min_sin.is_finite()
            && (0.0..1.0).contains(&self.frame_min_sin)
            && self.merge_twist_m.is_finite()
            && self.merge_twist_m >= 0.0
            && self.push_carry_frac.is_finite()
            && (0.0..=2.0).contains(&self.push_carry_frac)
            && self.link_posterior > 0.0
            && self.link_posterior < 1.0
            && self.frame_samples >= 3
            && self.frame_samples <= u32::MAX as usize / 4
            && self.depth_window_px <= 8
            && self.max_clusters >= 2
            && self.max_clusters <= MAX_CLUSTERS
            && self.kmeans_samples >= self.max_clusters
            && self.kmeans_iters > 0
            && self.uncertain_from < self.certain_from;
        if ok { Ok(()) } else { Err(Error::BadConfig) }
    }
}

impl Default for Config {
    fn default() -> Self {
        Self::PAPER
    }
}

/// The source text of this file: tools that show [`Config`]'s field docs at run time
/// (`riseg config --print`) read them here, so the docs are written once.
#[doc(hidden)]
pub const CONFIG_SOURCE: &str = include_str!("lib.rs");

/// Capacity bound of [`Config::max_clusters`] (fixed-size arrays in FindAction).
pub const MAX_CLUSTERS: usize = 16;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_config_is_valid_and_checks_reject_bad_fields() {
        assert_eq!(Config::PAPER.check(), Ok(()));
        let mut c = Config::PAPER;
        c.uncertain_from = 200;
        assert_eq!(c.check(), Err(Error::BadConfig));
        let mut c = Config::PAPER;
        c.push_len_m = f32::NAN;
        assert_eq!(c.check(), Err(Error::BadConfig));
        let mut c = Config::PAPER;
        c.max_clusters = MAX_CLUSTERS + 1;
        assert_eq!(c.check(), Err(Error::BadConfig));
    }
}
