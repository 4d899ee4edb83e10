//! FindAction (paper Algorithm 2): one small push between two "certain" object regions
//! that have an "uncertain" region between them.
//!
//! # Contract
//!
//! [`find_action`] reads a 0-255 heatmap (high = surely inside an object), a depth image
//! and the current mask (the accumulated labels; at the first frame the static
//! segmentation) of the same size, and returns an [`ActionReport`]: the cluster centres it
//! found (for display), the chosen pair of certain clusters, and the push, if any. The
//! push is the one the robot makes: where it starts, which way, how far (camera frame);
//! the host only maps it into the robot frame and checks the arm's limits. It writes only
//! the caller's [`ActionScratch`], allocates nothing, never panics, and gives bit-identical
//! reports for the same inputs and [`Config::seed`].
//!
//! # Steps
//!
//! 1. **Classes.** A pixel is *certain* when `heatmap >= certain_from` (paper `l_u`),
//!    *uncertain* when `uncertain_from <= heatmap < certain_from` (paper `l_l`), and
//!    *table* below. Only pixels with a depth reading ([`valid_depth`](crate::image::valid_depth)) are sampled.
//! 2. **Samples.** Up to [`Config::kmeans_samples`] pixels of each class are drawn by
//!    systematic sampling over the class's pixels in row-major order, with a seeded random
//!    offset: every class pixel has the same chance and no sort is needed. One vectorised
//!    pass counts each row's class pixels; a second pass reads pixel by pixel only the
//!    rows that hold a kept sample.
//! 3. **Certain regions.** The 4-connected regions of certain pixels (depth is not
//!    consulted, so a hole in the depth does not split an object), labelled as runs of
//!    certain pixels per row with union-find: a run joins the runs of the row above whose
//!    x ranges overlap, and a region's root is its first run in row-major order. An
//!    uncertain line one pixel wide, in any direction, separates two regions, so the
//!    uncertain bands and cut lines of the heatmap split certain pixels into object
//!    candidates. The [`MAX_CLUSTERS`] regions with the most pixels (ties: the earlier
//!    root) are the candidates, in the order of their roots; other regions are ignored.
//! 4. **Certain clusters.** Each certain sample belongs to the region of its pixel. For a
//!    candidate with at least one sample, with `z̄` the mean depth of its samples'
//!    back-projected points (camera frame, metres):
//!    - its *area* is its pixel count times `z̄² / (fx·fy)` (as seen from the camera); a
//!      region smaller than [`Config::region_min_area_m2`] is a fragment and gives no
//!      cluster;
//!    - its *lengths* `L₁ ≥ L₂` are `√(12 λ)` for the two largest eigenvalues `λ` of the
//!      covariance of those 3-D points (a uniform rectangle of side `L` has variance
//!      `L²/12` along it). A region with `L₁ <=` [`Config::region_max_len_m`] (or whose
//!      covariance is not finite, or whose eigen-solve does not converge) is one
//!      cluster: pixel centre the mean of its samples' pixels, 3-D centre the mean of
//!      their points;
//!    - a longer region is more than one object and is split into `n₁ × n₂` pieces,
//!      `n₁ = round(L₁ / region_cell_m)` clamped to `2..=5` and `n₂ = round(L₂ /
//!      region_cell_m)` clamped to `1..=2` and to at most `6 / n₁` (a 2 × 3 pack is
//!      six pieces, a row of five five). The pieces start at
//!      the cell centres of an `n₁ × n₂` grid laid along the principal axes of the
//!      samples' pixels (spanning `√(12 λ)` pixels along each axis) and are refined by
//!      Lloyd iterations over the region's samples in pixel coordinates (stopping rule of
//!      step 5, at most [`Config::kmeans_iters`] updates). Inside one region, at about one
//!      depth, this partition is the metric one; the metric lengths choose how many
//!      pieces. Each non-empty piece is a cluster: pixel centre the final centre, 3-D
//!      centre the mean of its members' points.
//!
//!    When there are more than [`Config::max_clusters`] clusters, those with the most
//!    samples (ties: the earlier) are kept; clusters keep their regions' order, pieces
//!    their grid order. A cluster's `samples` are its sampled pixels.
//! 5. **Uncertain clusters: k-means** in pixel coordinates, for every `k` in `1..=K`,
//!    `K = min(max_clusters, samples)`, each run warm-started from the previous one:
//!    `k = 1` starts from a seeded random sample; `k` keeps the converged centres of
//!    `k − 1` and adds one greedy k-means++ centre (the best, by resulting inertia, of
//!    `2 + ⌊ln k⌋` candidates drawn with probability proportional to the squared distance
//!    to the nearest centre). Lloyd iterations follow until an update would move the
//!    centres by less than 0.25 px in total (root of the summed squared shifts; the
//!    centres that made the last assignment are kept) or [`Config::kmeans_iters`] updates
//!    were made. A `k` for which no sample lies off the current centres ends the series.
//!    Plain k-means++ restarted for every `k` often lands in poor local minima and makes
//!    the inertia curve bumpy; the greedy, incremental seeding keeps it smooth.
//! 6. **Elbow**: Kneedle on the log-inertia curve. With `L(k) = ln(W(k) + n/6)` (`W` the
//!    inertia in pixels², `n/6` the inertia of pixel quantisation, so a perfect fit stays
//!    finite) and both axes normalised to `[0, 1]` (`x = (k−1)/(K−1)`,
//!    `y = (L(k) − L(K))/(L(1) − L(K))`), the chosen `k` lies farthest below the chord
//!    from `k = 1` to `k = K`: the largest `1 − x − y`, ties to the smaller `k`. A curve
//!    that nowhere drops more than 0.01 below its chord has no elbow and gives `k = 1`.
//!    With `K = 2` there is no interior point: `k = 2` when it removes at least half the
//!    inertia, else `k = 1`. Each uncertain cluster's 3-D centre is the mean of its
//!    sampled members' back-projected points; clusters left without members are dropped;
//!    the pixel centre is the k-means centre.
//! 7. **Pairs** (DESIGN §3, with two more conditions). A pair of certain clusters `i, j`
//!    qualifies when
//!    - their 3-D centres are at most [`Config::pair_max_m`] (paper `d_a`) apart;
//!    - an uncertain 3-D centre lies within [`Config::uncertain_max_m`] (`d_b`) of the
//!      3-D segment between them (the nearest one is the pair's uncertain centre);
//!    - they are *relative neighbours*: no third certain centre is closer to both of them
//!      than they are to each other (in a grid of cells this keeps side neighbours and
//!      drops diagonal ones; a third object between them drops the pair);
//!    - the straight line between their pixel centres stays on object: sampled once per
//!      pixel of length, every pixel on it is in the region (step 9) of `i` or `j`,
//!      uncertain, or certain in no cluster; none is off the image or in a third
//!      cluster's region, and at most 5 mm of it (its length taken as the pair's 3-D
//!      distance) is table, which a line through the point where two rounded objects
//!      touch clips at their rims. Two objects with table between them do not touch.
//!
//!    With [`Config::push_carry_frac`] above `0` (beyond the paper) a pair that meets
//!    every condition but the second also qualifies, as a *seam pair*, when its straight
//!    line crosses an uncertain pixel (a band or a cut of the heatmap lies between the
//!    two) and some uncertain centre exists (the nearest one, farther than `d_b`, is its
//!    uncertain centre): k-means puts the uncertain centres where most uncertain pixels
//!    are, in the wide band that an earlier push opened between two columns of a pack,
//!    and then finds none beside the faint cuts between the boxes of one column. Two
//!    pieces of one certain region that step 4 split by its metric size qualify as a
//!    seam pair without crossing an uncertain pixel, and without any uncertain centre
//!    (then the pair has none): a pack whose seams the heatmap does not show at all is one
//!    certain region, and its size is the only evidence that it holds several objects. A seam pair is pushed only when its push splits a segment
//!    (step 8).
//!
//!    Qualifying pairs are ranked by the distance of their uncertain centre (so every
//!    seam pair after the others), then by the distance between their centres, then by
//!    `(i, j)` in index order.
//! 8. **Which pair and cluster are pushed.** Every pair draws a side from the PRNG (one
//!    draw per pair, used for both of its clusters). The *candidates* are the pushes of
//!    step 9 in the paper's order: pairs in rank order; in a pair, the cluster with fewer
//!    samples first (the smaller region moves more readily and disturbs the scene less;
//!    ties: the lower index), then the other; for a cluster, the drawn side, then the
//!    opposite one. With [`Config::push_carry_frac`] `0` the first candidate is made (the
//!    paper's choice). Otherwise (beyond the paper) FindAction makes the push that
//!    separates the most objects the accumulated mask still merges:
//!    - each certain cluster takes the label of `mask` at its pixel centre (`0`, on
//!      background, joins no label);
//!    - a candidate's *moved set* is its pushed cluster and every cluster it is predicted
//!      to carry: the clusters ahead of the pushed one on the push's line, up to where the
//!      object it crosses ends (the first stretch of more than 5 mm of table), whose pixel
//!      centres lie off that line by less than `push_carry_frac` times the pair's pixel
//!      spacing. A box pushed across a row carries nothing; a box pushed along its row
//!      carries the row;
//!    - its *score* is the number of pairs of clusters with one label of which one is in
//!      the moved set and the other not: pairs a push splits. A push that moves a whole
//!      segment, or only objects already apart, scores `0`;
//!    - its *size score* counts pairs of objects instead, with a size prior: a segment
//!      (a label of `mask` under some cluster's pixel centre) holds `n` objects, the
//!      larger of its number of clusters and its metric area (pixels times `z̄²/(fx·fy)`,
//!      `z̄` the mean depth of its clusters' 3-D centres) in units of the smallest such
//!      segment's, rounded, at most 6 (the objects of a packed scene look alike, so the
//!      smallest segment is taken as one object; with one segment the prior adds
//!      nothing). With `m` of its clusters moved, each taken as one object, the push
//!      splits `m · (n − m)` of its pairs; the size score sums them over the segments.
//!      It sees what the score cannot: when the heatmap has no cut between two packed
//!      boxes, their certain region (shorter than [`Config::region_max_len_m`]) is one
//!      cluster, and their segment looks already split by clusters alone.
//!
//!    The candidate with the highest score is made, then the one that moves the fewest
//!    clusters, then the earliest. A seam pair's candidate that scores `0` is dropped.
//!    When no candidate scores above `0`, the size score decides in the same way (the
//!    highest, then the fewest clusters moved, then the earliest). When no candidate has
//!    a size score above `0` either (every object already has a label of its own, or the
//!    mask is background), the first candidate is made, as in the paper. The
//!    pushed cluster `C_i` and its pair are reported with the push; when no qualifying
//!    pair has a push, the best pair that is not a seam pair is reported without one.
//! 9. **Push point.** The *region* of certain cluster `q` is the set of certain pixels in
//!    `q`'s region of step 3 whose nearest pixel centre among that region's clusters is
//!    `q`. From the pixel centre `C_i` the walk goes in 0.5 px steps along the line
//!    through `C_i` perpendicular to `C_i → C_j`, on the side of the candidate (step 8).
//!    Once the walk has been inside
//!    `C_i`'s region, the first point whose pixel is table is the push start `P`: the
//!    walk leaves the whole object (or pack of objects) and `P` lies on its outer rim or
//!    just beyond, never in a cut or a band between two objects, and `P → C_i` is
//!    perpendicular to the pair (a shear of `C_i` along `C_j`). A side fails when the
//!    walk reaches the image border, or, after having been in `C_i`'s region, a pixel of
//!    another cluster's region (that side leads into another object): that side has no
//!    push.
//! 10. **Push.** The push starts where the pushed segment of the mask ends on the line
//!     from `C_i`'s pixel centre to `P`: walking from the centre towards `P` in 0.5 px
//!     steps while the pixel keeps the centre's label, the last point inside is the start
//!     `S` (`P` itself when the centre is background in the mask). The heatmap's rim `P`
//!     can lie a few pixels beyond or inside the segment's outline; the mask says where
//!     the object really ends. `S` is back-projected at the depth of the cluster's 3-D
//!     centre, so the tool starts at the object's height and not on the table; the
//!     direction is the unit vector from `P` so back-projected to the cluster's 3-D centre
//!     (the same line); the length is [`Config::push_len_m`].
//!
//! Cost: two vectorised passes over the pixels (class counts, and the per-row maximum
//! that skips rows without a certain pixel), a scan of the rows that hold certain pixels
//! (runs) and of the rows that hold samples, near-linear union-find over the runs,
//! `O(samples)` to give samples their regions, `O(samples · 4 · kmeans_iters)` per split
//! region, `O(samples · K² · kmeans_iters)` for the uncertain k-means (the inner loop
//! runs over sample planes and vectorises), `O(K² · (K + K_u + line · K))` for the pairs
//! and `O((width + height) · K)` per walk (four per pair with the push choice of step 8
//! on, each followed by the walk of its moved set and an `O(K²)` score; up to four per
//! pair tried with it off); with the push choice on and two or more segments under the
//! clusters, one pass over the mask (`O(pixels · K)` at worst) for the segments' areas. At 640×480 with
//! [`Config::PAPER`] a call takes about 1 ms on one x86-64 core (SSE2 only); the run
//! scratch is the largest buffer, `4 · height · ⌈width/2⌉` entries (2.4 MB at 640×480).

mod kmeans;
mod pairs;
mod push;
mod regions;
mod sample;
#[cfg(test)]
mod tests;

use heapless::Vec as FixedVec;
use nalgebra::{Point3, Vector3};

use crate::{
    Buffer, Config, Error, Intrinsics, MAX_CLUSTERS, error::check_len, image::ImageView,
    math::Real, rng::Pcg32,
};
use kmeans::*;
use pairs::*;
use push::*;
use regions::*;
use sample::*;

/// Scratch for [`find_action`]. Contents are garbage after the call.
///
/// Size every slice with [`ActionScratchLen::for_config`]; longer slices are fine. The
/// sample slices hold three planes of `n` entries each: x (pixels), y (pixels), depth
/// (metres), with `n` = [`ActionScratchLen::samples`]. [`ActionScratch::runs`] holds four
/// planes of `r` entries each, `r` = [`ActionScratchLen::max_runs`].
#[derive(Debug)]
pub struct ActionScratch<'a> {
    /// Sampled certain pixels, `3·n` entries (planes x, y, depth).
    pub certain: &'a mut [Real],
    /// Sampled uncertain pixels, `3·n` entries (planes x, y, depth).
    pub uncertain: &'a mut [Real],
    /// Squared distance of each sample to its nearest centre, pixels², `n` entries.
    pub dist2: &'a mut [Real],
    /// Index of each sample's nearest centre (or certain region), `n` entries.
    pub nearest: &'a mut [u32],
    /// Certain and uncertain pixel counts of each row, `2·height` entries.
    pub row_counts: &'a mut [u32],
    /// Runs of certain pixels (row by row), `4·r` entries: planes first x, end x (one
    /// past the last), parent run (union-find), count or region index.
    pub runs: &'a mut [u32],
    /// Index of each row's first run, then the number of runs: `height + 1` entries.
    pub row_runs: &'a mut [u32],
}

/// Element counts [`ActionScratch`] needs; `const` so bare-metal callers can size `static`
/// arrays.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ActionScratchLen {
    /// Samples per class, `n = min(kmeans_samples, width·height)`.
    pub samples: usize,
    /// Entries of [`ActionScratch::certain`] (`3·n`).
    pub certain: usize,
    /// Entries of [`ActionScratch::uncertain`] (`3·n`).
    pub uncertain: usize,
    /// Entries of [`ActionScratch::dist2`] (`n`).
    pub dist2: usize,
    /// Entries of [`ActionScratch::nearest`] (`n`).
    pub nearest: usize,
    /// Entries of [`ActionScratch::row_counts`] (`2·height`).
    pub row_counts: usize,
    /// Most runs of certain pixels an image can hold, `r = height·⌈width/2⌉` (runs in a
    /// row are separated by at least one pixel).
    pub max_runs: usize,
    /// Entries of [`ActionScratch::runs`] (`4·r`).
    pub runs: usize,
    /// Entries of [`ActionScratch::row_runs`] (`height + 1`).
    pub row_runs: usize,
}

impl ActionScratchLen {
    /// Counts for `cfg` and a `width × height` image. A class cannot have more pixels than
    /// the image, so `n = min(cfg.kmeans_samples, width·height)`.
    #[must_use]
    pub const fn for_config(cfg: &Config, width: usize, height: usize) -> Self {
        let pixels = width.saturating_mul(height);
        let n = if cfg.kmeans_samples < pixels {
            cfg.kmeans_samples
        } else {
            pixels
        };
        let max_runs = height.saturating_mul(width.div_ceil(2));
        Self {
            samples: n,
            certain: n.saturating_mul(3),
            uncertain: n.saturating_mul(3),
            dist2: n,
            nearest: n,
            row_counts: height.saturating_mul(2),
            max_runs,
            runs: max_runs.saturating_mul(4),
            row_runs: height.saturating_add(1),
        }
    }

    /// Total size of the scratch in bytes (saturating).
    #[must_use]
    pub const fn bytes(&self) -> usize {
        self.certain
            .saturating_add(self.uncertain)
            .saturating_add(self.dist2)
            .saturating_mul(size_of::<Real>())
            .saturating_add(
                self.nearest
                    .saturating_add(self.row_counts)
                    .saturating_add(self.runs)
                    .saturating_add(self.row_runs)
                    .saturating_mul(size_of::<u32>()),
            )
    }
}

/// One cluster of a heatmap class.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cluster {
    /// Centre `[x, y]`, pixels, measured from the centre of the top-left pixel: the mean of
    /// the members' pixels (the k-means centre for uncertain clusters and for pieces of a
    /// split certain region).
    pub centre_px: [Real; 2],
    /// Mean of the members' back-projected points, camera frame, metres.
    pub centre_cam_m: Point3<Real>,
    /// Sampled pixels assigned to the cluster (proportional to its area in the class).
    pub samples: u32,
}

/// The chosen pair of certain clusters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pair {
    /// Index into [`ActionReport::certain`] of the cluster that is pushed (`C_i*`).
    pub pushed: usize,
    /// Index into [`ActionReport::certain`] of the other cluster (`C_j*`).
    pub other: usize,
    /// Index into [`ActionReport::uncertain`] of the uncertain centre nearest the pair's
    /// segment; `None` for two pieces of one certain region when there is no uncertain
    /// centre at all (module docs, step 7).
    pub uncertain: Option<usize>,
    /// 3-D distance between the two certain centres, metres.
    pub pair_dist_m: Real,
    /// 3-D distance from the uncertain centre to the pair's segment, metres; above
    /// [`Config::uncertain_max_m`] for a seam pair, infinite without an uncertain centre
    /// (module docs, step 7).
    pub uncertain_dist_m: Real,
}

/// A push: start at the pushed object's edge, move towards the pushed cluster's centre
/// (module docs, steps 9-10). This is what the robot makes; the host maps it into the
/// robot frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Push {
    /// Start pixel `[x, y]` (sub-pixel): where the pushed segment of the mask ends on the
    /// way from the cluster's centre out of the object (module docs, step 10).
    pub start_px: [Real; 2],
    /// Pixel centre of the pushed cluster `[x, y]` (the push aims here).
    pub target_px: [Real; 2],
    /// Start point in the camera frame, metres: `start_px` back-projected at the depth of
    /// the cluster's 3-D centre.
    pub start_cam_m: Point3<Real>,
    /// Unit direction in the camera frame, from `start_cam_m` to the cluster's 3-D centre.
    pub direction_cam: Vector3<Real>,
    /// Push length (paper `d_push`), metres.
    pub length_m: Real,
}

/// What [`find_action`] found.
#[derive(Debug, Clone, PartialEq)]
pub struct ActionReport {
    certain: FixedVec<Cluster, MAX_CLUSTERS>,
    uncertain: FixedVec<Cluster, MAX_CLUSTERS>,
    pair: Option<Pair>,
    push: Option<Push>,
}

impl ActionReport {
    /// Certain clusters (paper `C^c`), at most [`Config::max_clusters`].
    #[must_use]
    pub fn certain(&self) -> &[Cluster] {
        &self.certain
    }

    /// Uncertain cluster centres (paper `C^u`), at most [`Config::max_clusters`].
    #[must_use]
    pub fn uncertain(&self) -> &[Cluster] {
        &self.uncertain
    }

    /// The chosen pair (module docs, step 8); `None` when no pair qualifies.
    #[must_use]
    pub const fn pair(&self) -> Option<Pair> {
        self.pair
    }

    /// The push; `None` when no pair qualifies, or when no qualifying pair has a
    /// cluster that a walk can leave to the outside of the object (module docs, steps
    /// 8-9).
    #[must_use]
    pub const fn push(&self) -> Option<Push> {
        self.push
    }
}

/// Finds the push of paper Algorithm 2 (see the [module docs](self) for every rule).
///
/// `heatmap` is 0-255 (high = object); `depth` is metres, with `0`, negative, NaN and
/// infinity meaning "no reading"; `mask` is the current instance mask (0 = background),
/// which places the push's start on the pushed segment's edge. Pixels are numbered from
/// the centre of the top-left pixel, as in [`Intrinsics`].
///
/// # Errors
/// [`Error::SizeMismatch`] if `heatmap`, `depth` and `mask` differ in size;
/// [`Error::BadConfig`] if [`Config::check`] fails; [`Error::NonFinite`] or
/// [`Error::BadConfig`] if [`Intrinsics::check`] fails;
/// [`Error::BufferTooSmall`] if a scratch slice is shorter than
/// [`ActionScratchLen::for_config`] asks. Nothing is written in these cases.
///
/// # Examples
/// ```
/// use riseg_core::{Config, ImageView, Intrinsics};
/// use riseg_core::action::{ActionScratch, ActionScratchLen, find_action};
///
/// let (w, h) = (32, 24);
/// let heat = vec![0u8; w * h]; // nothing is an object
/// let depth = vec![0.6f32; w * h];
/// let mask = vec![0u16; w * h];
/// let cfg = Config::PAPER;
/// let len = ActionScratchLen::for_config(&cfg, w, h);
/// let (mut c, mut u) = (vec![0.0; len.certain], vec![0.0; len.uncertain]);
/// let (mut d, mut n) = (vec![0.0; len.dist2], vec![0u32; len.nearest]);
/// let (mut rows, mut runs) = (vec![0u32; len.row_counts], vec![0u32; len.runs]);
/// let mut row_runs = vec![0u32; len.row_runs];
/// let scratch = ActionScratch {
///     certain: &mut c,
///     uncertain: &mut u,
///     dist2: &mut d,
///     nearest: &mut n,
///     row_counts: &mut rows,
///     runs: &mut runs,
///     row_runs: &mut row_runs,
/// };
/// let k = Intrinsics::new(30.0, 30.0, 15.5, 11.5)?;
/// let report = find_action(
///     &ImageView::packed(w, h, &heat)?,
///     &ImageView::packed(w, h, &depth)?,
///     &ImageView::packed(w, h, &mask)?,
///     &k,
///     &cfg,
///     scratch,
/// )?;
/// assert!(report.certain().is_empty() && report.push().is_none());
/// # Ok::<(), riseg_core::Error>(())
/// ```
pub fn find_action(
    heatmap: &ImageView<'_, u8>,
    depth: &ImageView<'_, Real>,
    mask: &ImageView<'_, u16>,
    intrinsics: &Intrinsics,
    cfg: &Config,
    scratch: ActionScratch<'_>,
) -> Result<ActionReport, Error> {
    if heatmap.size() != depth.size() || heatmap.size() != mask.size() {
        return Err(Error::SizeMismatch);
    }
    cfg.check()?;
    intrinsics.check()?;
    let (width, height) = heatmap.size();
    let len = ActionScratchLen::for_config(cfg, width, height);
    check_len(Buffer::Samples, len.certain, scratch.certain.len())?;
    check_len(Buffer::Samples, len.uncertain, scratch.uncertain.len())?;
    check_len(Buffer::SampleDist, len.dist2, scratch.dist2.len())?;
    check_len(Buffer::SampleNearest, len.nearest, scratch.nearest.len())?;
    check_len(Buffer::RowCounts, len.row_counts, scratch.row_counts.len())?;
    check_len(Buffer::Runs, len.runs, scratch.runs.len())?;
    check_len(Buffer::RowRuns, len.row_runs, scratch.row_runs.len())?;
    let n = len.samples;
    let too_small = Error::BufferTooSmall {
        buffer: Buffer::Samples,
        needed: len.certain,
        got: 0,
    };
    let (
        Some(certain_buf),
        Some(uncertain_buf),
        Some(dist2),
        Some(nearest),
        Some(row_counts),
        Some(row_runs),
    ) = (
        scratch.certain.get_mut(..len.certain),
        scratch.uncertain.get_mut(..len.uncertain),
        scratch.dist2.get_mut(..n),
        scratch.nearest.get_mut(..n),
        scratch.row_counts.get_mut(..len.row_counts),
        scratch.row_runs.get_mut(..len.row_runs),
    )
    else {
        // Unreachable after the checks above; kept total instead of indexing.
        return Err(too_small);
    };
    let (Some(mut certain_planes), Some(mut uncertain_planes), Some(mut runs)) = (
        Planes::split(certain_buf, n),
        Planes::split(uncertain_buf, n),
        RunPlanes::split(scratch.runs, len.max_runs),
    ) else {
        // Unreachable: the buffers hold 3·n and 4·r entries.
        return Err(too_small);
    };

    let mut rng = Pcg32::new(cfg.seed);
    let (n_certain, n_uncertain) = sample_classes(
        heatmap,
        depth,
        cfg,
        &mut rng,
        &mut certain_planes,
        &mut uncertain_planes,
        row_counts,
    );
    let n_runs = label_runs(heatmap, cfg.certain_from, &mut runs, row_runs);
    let certain_samples = certain_planes.prefix(n_certain);
    let regions = certain_clusters(
        &mut runs,
        n_runs,
        row_runs,
        &certain_samples,
        nearest,
        intrinsics,
        cfg,
    );
    let mut km = KMeans {
        dist2,
        nearest,
        iters: cfg.kmeans_iters,
    };
    let uncertain = km.cluster_class(
        &uncertain_planes.prefix(n_uncertain),
        intrinsics,
        cfg.max_clusters,
        &mut rng,
    );

    let map = RegionMap {
        heatmap,
        runs: runs.view(n_runs),
        row_runs,
        clusters: &regions.clusters,
        region_of: &regions.region_of,
        cfg,
    };
    let pairs = rank_pairs(&map, &uncertain, cfg);
    let (pair, push) = match choose_push(&map, mask, &pairs, intrinsics, cfg, &mut rng) {
        Some((pair, push)) => (Some(pair), Some(push)),
        None => (pairs.iter().find(|p| !is_seam(p, cfg)).copied(), None),
    };
    Ok(ActionReport {
        certain: regions.clusters,
        uncertain,
        pair,
        push,
    })
}
