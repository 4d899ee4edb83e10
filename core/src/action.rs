//! FindAction (paper Algorithm 2): one small push between two "certain" object regions
//! that have an "uncertain" region between them.
//!
//! # Contract
//!
//! [`find_action`] reads a 0-255 heatmap (high = surely inside an object) and a depth
//! image of the same size, and returns an [`ActionReport`]: the cluster centres it found
//! (for display), the chosen pair of certain clusters, and the push, if any. It writes only
//! the caller's [`ActionScratch`], allocates nothing, never panics, and gives bit-identical
//! reports for the same inputs and [`Config::seed`].
//!
//! # Steps
//!
//! 1. **Classes.** A pixel is *certain* when `heatmap >= certain_from` (paper `l_u`) and
//!    *uncertain* when `uncertain_from <= heatmap < certain_from` (paper `l_l`). Only pixels
//!    with a depth reading ([`valid_depth`]) are clustered.
//! 2. **Samples.** Up to [`Config::kmeans_samples`] pixels of each class are drawn by
//!    systematic sampling over the class's pixels in row-major order, with a seeded random
//!    offset: every class pixel has the same chance and no sort is needed. One vectorised
//!    pass counts each row's class pixels; a second pass reads pixel by pixel only the
//!    rows that hold a kept sample.
//! 3. **k-means** in pixel coordinates, for every `k` in `1..=K`,
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
//! 4. **Elbow**: Kneedle on the log-inertia curve. With `L(k) = ln(W(k) + n/6)` (`W` the
//!    inertia in pixels², `n/6` the inertia of pixel quantisation, so a perfect fit stays
//!    finite) and both axes normalised to `[0, 1]` (`x = (k−1)/(K−1)`,
//!    `y = (L(k) − L(K))/(L(1) − L(K))`), the chosen `k` lies farthest below the chord
//!    from `k = 1` to `k = K`: the largest `1 − x − y`, ties to the smaller `k`. A curve
//!    that nowhere drops more than 0.01 below its chord has no elbow and gives `k = 1`.
//!    With `K = 2` there is no interior point: `k = 2` when it removes at least half the
//!    inertia, else `k = 1`. The log makes the rule depend on *relative* drops, so five
//!    or six objects of one size are told apart; on the raw curve the first big drop
//!    dominates and close groups of objects merge. Kneedle never picks `k = K`, so
//!    `max_clusters` should exceed the number of objects expected by two or more. A single
//!    isolated object is split into a few clusters; if it is small (radius below about
//!    `1.4·d_b`) its own uncertain rim can then qualify a pair inside it, and the loop
//!    spends a push on it (Algorithm 1's push limit bounds this).
//! 5. **Metric centres.** Each cluster's 3-D centre is the mean of its sampled members'
//!    back-projected points (camera frame, metres), so holes in the depth do not move it;
//!    clusters left without members are dropped. The pixel centre is the k-means centre.
//! 6. **Pair** (DESIGN §3). Among certain pairs whose 3-D centres are at most
//!    [`Config::pair_max_m`] (paper `d_a`) apart, the distance of a pair is the smallest
//!    3-D distance from an uncertain centre to the segment between the two centres; the
//!    pair qualifies when that is at most [`Config::uncertain_max_m`] (`d_b`). The pair with
//!    the smallest such distance wins, then the one with the smaller centre distance, then
//!    the first in index order.
//! 7. **Which cluster is pushed.** The one of the pair with fewer sampled members (the
//!    smaller region, which moves more readily and disturbs the scene less); on a tie, the
//!    lower index.
//! 8. **Push point.** The *region* of the pushed cluster `i` is the set of pixels with
//!    `heatmap >= certain_from` whose nearest certain pixel centre is `i` (depth is not
//!    consulted, so a depth hole inside an object does not end the region). From the
//!    pixel centre `C_i` the walk goes in 0.5 px steps along the line through `C_i`
//!    perpendicular to `C_i → C_j`, on a side drawn from the PRNG. Once the walk has been
//!    inside the region, the first point whose pixel is outside it is the push start `P`
//!    (just outside the cluster, and `P → C_i` is perpendicular to the pair). If the walk
//!    reaches the image border first, the other side is tried; if neither side works, the
//!    pair is reported with no push.
//! 9. **Push.** `P` is back-projected at the depth of the cluster's 3-D centre, so the tool
//!    starts at the object's height and not on the table; the direction is the unit vector
//!    from there to the cluster's 3-D centre; the length is [`Config::push_len_m`].
//!
//! Cost: two passes over the pixels (the second only on rows with samples),
//! `O(samples · K² · kmeans_iters)` for the clustering of each class (the inner loop runs
//! over sample planes and vectorises), `O(K² · K_u)` for the pairs and
//! `O(width + height)` for the walk. At 640×480 with [`Config::PAPER`] a call takes about
//! 1 ms on one x86-64 core (SSE2 only).

use heapless::Vec as FixedVec;
use nalgebra::{Point3, Vector3};

use crate::{
    Buffer, Config, Error, Intrinsics, MAX_CLUSTERS,
    error::check_len,
    image::{ImageView, valid_depth},
    math::{Real, ln, round, sqrt},
    rng::Pcg32,
};

/// Step of the walk from a cluster centre to its region's boundary, pixels.
const WALK_STEP_PX: Real = 0.5;

/// Lloyd stops when an update would move the centres by less than this in total
/// (root of the summed squared shifts), pixels: the push is planned at pixel resolution.
const LLOYD_TOL_PX: Real = 0.25;

/// Smallest normalised drop below the chord that counts as an elbow.
const KNEE_MIN: Real = 0.01;

/// Scratch for [`find_action`]. Contents are garbage after the call.
///
/// Size every slice with [`ActionScratchLen::for_config`]; longer slices are fine. The
/// sample slices hold three planes of `n` entries each: x (pixels), y (pixels), depth
/// (metres), with `n` = [`ActionScratchLen::samples`].
#[derive(Debug)]
pub struct ActionScratch<'a> {
    /// Sampled certain pixels, `3·n` entries (planes x, y, depth).
    pub certain: &'a mut [Real],
    /// Sampled uncertain pixels, `3·n` entries (planes x, y, depth).
    pub uncertain: &'a mut [Real],
    /// Squared distance of each sample to its nearest centre, pixels², `n` entries.
    pub dist2: &'a mut [Real],
    /// Index of each sample's nearest centre, `n` entries.
    pub nearest: &'a mut [u32],
    /// Certain and uncertain pixel counts of each row, `2·height` entries.
    pub row_counts: &'a mut [u32],
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
        Self {
            samples: n,
            certain: n.saturating_mul(3),
            uncertain: n.saturating_mul(3),
            dist2: n,
            nearest: n,
            row_counts: height.saturating_mul(2),
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
                    .saturating_mul(size_of::<u32>()),
            )
    }
}

/// One k-means cluster of a heatmap class.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cluster {
    /// k-means centre `[x, y]`, pixels, measured from the centre of the top-left pixel.
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
    /// segment.
    pub uncertain: usize,
    /// 3-D distance between the two certain centres, metres.
    pub pair_dist_m: Real,
    /// 3-D distance from the uncertain centre to the pair's segment, metres.
    pub uncertain_dist_m: Real,
}

/// A push: start just outside the pushed cluster, move towards its centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Push {
    /// Start pixel `[x, y]` (sub-pixel; its pixel is outside the pushed region).
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
    /// Certain cluster centres (paper `C^c`), at most [`Config::max_clusters`].
    #[must_use]
    pub fn certain(&self) -> &[Cluster] {
        &self.certain
    }

    /// Uncertain cluster centres (paper `C^u`), at most [`Config::max_clusters`].
    #[must_use]
    pub fn uncertain(&self) -> &[Cluster] {
        &self.uncertain
    }

    /// The chosen pair; `None` when no pair qualifies.
    #[must_use]
    pub const fn pair(&self) -> Option<Pair> {
        self.pair
    }

    /// The push; `None` when no pair qualifies, or (rarely) when the walk from the pushed
    /// centre reaches the image border on both sides without leaving its region.
    #[must_use]
    pub const fn push(&self) -> Option<Push> {
        self.push
    }
}

/// Finds the push of paper Algorithm 2 (see the [module docs](self) for every rule).
///
/// `heatmap` is 0-255 (high = object); `depth` is metres, with `0`, negative, NaN and
/// infinity meaning "no reading". Pixels are numbered from the centre of the top-left
/// pixel, as in [`Intrinsics`].
///
/// # Errors
/// [`Error::SizeMismatch`] if `heatmap` and `depth` differ in size;
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
/// let cfg = Config::PAPER;
/// let len = ActionScratchLen::for_config(&cfg, w, h);
/// let (mut c, mut u) = (vec![0.0; len.certain], vec![0.0; len.uncertain]);
/// let (mut d, mut n) = (vec![0.0; len.dist2], vec![0u32; len.nearest]);
/// let mut rows = vec![0u32; len.row_counts];
/// let scratch = ActionScratch {
///     certain: &mut c,
///     uncertain: &mut u,
///     dist2: &mut d,
///     nearest: &mut n,
///     row_counts: &mut rows,
/// };
/// let k = Intrinsics::new(30.0, 30.0, 15.5, 11.5)?;
/// let report = find_action(
///     &ImageView::packed(w, h, &heat)?,
///     &ImageView::packed(w, h, &depth)?,
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
    intrinsics: &Intrinsics,
    cfg: &Config,
    scratch: ActionScratch<'_>,
) -> Result<ActionReport, Error> {
    if heatmap.size() != depth.size() {
        return Err(Error::SizeMismatch);
    }
    cfg.check()?;
    intrinsics.check()?;
    let (width, height) = heatmap.size();
    let len = ActionScratchLen::for_config(cfg, width, height);
    check_len(Buffer::Samples, len.certain, scratch.certain.len())?;
    check_len(Buffer::Samples, len.uncertain, scratch.uncertain.len())?;
    check_len(Buffer::Clusters, len.dist2, scratch.dist2.len())?;
    check_len(Buffer::Clusters, len.nearest, scratch.nearest.len())?;
    check_len(Buffer::Samples, len.row_counts, scratch.row_counts.len())?;
    let n = len.samples;
    let (Some(certain_buf), Some(uncertain_buf), Some(dist2), Some(nearest), Some(row_counts)) = (
        scratch.certain.get_mut(..len.certain),
        scratch.uncertain.get_mut(..len.uncertain),
        scratch.dist2.get_mut(..n),
        scratch.nearest.get_mut(..n),
        scratch.row_counts.get_mut(..len.row_counts),
    ) else {
        // Unreachable after the checks above; kept total instead of indexing.
        return Err(Error::BufferTooSmall {
            buffer: Buffer::Samples,
            needed: len.certain,
            got: 0,
        });
    };
    let (Some(mut certain_planes), Some(mut uncertain_planes)) = (
        Planes::split(certain_buf, n),
        Planes::split(uncertain_buf, n),
    ) else {
        // Unreachable: both buffers hold 3·n entries.
        return Err(Error::BufferTooSmall {
            buffer: Buffer::Samples,
            needed: len.certain,
            got: 0,
        });
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
    let mut km = KMeans {
        dist2,
        nearest,
        iters: cfg.kmeans_iters,
    };
    let certain = km.cluster_class(
        &certain_planes.prefix(n_certain),
        intrinsics,
        cfg.max_clusters,
        &mut rng,
    );
    let uncertain = km.cluster_class(
        &uncertain_planes.prefix(n_uncertain),
        intrinsics,
        cfg.max_clusters,
        &mut rng,
    );

    let pair = choose_pair(&certain, &uncertain, cfg);
    let push = pair.and_then(|p| plan_push(heatmap, &certain, &p, intrinsics, cfg, &mut rng));
    Ok(ActionReport {
        certain,
        uncertain,
        pair,
        push,
    })
}

/// Chooses `k` from the inertia curve `inertia[k − 1] = W(k)`, `k = 1..=K`, by the elbow
/// rule of the module docs (Kneedle on `ln(W + noise_floor)`; `W(2) <= W(1)/2` when
/// `K = 2`). Returns `0` only for an empty curve.
fn elbow(inertia: &[Real], noise_floor: Real) -> usize {
    let (Some(&first), Some(&last)) = (inertia.first(), inertia.last()) else {
        return 0;
    };
    match inertia.len() {
        1 => 1,
        2 => {
            if last <= 0.5 * first {
                2
            } else {
                1
            }
        }
        n => {
            let log = |w: Real| ln(w.max(0.0) + noise_floor);
            let (log_first, log_last) = (log(first), log(last));
            let span = log_first - log_last;
            if !(span > 0.0 && span.is_finite()) {
                return 1;
            }
            let x_scale = 1.0 / (n - 1) as Real;
            let mut best_k = 1;
            let mut best_score = KNEE_MIN;
            for (k0, &w) in inertia.iter().enumerate() {
                let x = k0 as Real * x_scale;
                let y = (log(w) - log_last) / span;
                let score = 1.0 - x - y;
                if score > best_score {
                    best_score = score;
                    best_k = k0 + 1;
                }
            }
            best_k
        }
    }
}

/// Pixel class of one heatmap value.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Class {
    Certain,
    Uncertain,
    Other,
}

fn class_of(heat: u8, cfg: &Config) -> Class {
    if heat >= cfg.certain_from {
        Class::Certain
    } else if heat >= cfg.uncertain_from {
        Class::Uncertain
    } else {
        Class::Other
    }
}

/// Uniform in `0..n` (`0` when `n == 0`), from 64 random bits.
fn below_usize(rng: &mut Pcg32, n: usize) -> usize {
    let r = (u64::from(rng.next_u32()) << 32) | u64::from(rng.next_u32());
    ((u128::from(r) * n as u128) >> 64) as usize
}

/// Sample coordinates as three planes of equal length.
struct Planes<'a> {
    x: &'a mut [Real],
    y: &'a mut [Real],
    z: &'a mut [Real],
}

/// Read-only view of the first samples of [`Planes`].
struct Samples<'a> {
    x: &'a [Real],
    y: &'a [Real],
    z: &'a [Real],
}

impl<'a> Planes<'a> {
    /// Splits `buf` into three planes of `n` entries; `None` if it is shorter than `3·n`.
    fn split(buf: &'a mut [Real], n: usize) -> Option<Self> {
        let (x, rest) = buf.split_at_mut_checked(n)?;
        let (y, rest) = rest.split_at_mut_checked(n)?;
        let z = rest.get_mut(..n)?;
        Some(Self { x, y, z })
    }

    fn prefix(&self, n: usize) -> Samples<'_> {
        let n = n.min(self.x.len()).min(self.y.len()).min(self.z.len());
        Samples {
            x: self.x.get(..n).unwrap_or(&[]),
            y: self.y.get(..n).unwrap_or(&[]),
            z: self.z.get(..n).unwrap_or(&[]),
        }
    }
}

impl Samples<'_> {
    const fn len(&self) -> usize {
        self.x.len()
    }

    fn get(&self, i: usize) -> Option<[Real; 2]> {
        Some([*self.x.get(i)?, *self.y.get(i)?])
    }
}

/// Systematic sampling: of `total` items offered in order, keeps the items at
/// `⌊(m·total + offset) / take⌋`, `m = 0..take`, with `offset` uniform in `0..total`
/// (all items when `total <= take`). Each item is kept with probability `take / total`.
struct Sampler {
    total: usize,
    take: usize,
    offset: usize,
    /// Slot of the next kept item (= items kept so far).
    next_slot: usize,
    /// Index (among offered items) of the next kept item.
    next_index: usize,
    /// Items offered so far.
    seen: usize,
}

impl Sampler {
    fn new(total: usize, cap: usize, rng: &mut Pcg32) -> Self {
        let take = total.min(cap);
        let offset = below_usize(rng, total);
        let mut s = Self {
            total,
            take,
            offset,
            next_slot: 0,
            next_index: 0,
            seen: 0,
        };
        s.next_index = s.index_of(0);
        s
    }

    fn index_of(&self, slot: usize) -> usize {
        if self.total <= self.take {
            slot
        } else {
            let i = (slot as u128 * self.total as u128 + self.offset as u128) / self.take as u128;
            usize::try_from(i).unwrap_or(usize::MAX)
        }
    }

    /// Whether the next kept item lies among the next `count` offered items.
    const fn wants_any_of(&self, count: usize) -> bool {
        self.next_slot < self.take && self.next_index < self.seen.saturating_add(count)
    }

    /// Skips `count` items, none of which is kept (see [`Sampler::wants_any_of`]).
    const fn skip(&mut self, count: usize) {
        self.seen = self.seen.saturating_add(count);
    }

    /// Offers the next item; returns the slot to store it in if it is kept.
    fn offer(&mut self) -> Option<usize> {
        let index = self.seen;
        self.seen = self.seen.saturating_add(1);
        if self.next_slot < self.take && index == self.next_index {
            let slot = self.next_slot;
            self.next_slot += 1;
            self.next_index = self.index_of(self.next_slot);
            Some(slot)
        } else {
            None
        }
    }
}

/// Counts the certain and uncertain pixels with a depth reading in one row (branch-free,
/// so it vectorises).
fn count_row(heat: &[u8], depth: &[Real], cfg: &Config) -> (usize, usize) {
    let (certain_from, uncertain_from) = (cfg.certain_from, cfg.uncertain_from);
    let (mut certain, mut uncertain) = (0usize, 0usize);
    // u32 lane counters, flushed every 2^16 pixels.
    for (hc, dc) in heat.chunks(1 << 16).zip(depth.chunks(1 << 16)) {
        let (mut c, mut u) = (0u32, 0u32);
        for (&h, &z) in hc.iter().zip(dc) {
            // `0 < z < ∞` on the bits: one unsigned compare; NaN and negatives fail.
            let valid = z.to_bits().wrapping_sub(1) < Real::INFINITY.to_bits() - 1;
            c += u32::from(valid & (h >= certain_from));
            u += u32::from(valid & (h >= uncertain_from) & (h < certain_from));
        }
        certain += c as usize;
        uncertain += u as usize;
    }
    (certain, uncertain)
}

/// Draws the samples of both classes; returns how many of each were stored.
///
/// The first pass counts each row's class pixels into `row_counts` (pairs certain,
/// uncertain); the second visits pixel by pixel only the rows that hold a kept sample.
fn sample_classes<'a>(
    heatmap: &ImageView<'_, u8>,
    depth: &ImageView<'_, Real>,
    cfg: &Config,
    rng: &mut Pcg32,
    certain: &mut Planes<'a>,
    uncertain: &mut Planes<'a>,
    row_counts: &mut [u32],
) -> (usize, usize) {
    let rows = || (0..heatmap.height()).filter_map(|y| Some((y, heatmap.row(y)?, depth.row(y)?)));
    let (mut n_certain, mut n_uncertain) = (0usize, 0usize);
    for ((_, heat_row, depth_row), counts) in rows().zip(row_counts.chunks_exact_mut(2)) {
        let (c, u) = count_row(heat_row, depth_row, cfg);
        n_certain += c;
        n_uncertain += u;
        // A saturated count (rows wider than u32::MAX) is recounted below.
        counts[0] = u32::try_from(c).unwrap_or(u32::MAX);
        counts[1] = u32::try_from(u).unwrap_or(u32::MAX);
    }
    let mut certain_sampler = Sampler::new(n_certain, certain.x.len(), rng);
    let mut uncertain_sampler = Sampler::new(n_uncertain, uncertain.x.len(), rng);
    for ((y, heat_row, depth_row), counts) in rows().zip(row_counts.chunks_exact(2)) {
        let (c, u) = match *counts {
            [c, u] if c < u32::MAX && u < u32::MAX => (c as usize, u as usize),
            _ => count_row(heat_row, depth_row, cfg),
        };
        if !certain_sampler.wants_any_of(c) && !uncertain_sampler.wants_any_of(u) {
            certain_sampler.skip(c);
            uncertain_sampler.skip(u);
            continue;
        }
        for (x, (&heat, &z)) in heat_row.iter().zip(depth_row).enumerate() {
            let Some(z) = valid_depth(z) else { continue };
            let (sampler, planes) = match class_of(heat, cfg) {
                Class::Certain => (&mut certain_sampler, &mut *certain),
                Class::Uncertain => (&mut uncertain_sampler, &mut *uncertain),
                Class::Other => continue,
            };
            if let Some(slot) = sampler.offer()
                && let (Some(px), Some(py), Some(pz)) = (
                    planes.x.get_mut(slot),
                    planes.y.get_mut(slot),
                    planes.z.get_mut(slot),
                )
            {
                (*px, *py, *pz) = (x as Real, y as Real, z);
            }
        }
    }
    (certain_sampler.next_slot, uncertain_sampler.next_slot)
}

type Centres = [[Real; 2]; MAX_CLUSTERS];

/// `2 + ⌊ln k⌋` for `k <= 20`: candidates per new centre in greedy k-means++.
const fn seeding_trials(k: usize) -> usize {
    2 + (k >= 3) as usize + (k >= 8) as usize
}

/// Squared pixel distance from `(x, y)` to `c`.
#[inline]
fn dist2_to(x: Real, y: Real, c: [Real; 2]) -> Real {
    let (dx, dy) = (x - c[0], y - c[1]);
    dx * dx + dy * dy
}

/// Sum with eight interleaved accumulators combined in a fixed order: vectorises, and
/// is still the same on every target (no reassociation is left to the compiler).
fn lane_sum(v: &[Real]) -> Real {
    let mut acc = [0.0 as Real; 8];
    let chunks = v.chunks_exact(8);
    let tail = chunks.remainder();
    for chunk in chunks {
        for (a, &d) in acc.iter_mut().zip(chunk) {
            *a += d;
        }
    }
    let [a0, a1, a2, a3, a4, a5, a6, a7] = acc;
    let mut total = ((a0 + a4) + (a1 + a5)) + ((a2 + a6) + (a3 + a7));
    for &d in tail {
        total += d;
    }
    total
}

/// k-means over caller scratch (`dist2`, `nearest`: exactly one entry per sample).
struct KMeans<'s> {
    dist2: &'s mut [Real],
    nearest: &'s mut [u32],
    iters: u32,
}

impl KMeans<'_> {
    /// Sets `dist2`/`nearest` to each sample's nearest centre (ties: lower index).
    ///
    /// Centre-outer, sample-inner, with selects written as bit masks so the inner loop
    /// vectorises instead of becoming conditional stores.
    fn assign(&mut self, s: &Samples<'_>, centres: &[[Real; 2]]) {
        let Some((&c0, rest)) = centres.split_first() else {
            return;
        };
        for (((&x, &y), d2), nj) in
            s.x.iter()
                .zip(s.y)
                .zip(self.dist2.iter_mut())
                .zip(self.nearest.iter_mut())
        {
            *d2 = dist2_to(x, y, c0);
            *nj = 0;
        }
        for (j, &c) in (1u32..).zip(rest) {
            for (((&x, &y), d2), nj) in
                s.x.iter()
                    .zip(s.y)
                    .zip(self.dist2.iter_mut())
                    .zip(self.nearest.iter_mut())
            {
                let d = dist2_to(x, y, c);
                let mask = u32::from(d < *d2).wrapping_neg();
                *d2 = Real::from_bits((d.to_bits() & mask) | (d2.to_bits() & !mask));
                *nj = (j & mask) | (*nj & !mask);
            }
        }
    }

    /// Member sums `[x, y]` and counts per centre of the current assignment.
    ///
    /// Four interleaved sets of accumulators (samples `i mod 4`), combined in a fixed
    /// order: neighbouring samples mostly share a cluster, and one set would make every
    /// addition wait for the previous one.
    fn sums(&self, s: &Samples<'_>) -> ([[Real; 2]; MAX_CLUSTERS], [usize; MAX_CLUSTERS]) {
        // Indices are masked to the array size (a power of two): never out of bounds, and
        // the mask is a no-op for real cluster indices (< MAX_CLUSTERS).
        const MASK: usize = MAX_CLUSTERS - 1;
        const _: () = assert!(MAX_CLUSTERS.is_power_of_two());
        let mut sets = [([[0.0 as Real; 2]; MAX_CLUSTERS], [0usize; MAX_CLUSTERS]); 4];
        let (xs, ys, ns) = (
            s.x.chunks_exact(4),
            s.y.chunks_exact(4),
            self.nearest.chunks_exact(4),
        );
        let (xt, yt, nt) = (xs.remainder(), ys.remainder(), ns.remainder());
        for ((xc, yc), nc) in xs.zip(ys).zip(ns) {
            for (((set, &x), &y), &nj) in sets.iter_mut().zip(xc).zip(yc).zip(nc) {
                let (sums, counts) = set;
                let j = nj as usize & MASK;
                sums[j][0] += x;
                sums[j][1] += y;
                counts[j] += 1;
            }
        }
        for (((set, &x), &y), &nj) in sets.iter_mut().zip(xt).zip(yt).zip(nt) {
            let (sums, counts) = set;
            let j = nj as usize & MASK;
            sums[j][0] += x;
            sums[j][1] += y;
            counts[j] += 1;
        }
        let [(s0, c0), (s1, c1), (s2, c2), (s3, c3)] = &sets;
        let sums = core::array::from_fn(|j| {
            let (a, b, c, d) = (s0[j], s1[j], s2[j], s3[j]);
            [(a[0] + b[0]) + (c[0] + d[0]), (a[1] + b[1]) + (c[1] + d[1])]
        });
        let counts = core::array::from_fn(|j| c0[j] + c1[j] + c2[j] + c3[j]);
        (sums, counts)
    }

    /// Lloyd iterations from `centres` until an update would move them by at most
    /// [`LLOYD_TOL_PX`] in total, or `iters` updates were made. Leaves the assignment made
    /// by the final `centres` in `dist2`/`nearest`; returns its inertia (pixels²).
    fn lloyd(&mut self, s: &Samples<'_>, centres: &mut [[Real; 2]]) -> Real {
        self.assign(s, centres);
        for _ in 0..self.iters {
            let (sums, counts) = self.sums(s);
            let mut means: Centres = [[0.0; 2]; MAX_CLUSTERS];
            let mut shift2 = 0.0;
            for (((m, c), sum), &count) in
                means.iter_mut().zip(centres.iter()).zip(&sums).zip(&counts)
            {
                *m = *c;
                if count > 0 {
                    let inv = 1.0 / count as Real;
                    *m = [sum[0] * inv, sum[1] * inv];
                    shift2 += dist2_to(m[0], m[1], *c);
                }
            }
            // Converged: keep the centres that made the current assignment.
            if shift2 <= LLOYD_TOL_PX * LLOYD_TOL_PX {
                break;
            }
            for (c, m) in centres.iter_mut().zip(&means) {
                *c = *m;
            }
            self.assign(s, centres);
        }
        lane_sum(self.dist2)
    }

    /// Greedy k-means++ step: a new centre drawn with probability proportional to
    /// `dist2` (the squared distance to the nearest current centre), best of `trials`
    /// draws by the resulting inertia. `None` when every sample sits on a centre.
    fn draw_centre(&self, s: &Samples<'_>, trials: usize, rng: &mut Pcg32) -> Option<[Real; 2]> {
        let potential = lane_sum(self.dist2);
        if potential.is_nan() || potential <= 0.0 {
            return None;
        }
        let mut best: Option<(Real, [Real; 2])> = None;
        for _ in 0..trials {
            let r = rng.unit() * potential;
            let mut acc = 0.0;
            let mut pick = None;
            for (i, &d2) in self.dist2.iter().enumerate() {
                if d2 > 0.0 {
                    acc += d2;
                    pick = Some(i);
                    if acc > r {
                        break;
                    }
                }
            }
            let c = s.get(pick?)?;
            let mut acc = [0.0 as Real; 8];
            let (xs, ys, ds) = (
                s.x.chunks_exact(8),
                s.y.chunks_exact(8),
                self.dist2.chunks_exact(8),
            );
            let (xt, yt, dt) = (xs.remainder(), ys.remainder(), ds.remainder());
            for ((xc, yc), dc) in xs.zip(ys).zip(ds) {
                for (((a, &x), &y), &d2) in acc.iter_mut().zip(xc).zip(yc).zip(dc) {
                    *a += d2.min(dist2_to(x, y, c));
                }
            }
            let mut pot = lane_sum(&acc);
            for ((&x, &y), &d2) in xt.iter().zip(yt).zip(dt) {
                pot += d2.min(dist2_to(x, y, c));
            }
            if best.is_none_or(|(b, _)| pot < b) {
                best = Some((pot, c));
            }
        }
        best.map(|(_, c)| c)
    }

    /// Clusters one class with the elbow-chosen `k`; returns its non-empty clusters.
    fn cluster_class(
        &mut self,
        s: &Samples<'_>,
        intrinsics: &Intrinsics,
        max_clusters: usize,
        rng: &mut Pcg32,
    ) -> FixedVec<Cluster, MAX_CLUSTERS> {
        let mut out = FixedVec::new();
        let n = s.len();
        let k_max = max_clusters.min(MAX_CLUSTERS).min(n);
        let (Some(dist2), Some(nearest), true) = (
            self.dist2.get_mut(..n),
            self.nearest.get_mut(..n),
            k_max > 0,
        ) else {
            return out;
        };
        // Scratch cut to exactly one entry per sample, so whole-slice sums are sample sums.
        let mut km = KMeans {
            dist2,
            nearest,
            iters: self.iters,
        };
        // k = 1 starts from a seeded sample; each further k keeps the converged centres
        // of k − 1 and adds one greedy k-means++ centre (incremental seeding).
        let mut all_centres = [[[0.0 as Real; 2]; MAX_CLUSTERS]; MAX_CLUSTERS];
        let mut inertia = [0.0 as Real; MAX_CLUSTERS];
        let mut centres: Centres = [[0.0; 2]; MAX_CLUSTERS];
        let mut tried = 0;
        for (k0, (centres_k, inertia_k)) in all_centres
            .iter_mut()
            .zip(inertia.iter_mut())
            .take(k_max)
            .enumerate()
        {
            let new = if k0 == 0 {
                s.get(below_usize(rng, n))
            } else {
                km.draw_centre(s, seeding_trials(k0 + 1), rng)
            };
            let (Some(new), Some(slot)) = (new, centres.get_mut(k0)) else {
                break;
            };
            *slot = new;
            let Some(used) = centres.get_mut(..=k0) else {
                break;
            };
            *inertia_k = km.lloyd(s, used);
            *centres_k = centres;
            tried = k0 + 1;
        }
        // Inertia of pixel quantisation: 1/12 px² per axis and sample.
        let noise_floor = n as Real / 6.0;
        let k = elbow(inertia.get(..tried).unwrap_or(&[]), noise_floor);
        let Some(centres) = k
            .checked_sub(1)
            .and_then(|i| all_centres.get(i))
            .and_then(|c| c.get(..k))
        else {
            return out;
        };
        km.assign(s, centres);

        let mut sums = [Vector3::<Real>::zeros(); MAX_CLUSTERS];
        let mut counts = [0usize; MAX_CLUSTERS];
        for (((&x, &y), &z), &nj) in s.x.iter().zip(s.y).zip(s.z).zip(km.nearest.iter()) {
            let j = nj as usize;
            if let (Some(sum), Some(count)) = (sums.get_mut(j), counts.get_mut(j)) {
                *sum += intrinsics.back_project(x, y, z).coords;
                *count += 1;
            }
        }
        for ((c, sum), &count) in centres.iter().zip(&sums).zip(&counts) {
            if count > 0 {
                let cluster = Cluster {
                    centre_px: *c,
                    centre_cam_m: Point3::from(sum / count as Real),
                    samples: u32::try_from(count).unwrap_or(u32::MAX),
                };
                // Capacity is MAX_CLUSTERS and k <= MAX_CLUSTERS, so this cannot fail.
                let _ = out.push(cluster);
            }
        }
        out
    }
}

/// 3-D distance from `p` to the segment `a b`.
fn segment_dist(p: &Point3<Real>, a: &Point3<Real>, b: &Point3<Real>) -> Real {
    let ab = b - a;
    let ap = p - a;
    let len2 = ab.norm_squared();
    let t = if len2 > 0.0 {
        (ap.dot(&ab) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (ap - ab * t).norm()
}

/// The qualifying certain pair with the nearest uncertain centre (module docs, step 6-7).
fn choose_pair(certain: &[Cluster], uncertain: &[Cluster], cfg: &Config) -> Option<Pair> {
    let mut best: Option<Pair> = None;
    for (i, ci) in certain.iter().enumerate() {
        for (j, cj) in certain.iter().enumerate().skip(i + 1) {
            let pair_dist_m = (cj.centre_cam_m - ci.centre_cam_m).norm();
            if pair_dist_m.is_nan() || pair_dist_m > cfg.pair_max_m {
                continue;
            }
            let mut nearest: Option<(Real, usize)> = None;
            for (n, u) in uncertain.iter().enumerate() {
                let d = segment_dist(&u.centre_cam_m, &ci.centre_cam_m, &cj.centre_cam_m);
                if d <= cfg.uncertain_max_m && nearest.is_none_or(|(b, _)| d < b) {
                    nearest = Some((d, n));
                }
            }
            let Some((uncertain_dist_m, n)) = nearest else {
                continue;
            };
            let better = best.is_none_or(|b| {
                uncertain_dist_m < b.uncertain_dist_m
                    || (uncertain_dist_m == b.uncertain_dist_m && pair_dist_m < b.pair_dist_m)
            });
            if better {
                let (pushed, other) = if cj.samples < ci.samples {
                    (j, i)
                } else {
                    (i, j)
                };
                best = Some(Pair {
                    pushed,
                    other,
                    uncertain: n,
                    pair_dist_m,
                    uncertain_dist_m,
                });
            }
        }
    }
    best
}

/// Index of the certain centre nearest the pixel `(x, y)` (ties: lower index).
fn nearest_centre(certain: &[Cluster], x: Real, y: Real) -> Option<usize> {
    let mut best: Option<(Real, usize)> = None;
    for (i, c) in certain.iter().enumerate() {
        let dx = x - c.centre_px[0];
        let dy = y - c.centre_px[1];
        let d = dx * dx + dy * dy;
        if best.is_none_or(|(b, _)| d < b) {
            best = Some((d, i));
        }
    }
    best.map(|(_, i)| i)
}

/// Walks from `from` along the unit `dir` (pixels); returns the first point whose pixel is
/// outside the region of `pushed` after the walk has been inside it, or `None` when the
/// image border comes first.
fn walk_out(
    heatmap: &ImageView<'_, u8>,
    certain: &[Cluster],
    pushed: usize,
    from: [Real; 2],
    dir: [Real; 2],
    cfg: &Config,
) -> Option<[Real; 2]> {
    let (width, height) = heatmap.size();
    // 0.5 px steps over width + height pixels cover the image diagonal.
    let steps = width
        .saturating_add(height)
        .saturating_mul(2)
        .saturating_add(4);
    let mut entered = false;
    let mut last: Option<(i64, i64)> = None;
    for s in 0..steps {
        let t = s as Real * WALK_STEP_PX;
        let p = [from[0] + t * dir[0], from[1] + t * dir[1]];
        let pixel = (round(p[0]) as i64, round(p[1]) as i64);
        if last == Some(pixel) {
            continue;
        }
        last = Some(pixel);
        let heat = heatmap.at(pixel.0, pixel.1)?;
        let inside = heat >= cfg.certain_from
            && nearest_centre(certain, pixel.0 as Real, pixel.1 as Real) == Some(pushed);
        if inside {
            entered = true;
        } else if entered {
            return Some(p);
        }
    }
    None
}

/// Push start and direction for the chosen pair (module docs, steps 8-9).
fn plan_push(
    heatmap: &ImageView<'_, u8>,
    certain: &[Cluster],
    pair: &Pair,
    intrinsics: &Intrinsics,
    cfg: &Config,
    rng: &mut Pcg32,
) -> Option<Push> {
    let ci = certain.get(pair.pushed)?;
    let cj = certain.get(pair.other)?;
    let dx = cj.centre_px[0] - ci.centre_px[0];
    let dy = cj.centre_px[1] - ci.centre_px[1];
    let len = sqrt(dx * dx + dy * dy);
    if len.is_nan() || len <= 1e-3 {
        return None;
    }
    let side: Real = if rng.below(2) == 0 { 1.0 } else { -1.0 };
    let perp = [-dy / len * side, dx / len * side];
    let start_px =
        walk_out(heatmap, certain, pair.pushed, ci.centre_px, perp, cfg).or_else(|| {
            walk_out(
                heatmap,
                certain,
                pair.pushed,
                ci.centre_px,
                [-perp[0], -perp[1]],
                cfg,
            )
        })?;
    let start_cam_m = intrinsics.back_project(start_px[0], start_px[1], ci.centre_cam_m.z);
    let towards = ci.centre_cam_m - start_cam_m;
    let norm = towards.norm();
    if !(norm > 0.0 && norm.is_finite()) {
        return None;
    }
    let direction_cam = towards / norm;
    if !direction_cam.iter().all(|v| v.is_finite()) {
        return None;
    }
    Some(Push {
        start_px,
        target_px: ci.centre_px,
        start_cam_m,
        direction_cam,
        length_m: cfg.push_len_m,
    })
}

#[cfg(test)]
mod tests {
    extern crate std;

    use std::{vec, vec::Vec};

    use super::*;

    const W: usize = 320;
    const H: usize = 240;
    const Z_M: Real = 0.6;

    fn intrinsics() -> Intrinsics {
        Intrinsics::new(300.0, 300.0, 159.5, 119.5).unwrap()
    }

    /// A synthetic heatmap over a flat depth plane (1 px ≈ 2 mm at 0.6 m, fx = 300).
    struct Scene {
        heat: Vec<u8>,
        depth: Vec<Real>,
    }

    impl Scene {
        fn new() -> Self {
            Self {
                heat: vec![0; W * H],
                depth: vec![Z_M; W * H],
            }
        }

        fn disc(&mut self, cx: Real, cy: Real, r: Real, v: u8) -> &mut Self {
            for y in 0..H {
                for x in 0..W {
                    let (dx, dy) = (x as Real - cx, y as Real - cy);
                    if dx * dx + dy * dy <= r * r {
                        self.heat[y * W + x] = v;
                    }
                }
            }
            self
        }

        /// Pixels with `x0 <= x < x1`, `y0 <= y < y1`.
        fn rect(&mut self, x0: usize, y0: usize, x1: usize, y1: usize, v: u8) -> &mut Self {
            for y in y0..y1 {
                for x in x0..x1 {
                    self.heat[y * W + x] = v;
                }
            }
            self
        }

        fn heat_at(&self, p: [Real; 2]) -> u8 {
            self.heat[round(p[1]) as usize * W + round(p[0]) as usize]
        }

        fn run(&self, cfg: &Config) -> Result<ActionReport, Error> {
            run(W, H, &self.heat, &self.depth, &intrinsics(), cfg)
        }
    }

    fn run(
        w: usize,
        h: usize,
        heat: &[u8],
        depth: &[Real],
        k: &Intrinsics,
        cfg: &Config,
    ) -> Result<ActionReport, Error> {
        let len = ActionScratchLen::for_config(cfg, w, h);
        let mut c = vec![0.0; len.certain];
        let mut u = vec![0.0; len.uncertain];
        let mut d = vec![0.0; len.dist2];
        let mut n = vec![0u32; len.nearest];
        let mut r = vec![0u32; len.row_counts];
        find_action(
            &ImageView::packed(w, h, heat)?,
            &ImageView::packed(w, h, depth)?,
            k,
            cfg,
            ActionScratch {
                certain: &mut c,
                uncertain: &mut u,
                dist2: &mut d,
                nearest: &mut n,
                row_counts: &mut r,
            },
        )
    }

    /// Index of the cluster whose pixel centre is within 3 px of `(x, y)`.
    fn find(clusters: &[Cluster], x: Real, y: Real) -> Option<usize> {
        clusters.iter().position(|c| {
            let (dx, dy) = (c.centre_px[0] - x, c.centre_px[1] - y);
            dx * dx + dy * dy < 9.0
        })
    }

    const A: (Real, Real) = (110.0, 130.0);
    const B: (Real, Real) = (150.0, 130.0);
    const C: (Real, Real) = (110.0, 90.0);
    const R_PX: Real = 15.0;

    /// Three certain discs: A–B 40 px (8 cm), A–C 40 px (8 cm), B–C 11.3 cm; an uncertain
    /// band only in the gap between A and B.
    fn three_blobs() -> Scene {
        let mut s = Scene::new();
        s.disc(A.0, A.1, R_PX, 255)
            .disc(B.0, B.1, R_PX, 255)
            .disc(C.0, C.1, R_PX, 255)
            .rect(126, 118, 135, 143, 130);
        s
    }

    #[test]
    fn picks_the_pair_with_the_uncertain_band_between_them() {
        let s = three_blobs();
        let report = s.run(&Config::PAPER).unwrap();
        let certain = report.certain();
        assert_eq!(certain.len(), 3, "{certain:?}");
        let a = find(certain, A.0, A.1).expect("cluster at A");
        let b = find(certain, B.0, B.1).expect("cluster at B");
        assert!(find(certain, C.0, C.1).is_some());
        let pair = report.pair().expect("a pair qualifies");
        let mut got = [pair.pushed, pair.other];
        got.sort_unstable();
        let mut want = [a, b];
        want.sort_unstable();
        assert_eq!(got, want);
        assert!((pair.pair_dist_m - 0.08).abs() < 0.005, "{pair:?}");
        assert!(pair.uncertain_dist_m <= Config::PAPER.uncertain_max_m);
        // Every uncertain centre lies in the band.
        for u in report.uncertain() {
            assert!((125.0..136.0).contains(&u.centre_px[0]), "{u:?}");
        }
        let push = report.push().expect("a push");
        assert_eq!(push.target_px, certain[pair.pushed].centre_px);
        assert!(s.heat_at(push.start_px) < Config::PAPER.certain_from);
        assert_eq!(push.length_m, 0.02);
    }

    #[test]
    fn the_pair_nearest_an_uncertain_centre_wins_over_another_qualifying_pair() {
        // A second uncertain band sits in the A–C gap but about 2.6 cm beside the A–C
        // segment; the A–B band lies on its segment.
        let mut s = three_blobs();
        s.rect(118, 105, 128, 115, 130);
        let report = s.run(&Config::PAPER).unwrap();
        let certain = report.certain();
        let (a, b) = (
            find(certain, A.0, A.1).unwrap(),
            find(certain, B.0, B.1).unwrap(),
        );
        let pair = report.pair().expect("pair");
        let mut got = [pair.pushed, pair.other];
        got.sort_unstable();
        assert_eq!(got, [a.min(b), a.max(b)], "{pair:?}");
        // Control: without the A–B band, A–C qualifies through the other band.
        let mut s = Scene::new();
        s.disc(A.0, A.1, R_PX, 255)
            .disc(B.0, B.1, R_PX, 255)
            .disc(C.0, C.1, R_PX, 255)
            .rect(118, 105, 128, 115, 130);
        let report = s.run(&Config::PAPER).unwrap();
        let certain = report.certain();
        let (a, c) = (
            find(certain, A.0, A.1).unwrap(),
            find(certain, C.0, C.1).unwrap(),
        );
        let pair = report.pair().expect("A–C qualifies");
        let mut got = [pair.pushed, pair.other];
        got.sort_unstable();
        assert_eq!(got, [a.min(c), a.max(c)], "{pair:?}");
        assert!(pair.uncertain_dist_m > 0.015, "{pair:?}");
    }

    #[test]
    fn none_when_the_only_pair_is_farther_than_d_a() {
        // 80 px = 16 cm apart, uncertain band between them.
        let mut s = Scene::new();
        s.disc(100.0, 120.0, R_PX, 255)
            .disc(180.0, 120.0, R_PX, 255)
            .rect(116, 110, 165, 131, 130);
        let report = s.run(&Config::PAPER).unwrap();
        assert_eq!(report.certain().len(), 2);
        assert!(!report.uncertain().is_empty());
        assert_eq!(report.pair(), None);
        assert_eq!(report.push(), None);
        // Control: the same scene qualifies once d_a admits the pair.
        let mut cfg = Config::PAPER;
        cfg.pair_max_m = 0.2;
        let report = s.run(&cfg).unwrap();
        assert!(report.push().is_some());
    }

    #[test]
    fn none_when_no_uncertain_centre_is_within_d_b() {
        let mut s = Scene::new();
        s.disc(140.0, 120.0, R_PX, 255)
            .disc(180.0, 120.0, R_PX, 255)
            .rect(20, 20, 50, 50, 130);
        let report = s.run(&Config::PAPER).unwrap();
        assert_eq!(report.certain().len(), 2);
        assert!(!report.uncertain().is_empty());
        assert_eq!(report.pair(), None);
        assert_eq!(report.push(), None);
        // Control: with a huge d_b the pair qualifies.
        let mut cfg = Config::PAPER;
        cfg.uncertain_max_m = 1.0;
        assert!(s.run(&cfg).unwrap().push().is_some());
        // And without any uncertain pixel there is nothing to do.
        let mut s = Scene::new();
        s.disc(140.0, 120.0, R_PX, 255)
            .disc(180.0, 120.0, R_PX, 255);
        let report = s.run(&cfg).unwrap();
        assert!(report.uncertain().is_empty() && report.push().is_none());
    }

    #[test]
    fn push_starts_outside_the_cluster_perpendicular_and_points_at_its_centre() {
        let s = three_blobs();
        let k = intrinsics();
        let mut sides = [false; 2];
        for seed in 0..12 {
            let mut cfg = Config::PAPER;
            cfg.seed = seed;
            let report = s.run(&cfg).unwrap();
            let pair = report.pair().expect("pair");
            let push = report.push().expect("push");
            let certain = report.certain();
            let ci = certain[pair.pushed];
            let cj = certain[pair.other];
            // Outside the pushed cluster's region, but on its boundary.
            let outside = s.heat_at(push.start_px) < cfg.certain_from
                || nearest_centre(certain, round(push.start_px[0]), round(push.start_px[1]))
                    != Some(pair.pushed);
            assert!(outside, "seed {seed}: {push:?}");
            let (sx, sy) = (
                push.start_px[0] - ci.centre_px[0],
                push.start_px[1] - ci.centre_px[1],
            );
            let r = sqrt(sx * sx + sy * sy);
            assert!(
                (r - R_PX).abs() < 2.0,
                "seed {seed}: start {r} px from centre"
            );
            sides[usize::from(sy > 0.0)] = true;
            // Perpendicular to the pair (pixels and metres) within 10 degrees.
            let pair_px = Vector3::new(
                cj.centre_px[0] - ci.centre_px[0],
                cj.centre_px[1] - ci.centre_px[1],
                0.0,
            )
            .normalize();
            let to_centre_px = Vector3::new(-sx, -sy, 0.0).normalize();
            let sin10 = 0.1737;
            assert!(pair_px.dot(&to_centre_px).abs() < sin10, "seed {seed}");
            let pair_m = (cj.centre_cam_m - ci.centre_cam_m).normalize();
            assert!(pair_m.dot(&push.direction_cam).abs() < sin10, "seed {seed}");
            // Points at the centre; unit length; starts at the object's depth.
            let to_centre_m = (ci.centre_cam_m - push.start_cam_m).normalize();
            assert!(to_centre_m.dot(&push.direction_cam) > 0.99);
            assert!((push.direction_cam.norm() - 1.0).abs() < 1e-5);
            assert_eq!(push.start_cam_m.z, ci.centre_cam_m.z);
            let back = k.project(&push.start_cam_m).unwrap();
            assert!((back.x - push.start_px[0]).abs() < 1e-3);
            assert!((back.y - push.start_px[1]).abs() < 1e-3);
        }
        assert!(sides[0] && sides[1], "both sides are drawn over 12 seeds");
    }

    #[test]
    fn push_tries_the_other_side_when_one_side_never_leaves_the_region() {
        // A (pushed, smaller) touches the top border; its partner B sits right of it.
        let mut s = Scene::new();
        s.rect(100, 0, 121, 20, 255) // A: x 100..121, y 0..20, reaches the top border
            .rect(140, 0, 171, 30, 255) // B: larger
            .rect(122, 0, 139, 20, 130);
        for seed in 0..6 {
            let mut cfg = Config::PAPER;
            cfg.seed = seed;
            let report = s.run(&cfg).unwrap();
            let pair = report.pair().expect("pair");
            let ci = report.certain()[pair.pushed];
            assert!((ci.centre_px[0] - 110.0).abs() < 1.0, "{ci:?}");
            let push = report.push().expect("push");
            // Up leaves the image inside A, so the push always starts below it.
            assert!(push.start_px[1] > 19.0, "seed {seed}: {push:?}");
            assert!(push.direction_cam.y < -0.98, "seed {seed}: {push:?}");
        }
    }

    #[test]
    fn the_push_starts_at_the_height_of_the_object_on_a_tilted_table() {
        // Depth grows with y, as for a camera tilted towards the table.
        let mut s = three_blobs();
        for y in 0..H {
            for x in 0..W {
                s.depth[y * W + x] = 0.5 + 0.001 * y as Real;
            }
        }
        let report = s.run(&Config::PAPER).unwrap();
        let pair = report.pair().expect("pair");
        let push = report.push().expect("push");
        let ci = report.certain()[pair.pushed];
        assert_eq!(push.start_cam_m.z, ci.centre_cam_m.z);
        let to_centre = (ci.centre_cam_m - push.start_cam_m).normalize();
        assert!(to_centre.dot(&push.direction_cam) > 0.9999);
    }

    #[test]
    fn same_input_and_seed_give_identical_reports() {
        let s = three_blobs();
        let mut cfg = Config::PAPER;
        cfg.seed = 42;
        let first = s.run(&cfg).unwrap();
        let second = s.run(&cfg).unwrap();
        assert_eq!(first, second);
        assert!(first.push().is_some());
        // Bit-identical, not just equal up to float comparison quirks.
        let (p, q) = (first.push().unwrap(), second.push().unwrap());
        assert_eq!(p.start_px.map(Real::to_bits), q.start_px.map(Real::to_bits));
    }

    #[test]
    fn bad_inputs_are_errors_not_panics() {
        let cfg = Config::PAPER;
        let k = intrinsics();
        let heat = vec![200u8; W * H];
        let depth = vec![Z_M; W * H];
        let len = ActionScratchLen::for_config(&cfg, W, H);
        let mut c = vec![0.0; len.certain];
        let mut u = vec![0.0; len.uncertain];
        let mut d = vec![0.0; len.dist2];
        let mut n = vec![0u32; len.nearest];
        let mut r = vec![0u32; len.row_counts];
        let hv = ImageView::packed(W, H, &heat).unwrap();
        let short_depth = ImageView::packed(W, H - 1, &depth).unwrap();
        let scratch = ActionScratch {
            certain: &mut c,
            uncertain: &mut u,
            dist2: &mut d,
            nearest: &mut n,
            row_counts: &mut r,
        };
        assert_eq!(
            find_action(&hv, &short_depth, &k, &cfg, scratch).err(),
            Some(Error::SizeMismatch)
        );

        let dv = ImageView::packed(W, H, &depth).unwrap();
        let mut short = vec![0u32; len.nearest - 1];
        let scratch = ActionScratch {
            certain: &mut c,
            uncertain: &mut u,
            dist2: &mut d,
            nearest: &mut short,
            row_counts: &mut r,
        };
        assert_eq!(
            find_action(&hv, &dv, &k, &cfg, scratch).err(),
            Some(Error::BufferTooSmall {
                buffer: Buffer::Clusters,
                needed: len.nearest,
                got: len.nearest - 1
            })
        );
        // Room for x and y planes but not depth.
        let mut short = vec![0.0; 2 * len.samples];
        let scratch = ActionScratch {
            certain: &mut c,
            uncertain: &mut short,
            dist2: &mut d,
            nearest: &mut n,
            row_counts: &mut r,
        };
        assert_eq!(
            find_action(&hv, &dv, &k, &cfg, scratch).err(),
            Some(Error::BufferTooSmall {
                buffer: Buffer::Samples,
                needed: 3 * len.samples,
                got: 2 * len.samples
            })
        );

        let mut bad_cfg = cfg;
        bad_cfg.max_clusters = 0;
        assert_eq!(
            run(W, H, &heat, &depth, &k, &bad_cfg).err(),
            Some(Error::BadConfig)
        );
        let mut bad_k = k;
        bad_k.fx = Real::NAN;
        assert_eq!(
            run(W, H, &heat, &depth, &bad_k, &cfg).err(),
            Some(Error::NonFinite)
        );

        // No depth anywhere: nothing to cluster, no push.
        let s = three_blobs();
        let nan = vec![Real::NAN; W * H];
        let report = run(W, H, &s.heat, &nan, &k, &cfg).unwrap();
        assert!(report.certain().is_empty() && report.uncertain().is_empty());
        assert_eq!(report.push(), None);
        // Empty image.
        let report = run(0, 0, &[], &[], &k, &cfg).unwrap();
        assert!(report.certain().is_empty() && report.push().is_none());
    }

    #[test]
    fn random_inputs_never_panic_and_respect_the_capacity() {
        let mut rng = Pcg32::new(99);
        let specials = [0.0, -1.0, Real::NAN, Real::INFINITY, 1e30, 1e-30, 0.6, 0.61];
        for trial in 0..200u32 {
            let w = rng.below(24) as usize;
            let h = rng.below(24) as usize;
            let mut cfg = Config::PAPER;
            cfg.max_clusters = 2 + rng.below(MAX_CLUSTERS as u32 - 1) as usize;
            cfg.kmeans_samples = cfg.max_clusters + rng.below(80) as usize;
            cfg.kmeans_iters = 1 + rng.below(5);
            cfg.pair_max_m = 0.05 + rng.unit();
            cfg.uncertain_max_m = 0.01 + rng.unit();
            cfg.seed = u64::from(trial);
            let heat: Vec<u8> = (0..w * h)
                .map(|_| [0, 125, 200, rng.below(256) as u8][rng.below(4) as usize])
                .collect();
            let depth: Vec<Real> = (0..w * h)
                .map(|_| specials[rng.below(specials.len() as u32) as usize])
                .collect();
            let fx = [1e-6, 1.0, 300.0, 1e9][rng.below(4) as usize];
            let k = Intrinsics::new(fx, fx, w as Real / 2.0, h as Real / 2.0).unwrap();
            let report = run(w, h, &heat, &depth, &k, &cfg).unwrap();
            assert!(report.certain().len() <= cfg.max_clusters);
            assert!(report.uncertain().len() <= cfg.max_clusters);
            if let Some(push) = report.push() {
                assert!((push.direction_cam.norm() - 1.0).abs() < 1e-3);
            }
        }
    }

    #[test]
    fn elbow_rule() {
        assert_eq!(elbow(&[], 0.0), 0);
        assert_eq!(elbow(&[5.0], 0.0), 1);
        assert_eq!(elbow(&[10.0, 4.0], 0.0), 2);
        assert_eq!(elbow(&[10.0, 6.0], 0.0), 1);
        // Three well-separated groups: big drops up to k = 3, then a flat tail.
        let three = [100.0, 60.0, 5.0, 4.0, 3.5, 3.0, 2.5, 2.0];
        assert_eq!(elbow(&three, 0.0), 3);
        // Six touching objects (a measured curve): the raw-curve Kneedle would say 2.
        let six = [1.0, 0.422, 0.315, 0.217, 0.151, 0.09, 0.085, 0.079];
        assert_eq!(elbow(&six, 0.0), 6);
        // Constant ratio (a straight line in log) and a straight line have no elbow;
        // neither has a flat curve.
        let halving: Vec<Real> = (0..8).map(|i| 0.5f32.powi(i)).collect();
        assert_eq!(elbow(&halving, 0.0), 1);
        assert_eq!(elbow(&[8.0, 7.0, 6.0, 5.0, 4.0, 3.0, 2.0, 1.0], 0.0), 1);
        assert_eq!(elbow(&[1.0, 1.0, 1.0], 0.0), 1);
        assert_eq!(elbow(&[Real::NAN, 1.0, 0.0], 1.0), 1);
        // A perfect fit stays finite through the noise floor.
        assert_eq!(elbow(&[100.0, 60.0, 0.0, 0.0, 0.0], 1.0), 3);
    }

    #[test]
    fn row_skipping_sampler_matches_offering_every_pixel() {
        let (w, h) = (37, 23);
        let mut rng = Pcg32::new(5);
        let heat: Vec<u8> = (0..w * h).map(|_| rng.below(256) as u8).collect();
        let depth: Vec<Real> = (0..w * h)
            .map(|_| [0.6, Real::NAN, 0.0, 0.7][rng.below(4) as usize])
            .collect();
        let (hv, dv) = (
            ImageView::packed(w, h, &heat).unwrap(),
            ImageView::packed(w, h, &depth).unwrap(),
        );
        let cfg = Config::PAPER;
        for cap in [1, 7, 50, 10_000] {
            let mut bufs = [vec![0.0; 3 * cap], vec![0.0; 3 * cap]];
            let [cb, ub] = &mut bufs;
            let (mut cp, mut up) = (
                Planes::split(cb, cap).unwrap(),
                Planes::split(ub, cap).unwrap(),
            );
            let mut rows = vec![0u32; 2 * h];
            let (nc, nu) = sample_classes(
                &hv,
                &dv,
                &cfg,
                &mut Pcg32::new(9),
                &mut cp,
                &mut up,
                &mut rows,
            );
            // Reference: offer every pixel of each class in row-major order.
            let mut rng = Pcg32::new(9);
            let class_px = |want: Class| -> Vec<[Real; 3]> {
                hv.pixels()
                    .filter(|&(x, y, &v)| {
                        class_of(v, &cfg) == want && valid_depth(*dv.get(x, y).unwrap()).is_some()
                    })
                    .map(|(x, y, _)| [x as Real, y as Real, *dv.get(x, y).unwrap()])
                    .collect()
            };
            let (all_c, all_u) = (class_px(Class::Certain), class_px(Class::Uncertain));
            let mut sc = Sampler::new(all_c.len(), cap, &mut rng);
            let mut su = Sampler::new(all_u.len(), cap, &mut rng);
            let want_c: Vec<_> = all_c.iter().filter(|_| sc.offer().is_some()).collect();
            let want_u: Vec<_> = all_u.iter().filter(|_| su.offer().is_some()).collect();
            assert_eq!((nc, nu), (want_c.len(), want_u.len()), "cap {cap}");
            for (i, p) in want_c.iter().enumerate() {
                assert_eq!([cp.x[i], cp.y[i], cp.z[i]], **p, "cap {cap}");
            }
            for (i, p) in want_u.iter().enumerate() {
                assert_eq!([up.x[i], up.y[i], up.z[i]], **p, "cap {cap}");
            }
        }
    }

    #[test]
    fn sampling_keeps_the_requested_count_in_order() {
        let mut rng = Pcg32::new(3);
        for (total, cap) in [(0, 5), (3, 5), (5, 5), (1000, 7), (7, 6), (10_000, 2000)] {
            let mut s = Sampler::new(total, cap, &mut rng);
            let mut kept = Vec::new();
            for i in 0..total {
                if let Some(slot) = s.offer() {
                    assert_eq!(slot, kept.len());
                    kept.push(i);
                }
            }
            assert_eq!(kept.len(), total.min(cap), "total {total} cap {cap}");
            assert!(kept.windows(2).all(|p| p[0] < p[1]));
        }
    }

    #[test]
    fn scratch_len_is_capped_by_the_image() {
        let cfg = Config::PAPER;
        let len = ActionScratchLen::for_config(&cfg, 640, 480);
        assert_eq!(len.samples, cfg.kmeans_samples);
        assert_eq!(len.certain, 3 * cfg.kmeans_samples);
        assert_eq!(len.row_counts, 960);
        assert_eq!(
            len.bytes(),
            cfg.kmeans_samples * (12 + 12 + 4 + 4) + 960 * 4
        );
        assert_eq!(ActionScratchLen::for_config(&cfg, 10, 10).samples, 100);
        let huge = ActionScratchLen::for_config(
            &Config {
                kmeans_samples: usize::MAX,
                ..cfg
            },
            usize::MAX,
            2,
        );
        assert_eq!(huge.bytes(), usize::MAX);
    }
}
