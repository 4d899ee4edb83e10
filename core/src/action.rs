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
//! 1. **Classes.** A pixel is *certain* when `heatmap >= certain_from` (paper `l_u`),
//!    *uncertain* when `uncertain_from <= heatmap < certain_from` (paper `l_l`), and
//!    *table* below. Only pixels with a depth reading ([`valid_depth`]) are sampled.
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
//!      `n₁ = round(L₁ / region_cell_m)` clamped to `2..=4` and `n₂ = round(L₂ /
//!      region_cell_m)` clamped to `1..=2` and to at most `4 / n₁`. The pieces start at
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
//!    Qualifying pairs are ranked by the distance of their uncertain centre, then by the
//!    distance between their centres, then by `(i, j)` in index order.
//! 8. **Which pair and cluster are pushed.** Pairs are tried in rank order. In a pair,
//!    the cluster with fewer samples is tried first (the smaller region moves more readily
//!    and disturbs the scene less; ties: the lower index), then the other; the first that
//!    has a push (step 9) is the pushed cluster `C_i` and the pair is reported with it.
//!    When no qualifying pair has a push, the best pair is reported without one.
//! 9. **Push point.** The *region* of certain cluster `q` is the set of certain pixels in
//!    `q`'s region of step 3 whose nearest pixel centre among that region's clusters is
//!    `q`. From the pixel centre `C_i` the walk goes in 0.5 px steps along the line
//!    through `C_i` perpendicular to `C_i → C_j`, on a side drawn from the PRNG (one draw
//!    per pair tried, used for both of its clusters). Once the walk has been inside
//!    `C_i`'s region, the first point whose pixel is table is the push start `P`: the
//!    walk leaves the whole object (or pack of objects) and `P` lies on its outer rim or
//!    just beyond, never in a cut or a band between two objects, and `P → C_i` is
//!    perpendicular to the pair (a shear of `C_i` along `C_j`). A side fails when the
//!    walk reaches the image border, or, after having been in `C_i`'s region, a pixel of
//!    another cluster's region (that side leads into another object); then the other side
//!    is tried.
//! 10. **Push.** `P` is back-projected at the depth of the cluster's 3-D centre, so the
//!     tool starts at the object's height and not on the table; the direction is the unit
//!     vector from there to the cluster's 3-D centre; the length is
//!     [`Config::push_len_m`].
//!
//! Cost: two vectorised passes over the pixels (class counts, and the per-row maximum
//! that skips rows without a certain pixel), a scan of the rows that hold certain pixels
//! (runs) and of the rows that hold samples, near-linear union-find over the runs,
//! `O(samples)` to give samples their regions, `O(samples · 4 · kmeans_iters)` per split
//! region, `O(samples · K² · kmeans_iters)` for the uncertain k-means (the inner loop
//! runs over sample planes and vectorises), `O(K² · (K + K_u + line · K))` for the pairs
//! and `O(width + height)` per walk (up to four per pair tried). At 640×480 with
//! [`Config::PAPER`] a call takes about 1 ms on one x86-64 core (SSE2 only); the run
//! scratch is the largest buffer, `4 · height · ⌈width/2⌉` entries (2.4 MB at 640×480).

use heapless::Vec as FixedVec;
use nalgebra::{Matrix3, Point3, Vector3, linalg::SymmetricEigen};

use crate::{
    Buffer, Config, Error, Intrinsics, MAX_CLUSTERS,
    error::check_len,
    image::{ImageView, valid_depth},
    math::{Real, ln, round, sqrt},
    rng::Pcg32,
};

/// Step of the walk from a cluster centre out of its object, pixels.
const WALK_STEP_PX: Real = 0.5;

/// Lloyd stops when an update would move the centres by less than this in total
/// (root of the summed squared shifts), pixels: the push is planned at pixel resolution.
const LLOYD_TOL_PX: Real = 0.25;

/// Smallest normalised drop below the chord that counts as an elbow.
const KNEE_MIN: Real = 0.01;

/// Most pieces one oversized certain region is split into.
const MAX_PIECES: usize = 4;

/// Most pieces along a region's long axis.
const MAX_PIECES_LONG: usize = 4;

/// Most pieces along a region's short axis.
const MAX_PIECES_SHORT: usize = 2;

/// Most iterations of the eigen-solver for a region's 3-D covariance.
const EIGEN_ITERS: usize = 64;

/// Most table the line between the two centres of a pair may cross, metres: where two
/// rounded objects touch at a point, the line clips the corners of their rims.
const LINE_TABLE_MAX_M: Real = 0.005;

/// Most certain pairs: every pair of [`MAX_CLUSTERS`] clusters.
const MAX_PAIRS: usize = MAX_CLUSTERS * (MAX_CLUSTERS - 1) / 2;

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
    /// segment.
    pub uncertain: usize,
    /// 3-D distance between the two certain centres, metres.
    pub pair_dist_m: Real,
    /// 3-D distance from the uncertain centre to the pair's segment, metres.
    pub uncertain_dist_m: Real,
}

/// A push: start just outside the pushed object, move towards the pushed cluster's centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Push {
    /// Start pixel `[x, y]` (sub-pixel): the first pixel of the walk out of the pushed
    /// cluster that is no longer object (heat below [`Config::uncertain_from`]).
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
    check_len(Buffer::Runs, len.runs, scratch.runs.len())?;
    check_len(Buffer::Runs, len.row_runs, scratch.row_runs.len())?;
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
    let mut pair = pairs.first().copied();
    let mut push = None;
    for p in &pairs {
        if let Some((p, found)) = plan_push(&map, p, intrinsics, cfg, &mut rng) {
            pair = Some(p);
            push = Some(found);
            break;
        }
    }
    Ok(ActionReport {
        certain: regions.clusters,
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

/// "No region" in the run planes and in [`ActionScratch::nearest`].
const NONE: u32 = u32::MAX;

/// Runs of certain pixels as four planes of equal length (module docs, step 3).
struct RunPlanes<'a> {
    /// First pixel of the run.
    x0: &'a mut [u32],
    /// One past the last pixel of the run.
    x1: &'a mut [u32],
    /// Union-find parent; after [`certain_clusters`] the root run of the run's region.
    parent: &'a mut [u32],
    /// Pixel count while labelling; then the index of the run's candidate region, or
    /// [`NONE`].
    aux: &'a mut [u32],
}

impl<'a> RunPlanes<'a> {
    /// Splits `buf` into four planes of `r` entries; `None` if it is shorter than `4·r`.
    fn split(buf: &'a mut [u32], r: usize) -> Option<Self> {
        let (x0, rest) = buf.split_at_mut_checked(r)?;
        let (x1, rest) = rest.split_at_mut_checked(r)?;
        let (parent, rest) = rest.split_at_mut_checked(r)?;
        let aux = rest.get_mut(..r)?;
        Some(Self {
            x0,
            x1,
            parent,
            aux,
        })
    }

    fn view(&self, n: usize) -> Runs<'_> {
        Runs {
            x0: self.x0.get(..n).unwrap_or(&[]),
            x1: self.x1.get(..n).unwrap_or(&[]),
            aux: self.aux.get(..n).unwrap_or(&[]),
        }
    }
}

/// Read-only view of the labelled runs.
#[derive(Clone, Copy)]
struct Runs<'a> {
    x0: &'a [u32],
    x1: &'a [u32],
    aux: &'a [u32],
}

impl Runs<'_> {
    /// The run holding pixel `(x, y)`, if that pixel is certain.
    fn at(&self, row_runs: &[u32], x: usize, y: usize) -> Option<usize> {
        let start = *row_runs.get(y)? as usize;
        let end = *row_runs.get(y.checked_add(1)?)? as usize;
        let k = self
            .x0
            .get(start..end)?
            .partition_point(|&a| a as usize <= x);
        let r = start.checked_add(k.checked_sub(1)?)?;
        (x < *self.x1.get(r)? as usize).then_some(r)
    }

    /// The candidate region of pixel `(x, y)` ([`NONE`] when it is in none).
    fn region_at(&self, row_runs: &[u32], x: usize, y: usize) -> u32 {
        self.at(row_runs, x, y)
            .and_then(|r| self.aux.get(r).copied())
            .unwrap_or(NONE)
    }
}

/// Root of run `r`. Parents never exceed their run's index, so the walk ends; it halves
/// the path as it goes.
fn find_root(parent: &mut [u32], mut r: usize) -> usize {
    loop {
        let Some(&p) = parent.get(r) else {
            return r;
        };
        let p = p as usize;
        if p >= r {
            return r;
        }
        let grand = parent.get(p).copied().unwrap_or(p as u32);
        if let Some(slot) = parent.get_mut(r) {
            *slot = grand;
        }
        r = p;
    }
}

/// Joins the regions of runs `a` and `b`; the smaller root index stays the root.
fn union(parent: &mut [u32], a: usize, b: usize) {
    let (ra, rb) = (find_root(parent, a), find_root(parent, b));
    let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
    if lo != hi
        && let Some(slot) = parent.get_mut(hi)
    {
        *slot = lo as u32;
    }
}

/// Labels the 4-connected regions of certain pixels (`heat >= certain_from`; depth is not
/// consulted) as runs with union-find; returns the number of runs. Rows without a certain
/// pixel are skipped after a vectorised maximum.
fn label_runs(
    heatmap: &ImageView<'_, u8>,
    certain_from: u8,
    runs: &mut RunPlanes<'_>,
    row_runs: &mut [u32],
) -> usize {
    let cap = runs.x0.len().min(NONE as usize);
    let mut n = 0usize;
    let mut prev = 0..0;
    for y in 0..heatmap.height() {
        let start = n;
        if let Some(slot) = row_runs.get_mut(y) {
            *slot = n as u32;
        }
        let row = heatmap.row(y).unwrap_or(&[]);
        let row = row.get(..row.len().min(NONE as usize)).unwrap_or(&[]);
        if row.iter().fold(0u8, |m, &v| m.max(v)) >= certain_from {
            let mut x = 0usize;
            while let Some(off) = row
                .get(x..)
                .and_then(|r| r.iter().position(|&v| v >= certain_from))
            {
                let x0 = x + off;
                let len = row.get(x0..).map_or(0, |r| {
                    r.iter().position(|&v| v < certain_from).unwrap_or(r.len())
                });
                let x1 = x0 + len;
                if n < cap
                    && let (Some(a), Some(b), Some(p), Some(c)) = (
                        runs.x0.get_mut(n),
                        runs.x1.get_mut(n),
                        runs.parent.get_mut(n),
                        runs.aux.get_mut(n),
                    )
                {
                    (*a, *b, *p, *c) = (x0 as u32, x1 as u32, n as u32, len as u32);
                    n += 1;
                }
                x = x1;
            }
            // 4-connectivity: runs of consecutive rows join where their x ranges overlap.
            let (mut i, mut j) = (prev.start, start);
            while i < prev.end && j < n {
                let (Some(&a0), Some(&a1), Some(&b0), Some(&b1)) = (
                    runs.x0.get(i),
                    runs.x1.get(i),
                    runs.x0.get(j),
                    runs.x1.get(j),
                ) else {
                    break;
                };
                if a0 < b1 && b0 < a1 {
                    union(runs.parent, i, j);
                }
                if a1 <= b1 {
                    i += 1;
                } else {
                    j += 1;
                }
            }
        }
        prev = start..n;
    }
    if let Some(slot) = row_runs.get_mut(heatmap.height()) {
        *slot = n as u32;
    }
    n
}

/// Sums over the samples of one candidate region (module docs, step 4).
#[derive(Clone, Copy)]
struct RegionSums {
    /// Pixels of the region.
    pixels: u32,
    samples: u32,
    /// First sample's pixel; pixel sums are taken relative to it (precision).
    px_ref: [Real; 2],
    /// Sum of `(x, y) − px_ref`.
    s_px: [Real; 2],
    /// Sums of `dx²`, `dx·dy`, `dy²` relative to `px_ref`.
    s_pxx: [Real; 3],
    /// First sample's back-projected point; 3-D sums are relative to it.
    p_ref: Vector3<Real>,
    /// Sum of `p − p_ref`.
    s_p: Vector3<Real>,
    /// Sum of `(p − p_ref)(p − p_ref)ᵀ`.
    s_pp: Matrix3<Real>,
}

impl RegionSums {
    const fn new(pixels: u32) -> Self {
        Self {
            pixels,
            samples: 0,
            px_ref: [0.0; 2],
            s_px: [0.0; 2],
            s_pxx: [0.0; 3],
            p_ref: Vector3::new(0.0, 0.0, 0.0),
            s_p: Vector3::new(0.0, 0.0, 0.0),
            s_pp: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        }
    }

    fn add(&mut self, px: [Real; 2], p: Vector3<Real>) {
        if self.samples == 0 {
            self.px_ref = px;
            self.p_ref = p;
        }
        self.samples = self.samples.saturating_add(1);
        let (dx, dy) = (px[0] - self.px_ref[0], px[1] - self.px_ref[1]);
        self.s_px[0] += dx;
        self.s_px[1] += dy;
        self.s_pxx[0] += dx * dx;
        self.s_pxx[1] += dx * dy;
        self.s_pxx[2] += dy * dy;
        let d = p - self.p_ref;
        self.s_p += d;
        self.s_pp += d * d.transpose();
    }

    fn mean_px(&self) -> [Real; 2] {
        let inv = 1.0 / self.samples.max(1) as Real;
        [
            self.px_ref[0] + self.s_px[0] * inv,
            self.px_ref[1] + self.s_px[1] * inv,
        ]
    }

    fn mean_cam(&self) -> Vector3<Real> {
        self.p_ref + self.s_p / self.samples.max(1) as Real
    }

    /// Lengths `L = √(12 λ)` along the two longest principal axes of the sampled 3-D
    /// points (a uniform rectangle of side `L` has variance `L²/12` along it); `None` when
    /// the covariance is not finite or the solver does not converge.
    fn metric_lengths(&self) -> Option<(Real, Real)> {
        let inv = 1.0 / self.samples.max(1) as Real;
        let m = self.s_p * inv;
        let cov = self.s_pp * inv - m * m.transpose();
        if !cov.iter().all(|v| v.is_finite()) {
            return None;
        }
        let eig = SymmetricEigen::try_new(cov, Real::EPSILON, EIGEN_ITERS)?;
        let mut ev = [eig.eigenvalues.x, eig.eigenvalues.y, eig.eigenvalues.z];
        ev.sort_unstable_by(|a, b| b.total_cmp(a));
        let [l1, l2, _] = ev.map(|v| sqrt(12.0 * v.max(0.0)));
        Some((l1, l2))
    }

    /// Principal axes of the sampled pixels: unit long axis and the lengths
    /// `√(12 λ)` along the long and the short axis, pixels.
    fn pixel_axes(&self) -> ([Real; 2], Real, Real) {
        let inv = 1.0 / self.samples.max(1) as Real;
        let (mx, my) = (self.s_px[0] * inv, self.s_px[1] * inv);
        let cxx = (self.s_pxx[0] * inv - mx * mx).max(0.0);
        let cxy = self.s_pxx[1] * inv - mx * my;
        let cyy = (self.s_pxx[2] * inv - my * my).max(0.0);
        let half_tr = 0.5 * (cxx + cyy);
        let disc = sqrt((half_tr * half_tr - (cxx * cyy - cxy * cxy)).max(0.0));
        let (l1, l2) = (half_tr + disc, (half_tr - disc).max(0.0));
        let (ux, uy) = if cxy.abs() > 1e-6 * (cxx + cyy) {
            (l1 - cyy, cxy)
        } else if cxx >= cyy {
            (1.0, 0.0)
        } else {
            (0.0, 1.0)
        };
        let norm = sqrt(ux * ux + uy * uy);
        let axis = if norm > 0.0 && norm.is_finite() {
            [ux / norm, uy / norm]
        } else {
            [1.0, 0.0]
        };
        (axis, sqrt(12.0 * l1), sqrt(12.0 * l2))
    }
}

/// The certain clusters and, for each, its candidate region.
struct CertainClusters {
    clusters: FixedVec<Cluster, MAX_CLUSTERS>,
    region_of: FixedVec<u32, MAX_CLUSTERS>,
}

/// Certain clusters from the labelled runs and the certain samples (module docs,
/// steps 3-4). Leaves each run's candidate region (or [`NONE`]) in `runs.aux` and each
/// run's root in `runs.parent`; uses `nearest` for the samples' regions.
fn certain_clusters(
    runs: &mut RunPlanes<'_>,
    n_runs: usize,
    row_runs: &[u32],
    s: &Samples<'_>,
    nearest: &mut [u32],
    intrinsics: &Intrinsics,
    cfg: &Config,
) -> CertainClusters {
    let mut out = CertainClusters {
        clusters: FixedVec::new(),
        region_of: FixedVec::new(),
    };
    // Roots and pixel counts: a run's root index never exceeds its own, so in index
    // order every run's root is final when the run is reached.
    for r in 0..n_runs {
        let root = find_root(runs.parent, r);
        if let Some(p) = runs.parent.get_mut(r) {
            *p = root as u32;
        }
        if root != r {
            let count = runs.aux.get(r).copied().unwrap_or(0);
            if let Some(c) = runs.aux.get_mut(root) {
                *c = c.saturating_add(count);
            }
        }
    }
    // The MAX_CLUSTERS largest regions (ties: earlier root), in root order.
    let mut top: FixedVec<(u32, u32), MAX_CLUSTERS> = FixedVec::new();
    // Once `top` is full: the index of its smallest entry (latest on ties).
    let smallest = |top: &FixedVec<(u32, u32), MAX_CLUSTERS>| {
        top.iter()
            .enumerate()
            .min_by(|(_, a), (_, b)| a.0.cmp(&b.0).then(b.1.cmp(&a.1)))
            .map(|(i, _)| i)
    };
    let mut worst: Option<usize> = None;
    for (r, (&parent, &pixels)) in runs
        .parent
        .iter()
        .zip(runs.aux.iter())
        .take(n_runs)
        .enumerate()
    {
        if parent as usize != r {
            continue;
        }
        let entry = (pixels, r as u32);
        if top.push(entry).is_err() {
            // Full: replace the smallest if the new region is larger.
            if let Some(slot) = worst.and_then(|i| top.get_mut(i))
                && slot.0 < pixels
            {
                *slot = entry;
                worst = smallest(&top);
            }
        } else if top.is_full() {
            worst = smallest(&top);
        }
    }
    top.sort_unstable_by_key(|&(_, root)| root);
    // Each run's candidate region.
    for (r, (&parent, aux)) in runs
        .parent
        .iter()
        .zip(runs.aux.iter_mut())
        .take(n_runs)
        .enumerate()
    {
        if parent as usize == r {
            *aux = NONE;
        }
    }
    for (i, &(_, root)) in top.iter().enumerate() {
        if let Some(aux) = runs.aux.get_mut(root as usize) {
            *aux = i as u32;
        }
    }
    for r in 0..n_runs {
        let root = runs.parent.get(r).map_or(r, |&p| p as usize);
        if root != r {
            let region = runs.aux.get(root).copied().unwrap_or(NONE);
            if let Some(aux) = runs.aux.get_mut(r) {
                *aux = region;
            }
        }
    }

    // Sample sums per region.
    let mut sums: FixedVec<RegionSums, MAX_CLUSTERS> = FixedVec::new();
    for &(pixels, _) in &top {
        // `top` holds at most MAX_CLUSTERS entries, the capacity of `sums`.
        let _ = sums.push(RegionSums::new(pixels));
    }
    let view = runs.view(n_runs);
    for (((&x, &y), &z), region) in s.x.iter().zip(s.y).zip(s.z).zip(nearest.iter_mut()) {
        // Samples are pixel coordinates of the image: whole, non-negative numbers.
        *region = view.region_at(row_runs, x as usize, y as usize);
        if let Some(sum) = sums.get_mut(*region as usize) {
            sum.add([x, y], intrinsics.back_project(x, y, z).coords);
        }
    }

    // Pieces: kept regions, oversized ones split.
    let mut pieces: FixedVec<(Cluster, u32), { MAX_CLUSTERS * MAX_PIECES }> = FixedVec::new();
    for (region, sum) in sums.iter().enumerate() {
        if sum.samples == 0 {
            continue;
        }
        let centre = sum.mean_cam();
        let m_per_px2 = centre.z * centre.z / (intrinsics.fx * intrinsics.fy);
        let area_m2 = sum.pixels as Real * m_per_px2;
        if area_m2.is_nan() || area_m2 < cfg.region_min_area_m2 {
            continue;
        }
        let lengths = sum.metric_lengths();
        match lengths {
            Some((long, short)) if long > cfg.region_max_len_m => {
                let per_axis = |len: Real, lo: usize, hi: usize| {
                    (round(len / cfg.region_cell_m) as usize).clamp(lo, hi)
                };
                let n_long = per_axis(long, 2, MAX_PIECES_LONG);
                let n_short = per_axis(short, 1, MAX_PIECES_SHORT).min(MAX_PIECES / n_long);
                split_region(
                    sum,
                    region as u32,
                    [n_long, n_short.max(1)],
                    s,
                    nearest,
                    intrinsics,
                    cfg,
                    &mut pieces,
                );
            }
            _ => {
                let _ = pieces.push((
                    Cluster {
                        centre_px: sum.mean_px(),
                        centre_cam_m: Point3::from(centre),
                        samples: sum.samples,
                    },
                    region as u32,
                ));
            }
        }
    }

    // At most max_clusters: the ones with the most samples (ties: earlier), in order.
    let keep = cfg.max_clusters.min(MAX_CLUSTERS);
    for (i, (cluster, region)) in pieces.iter().enumerate() {
        let better = pieces
            .iter()
            .enumerate()
            .filter(|&(j, (c, _))| {
                c.samples > cluster.samples || (c.samples == cluster.samples && j < i)
            })
            .count();
        if better < keep {
            let _ = out.clusters.push(*cluster);
            let _ = out.region_of.push(*region);
        }
    }
    out
}

/// Splits one oversized region into a `grid[0] × grid[1]` grid of pieces along its
/// pixel principal axes, refined by Lloyd iterations over the region's samples (module
/// docs, step 4); appends the non-empty pieces.
#[allow(clippy::too_many_arguments)]
fn split_region(
    sum: &RegionSums,
    region: u32,
    grid: [usize; 2],
    s: &Samples<'_>,
    nearest: &[u32],
    intrinsics: &Intrinsics,
    cfg: &Config,
    pieces: &mut FixedVec<(Cluster, u32), { MAX_CLUSTERS * MAX_PIECES }>,
) {
    let (axis, long_px, short_px) = sum.pixel_axes();
    let across = [-axis[1], axis[0]];
    let mean = sum.mean_px();
    let mut centres: FixedVec<[Real; 2], MAX_PIECES> = FixedVec::new();
    for a in 0..grid[0] {
        for b in 0..grid[1] {
            let u = ((a as Real + 0.5) / grid[0] as Real - 0.5) * long_px;
            let v = ((b as Real + 0.5) / grid[1] as Real - 0.5) * short_px;
            let _ = centres.push([
                mean[0] + u * axis[0] + v * across[0],
                mean[1] + u * axis[1] + v * across[1],
            ]);
        }
    }
    let members = || {
        s.x.iter()
            .zip(s.y)
            .zip(s.z)
            .zip(nearest)
            .filter(move |(_, r)| **r == region)
            .map(|(((&x, &y), &z), _)| (x, y, z))
    };
    let nearest_piece = |centres: &[[Real; 2]], x: Real, y: Real| -> usize {
        let mut best = (Real::INFINITY, 0);
        for (k, &c) in centres.iter().enumerate() {
            let d = dist2_to(x, y, c);
            if d < best.0 {
                best = (d, k);
            }
        }
        best.1
    };
    for _ in 0..cfg.kmeans_iters {
        let mut acc = [([0.0 as Real; 2], 0u32); MAX_PIECES];
        for (x, y, _) in members() {
            if let Some((sum, count)) = acc.get_mut(nearest_piece(&centres, x, y)) {
                sum[0] += x;
                sum[1] += y;
                *count += 1;
            }
        }
        let mut shift2 = 0.0;
        let mut means = [[0.0 as Real; 2]; MAX_PIECES];
        for ((m, c), (sum, count)) in means.iter_mut().zip(centres.iter()).zip(&acc) {
            *m = *c;
            if *count > 0 {
                let inv = 1.0 / *count as Real;
                *m = [sum[0] * inv, sum[1] * inv];
                shift2 += dist2_to(m[0], m[1], *c);
            }
        }
        // Converged (or not finite): keep the centres that made the last assignment.
        if shift2.is_nan() || shift2 <= LLOYD_TOL_PX * LLOYD_TOL_PX {
            break;
        }
        for (c, m) in centres.iter_mut().zip(&means) {
            *c = *m;
        }
    }
    let mut acc = [(Vector3::<Real>::zeros(), 0u32); MAX_PIECES];
    for (x, y, z) in members() {
        if let Some((sum, count)) = acc.get_mut(nearest_piece(&centres, x, y)) {
            *sum += intrinsics.back_project(x, y, z).coords;
            *count += 1;
        }
    }
    for (c, (sum, count)) in centres.iter().zip(&acc) {
        if *count > 0 {
            let _ = pieces.push((
                Cluster {
                    centre_px: *c,
                    centre_cam_m: Point3::from(sum / *count as Real),
                    samples: *count,
                },
                region,
            ));
        }
    }
}

/// What a pixel is to the walk of the push.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Px {
    /// Off the image.
    Off,
    /// Heat below [`Config::uncertain_from`]: not an object.
    Background,
    /// An uncertain pixel, or a certain pixel in no cluster.
    Object,
    /// A certain pixel of this cluster.
    Cluster(usize),
}

/// Which cluster each certain pixel belongs to (module docs, step 9).
struct RegionMap<'a> {
    heatmap: &'a ImageView<'a, u8>,
    runs: Runs<'a>,
    row_runs: &'a [u32],
    clusters: &'a [Cluster],
    region_of: &'a [u32],
    cfg: &'a Config,
}

impl RegionMap<'_> {
    fn at(&self, x: i64, y: i64) -> Px {
        let Some(heat) = self.heatmap.at(x, y) else {
            return Px::Off;
        };
        if heat < self.cfg.uncertain_from {
            return Px::Background;
        }
        if heat < self.cfg.certain_from {
            return Px::Object;
        }
        // On the image, so both are non-negative.
        let region = self.runs.region_at(self.row_runs, x as usize, y as usize);
        let mut best: Option<(Real, usize)> = None;
        for (i, (c, &r)) in self.clusters.iter().zip(self.region_of).enumerate() {
            if r == region && region != NONE {
                let d = dist2_to(x as Real, y as Real, c.centre_px);
                if best.is_none_or(|(b, _)| d < b) {
                    best = Some((d, i));
                }
            }
        }
        best.map_or(Px::Object, |(_, i)| Px::Cluster(i))
    }
}

/// Whether the straight line between the pixel centres of clusters `i` and `j` stays on
/// object (module docs, step 7): every pixel on it is in `i` or `j`, uncertain, or certain
/// in no cluster, except at most [`LINE_TABLE_MAX_M`] of it (with the line's length taken
/// as `pair_dist_m`) on the table; none is off the image or in a third cluster.
fn line_stays_on_objects(map: &RegionMap<'_>, i: usize, j: usize, pair_dist_m: Real) -> bool {
    let (Some(a), Some(b)) = (map.clusters.get(i), map.clusters.get(j)) else {
        return false;
    };
    let (dx, dy) = (
        b.centre_px[0] - a.centre_px[0],
        b.centre_px[1] - a.centre_px[1],
    );
    let len = sqrt(dx * dx + dy * dy);
    if !len.is_finite() {
        return false;
    }
    // One step per pixel of length; centres lie on the image, so the line is shorter
    // than width + height.
    let (width, height) = map.heatmap.size();
    let steps = (len as usize)
        .saturating_add(1)
        .min(width.saturating_add(height));
    let step_m = pair_dist_m / steps.max(1) as Real;
    let mut table_m = 0.0;
    for s in 0..=steps {
        let t = s as Real / steps.max(1) as Real;
        let pixel = (
            round(a.centre_px[0] + t * dx) as i64,
            round(a.centre_px[1] + t * dy) as i64,
        );
        match map.at(pixel.0, pixel.1) {
            Px::Cluster(q) if q == i || q == j => {}
            Px::Object => {}
            Px::Background => {
                table_m += step_m;
                if table_m.is_nan() || table_m > LINE_TABLE_MAX_M {
                    return false;
                }
            }
            Px::Cluster(_) | Px::Off => return false,
        }
    }
    true
}

/// Whether `i` and `j` are neighbours in the relative neighbourhood graph of the certain
/// 3-D centres: no third centre is closer to both than they are to each other.
fn relative_neighbours(certain: &[Cluster], i: usize, j: usize) -> bool {
    let (Some(ci), Some(cj)) = (certain.get(i), certain.get(j)) else {
        return false;
    };
    let d_ij = (cj.centre_cam_m - ci.centre_cam_m).norm();
    certain.iter().enumerate().all(|(k, c)| {
        k == i
            || k == j
            || !((c.centre_cam_m - ci.centre_cam_m).norm() < d_ij
                && (c.centre_cam_m - cj.centre_cam_m).norm() < d_ij)
    })
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

/// Every qualifying certain pair, best first (module docs, step 7).
fn rank_pairs(
    map: &RegionMap<'_>,
    uncertain: &[Cluster],
    cfg: &Config,
) -> FixedVec<Pair, MAX_PAIRS> {
    let certain = map.clusters;
    let mut pairs: FixedVec<Pair, MAX_PAIRS> = FixedVec::new();
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
            if !relative_neighbours(certain, i, j) || !line_stays_on_objects(map, i, j, pair_dist_m)
            {
                continue;
            }
            let (pushed, other) = if cj.samples < ci.samples {
                (j, i)
            } else {
                (i, j)
            };
            let _ = pairs.push(Pair {
                pushed,
                other,
                uncertain: n,
                pair_dist_m,
                uncertain_dist_m,
            });
        }
    }
    // Nearest uncertain centre first, then the closer pair, then (i, j) order.
    let order = |p: &Pair| (p.pushed.min(p.other), p.pushed.max(p.other));
    pairs.sort_unstable_by(|a, b| {
        a.uncertain_dist_m
            .total_cmp(&b.uncertain_dist_m)
            .then(a.pair_dist_m.total_cmp(&b.pair_dist_m))
            .then(order(a).cmp(&order(b)))
    });
    pairs
}

/// Walks from `from` along the unit `dir` (pixels); returns the first point that is not
/// object after the walk has been in cluster `pushed`. `None` when the image border, or
/// another cluster after `pushed`, comes first.
fn walk_out(
    map: &RegionMap<'_>,
    pushed: usize,
    from: [Real; 2],
    dir: [Real; 2],
) -> Option<[Real; 2]> {
    let (width, height) = map.heatmap.size();
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
        match map.at(pixel.0, pixel.1) {
            Px::Off => return None,
            Px::Cluster(q) if q == pushed => entered = true,
            Px::Cluster(_) if entered => return None,
            Px::Background if entered => return Some(p),
            Px::Cluster(_) | Px::Object | Px::Background => {}
        }
    }
    None
}

/// The push for `pair` (module docs, steps 8-10), with the pair as pushed: the pair's
/// pushed cluster first, then the other one.
fn plan_push(
    map: &RegionMap<'_>,
    pair: &Pair,
    intrinsics: &Intrinsics,
    cfg: &Config,
    rng: &mut Pcg32,
) -> Option<(Pair, Push)> {
    let side: Real = if rng.below(2) == 0 { 1.0 } else { -1.0 };
    for (pushed, other) in [(pair.pushed, pair.other), (pair.other, pair.pushed)] {
        let (Some(ci), Some(cj)) = (map.clusters.get(pushed), map.clusters.get(other)) else {
            continue;
        };
        let dx = cj.centre_px[0] - ci.centre_px[0];
        let dy = cj.centre_px[1] - ci.centre_px[1];
        let len = sqrt(dx * dx + dy * dy);
        if len.is_nan() || len <= 1e-3 {
            continue;
        }
        let perp = [-dy / len * side, dx / len * side];
        let Some(start_px) = walk_out(map, pushed, ci.centre_px, perp)
            .or_else(|| walk_out(map, pushed, ci.centre_px, [-perp[0], -perp[1]]))
        else {
            continue;
        };
        let start_cam_m = intrinsics.back_project(start_px[0], start_px[1], ci.centre_cam_m.z);
        let towards = ci.centre_cam_m - start_cam_m;
        let norm = towards.norm();
        if !(norm > 0.0 && norm.is_finite()) {
            continue;
        }
        let direction_cam = towards / norm;
        if !direction_cam.iter().all(|v| v.is_finite()) {
            continue;
        }
        let push = Push {
            start_px,
            target_px: ci.centre_px,
            start_cam_m,
            direction_cam,
            length_m: cfg.push_len_m,
        };
        return Some((
            Pair {
                pushed,
                other,
                ..*pair
            },
            push,
        ));
    }
    None
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
        let mut runs = vec![0u32; len.runs];
        let mut row_runs = vec![0u32; len.row_runs];
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
                runs: &mut runs,
                row_runs: &mut row_runs,
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

    /// An uncertain centre at pixel `(x, y)` (for [`ranked`]).
    fn uncertain_at(x: Real, y: Real) -> Cluster {
        Cluster {
            centre_px: [x, y],
            centre_cam_m: intrinsics().back_project(x, y, Z_M),
            samples: 100,
        }
    }

    /// FindAction's certain clusters of `s`, and its qualifying pairs, best first, against
    /// the given uncertain centres (instead of k-means ones).
    fn ranked(s: &Scene, cfg: &Config, uncertain: &[Cluster]) -> (Vec<Cluster>, Vec<Pair>) {
        let k = intrinsics();
        let heat = ImageView::packed(W, H, &s.heat).unwrap();
        let depth = ImageView::packed(W, H, &s.depth).unwrap();
        let len = ActionScratchLen::for_config(cfg, W, H);
        let (mut cbuf, mut ubuf) = (vec![0.0; len.certain], vec![0.0; len.uncertain]);
        let mut rows = vec![0u32; len.row_counts];
        let mut runs_buf = vec![0u32; len.runs];
        let mut row_runs = vec![0u32; len.row_runs];
        let mut nearest = vec![0u32; len.nearest];
        let mut cp = Planes::split(&mut cbuf, len.samples).unwrap();
        let mut up = Planes::split(&mut ubuf, len.samples).unwrap();
        let mut rng = Pcg32::new(cfg.seed);
        let (nc, _) = sample_classes(&heat, &depth, cfg, &mut rng, &mut cp, &mut up, &mut rows);
        let mut runs = RunPlanes::split(&mut runs_buf, len.max_runs).unwrap();
        let n_runs = label_runs(&heat, cfg.certain_from, &mut runs, &mut row_runs);
        let found = certain_clusters(
            &mut runs,
            n_runs,
            &row_runs,
            &cp.prefix(nc),
            &mut nearest,
            &k,
            cfg,
        );
        let map = RegionMap {
            heatmap: &heat,
            runs: runs.view(n_runs),
            row_runs: &row_runs,
            clusters: &found.clusters,
            region_of: &found.region_of,
            cfg,
        };
        let pairs = rank_pairs(&map, uncertain, cfg);
        (found.clusters.to_vec(), pairs.to_vec())
    }

    /// Sorted cluster indices of a pair.
    fn members(p: &Pair) -> [usize; 2] {
        [p.pushed.min(p.other), p.pushed.max(p.other)]
    }

    /// A, B and C with uncertain bands across the A–B and the A–C gaps.
    fn three_blobs_two_bands() -> Scene {
        let mut s = three_blobs();
        s.rect(100, 106, 121, 115, 130);
        s
    }

    #[test]
    fn the_pair_nearest_an_uncertain_centre_wins_over_another_qualifying_pair() {
        let s = three_blobs_two_bands();
        let cfg = Config::PAPER;
        // One centre on the A–B segment, one 1 cm beside the A–C segment.
        let (certain, pairs) = ranked(
            &s,
            &cfg,
            &[uncertain_at(130.0, 130.0), uncertain_at(115.0, 110.0)],
        );
        let a = find(&certain, A.0, A.1).expect("A");
        let b = find(&certain, B.0, B.1).expect("B");
        let c = find(&certain, C.0, C.1).expect("C");
        let want = |i: usize, j: usize| [i.min(j), i.max(j)];
        assert_eq!(
            pairs.iter().map(members).collect::<Vec<_>>(),
            [want(a, b), want(a, c)]
        );
        assert!((pairs[1].uncertain_dist_m - 0.01).abs() < 1e-3, "{pairs:?}");
        // Swapped: the centre on the A–C segment wins.
        let (_, pairs) = ranked(
            &s,
            &cfg,
            &[uncertain_at(130.0, 136.0), uncertain_at(110.0, 110.0)],
        );
        assert_eq!(
            pairs.iter().map(members).collect::<Vec<_>>(),
            [want(a, c), want(a, b)]
        );
        // End to end with k-means centres: a pair across one of the two bands.
        let report = s.run(&cfg).unwrap();
        let pair = report.pair().expect("pair");
        let got = members(&pair);
        assert!(got == want(a, b) || got == want(a, c), "{pair:?}");
    }

    #[test]
    fn no_pair_without_an_uncertain_centre_within_d_b() {
        let s = three_blobs();
        let cfg = Config::PAPER;
        // 3.4 cm beside the A–B segment: farther than d_b = 3 cm.
        let (_, pairs) = ranked(&s, &cfg, &[uncertain_at(130.0, 147.0)]);
        assert!(pairs.is_empty(), "{pairs:?}");
        // 2.6 cm beside it: within d_b.
        let (_, pairs) = ranked(&s, &cfg, &[uncertain_at(130.0, 143.0)]);
        assert_eq!(pairs.len(), 1, "{pairs:?}");
        assert!((pairs[0].uncertain_dist_m - 0.026).abs() < 1e-3);
        // And without any uncertain pixel there is nothing to do.
        let mut s = Scene::new();
        s.disc(140.0, 120.0, R_PX, 255)
            .disc(172.0, 120.0, R_PX, 255);
        let report = s.run(&cfg).unwrap();
        assert!(report.uncertain().is_empty() && report.push().is_none());
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

    /// A 2×2 pack as the heatmap draws it: a 12 cm square (60 px) with a 4 mm rim and
    /// uncertain bands 1 cm either side of the two cut lines through its middle, so four
    /// certain cells of about 4.6 cm.
    const PACK: (usize, usize, usize) = (130, 90, 60);

    fn pack_2x2() -> Scene {
        let (x0, y0, side) = PACK;
        let mut s = Scene::new();
        s.rect(x0, y0, x0 + side, y0 + side, 100) // rim (below l_l)
            .rect(x0 + 2, y0 + 2, x0 + side - 2, y0 + side - 2, 255)
            .rect(
                x0 + side / 2 - 5,
                y0 + 2,
                x0 + side / 2 + 6,
                y0 + side - 2,
                130,
            )
            .rect(
                x0 + 2,
                y0 + side / 2 - 5,
                x0 + side - 2,
                y0 + side / 2 + 6,
                130,
            );
        s
    }

    #[test]
    fn a_2x2_pack_is_sheared_across_a_cut_from_outside_the_pack() {
        let s = pack_2x2();
        let (x0, y0, side) = PACK;
        let inner = |p: [Real; 2]| {
            let (x, y) = (round(p[0]) as usize, round(p[1]) as usize);
            (x0 + 2..x0 + side - 2).contains(&x) && (y0 + 2..y0 + side - 2).contains(&y)
        };
        let mut vertical_push = [false; 2];
        for seed in 0..16 {
            let mut cfg = Config::PAPER;
            cfg.seed = seed;
            let report = s.run(&cfg).unwrap();
            let certain = report.certain();
            assert_eq!(certain.len(), 4, "seed {seed}: one cluster per cell");
            let pair = report.pair().expect("a pair across a cut");
            let (ci, cj) = (certain[pair.pushed], certain[pair.other]);
            // Adjacent cells (34 px apart), not diagonal ones (48 px).
            let (dx, dy) = (
                cj.centre_px[0] - ci.centre_px[0],
                cj.centre_px[1] - ci.centre_px[1],
            );
            assert!(
                (dx.abs() < 2.0 && (dy.abs() - 34.0).abs() < 2.0)
                    || (dy.abs() < 2.0 && (dx.abs() - 34.0).abs() < 2.0),
                "seed {seed}: {pair:?} {certain:?}"
            );
            let push = report.push().expect("push");
            assert_eq!(push.target_px, ci.centre_px);
            // Starts off the object and outside the pack's interior (never in a cut).
            assert!(s.heat_at(push.start_px) < cfg.uncertain_from, "seed {seed}");
            assert!(!inner(push.start_px), "seed {seed}: {push:?}");
            // A shear: perpendicular to the pair, into the pack.
            let pair_dir = (cj.centre_cam_m - ci.centre_cam_m).normalize();
            assert!(
                pair_dir.dot(&push.direction_cam).abs() < 0.05,
                "seed {seed}"
            );
            let inward = (ci.centre_cam_m - push.start_cam_m).normalize();
            assert!(inward.dot(&push.direction_cam) > 0.99);
            vertical_push[usize::from(push.direction_cam.y.abs() > 0.9)] = true;
        }
        assert!(
            vertical_push[0] && vertical_push[1],
            "both cut lines are used"
        );
    }

    #[test]
    fn the_other_cluster_is_pushed_when_the_pushed_one_is_enclosed() {
        // M (small) touches R (larger) across a band; above and below M, object pixels
        // lead to T and D (more than d_a from M): no walk from M reaches the table.
        let mut s = Scene::new();
        s.rect(140, 40, 161, 201, 130) // object column through M
            .disc(150.0, 60.0, 10.0, 255) // T
            .disc(150.0, 180.0, 10.0, 255) // D
            .disc(150.0, 120.0, 8.0, 255) // M
            .rect(158, 112, 171, 129, 130) // M–R band
            .disc(180.0, 120.0, 12.0, 255); // R
        let mut cfg = Config::PAPER;
        cfg.uncertain_max_m = 0.2; // any uncertain centre qualifies the pair
        for seed in 0..8 {
            cfg.seed = seed;
            let report = s.run(&cfg).unwrap();
            let certain = report.certain();
            let m = find(certain, 150.0, 120.0).expect("M");
            let r = find(certain, 180.0, 120.0).expect("R");
            let pair = report.pair().expect("pair");
            assert_eq!((pair.pushed, pair.other), (r, m), "seed {seed}");
            let push = report.push().expect("push");
            assert_eq!(push.target_px, certain[r].centre_px);
            assert!(s.heat_at(push.start_px) < cfg.uncertain_from);
            assert!(push.direction_cam.y.abs() > 0.99, "{push:?}");
        }
    }

    #[test]
    fn one_object_is_one_cluster_and_a_region_much_longer_than_an_object_is_split() {
        let cfg = Config::PAPER;
        // A 5 cm square: one cluster at its centre.
        let mut s = Scene::new();
        s.rect(100, 100, 125, 125, 255);
        let report = s.run(&cfg).unwrap();
        assert_eq!(report.certain().len(), 1, "{:?}", report.certain());
        let c = report.certain()[0];
        assert!((c.centre_px[0] - 112.0).abs() < 0.5 && (c.centre_px[1] - 112.0).abs() < 0.5);
        // A 20 cm × 5 cm bar (longer than region_max_len_m): round(20 / 6) = 3 pieces
        // along it, about 6.7 cm apart.
        let mut s = Scene::new();
        s.rect(100, 100, 200, 125, 255);
        let report = s.run(&cfg).unwrap();
        let mut xs: Vec<Real> = report.certain().iter().map(|c| c.centre_px[0]).collect();
        xs.sort_by(Real::total_cmp);
        assert_eq!(xs.len(), 3, "{:?}", report.certain());
        for (x, want) in xs.iter().zip([116.5, 149.5, 182.5]) {
            assert!((x - want).abs() < 3.0, "{xs:?}");
        }
        for c in report.certain() {
            assert!((c.centre_px[1] - 112.0).abs() < 1.0);
        }
    }

    #[test]
    fn fragments_below_the_minimum_area_are_not_clusters() {
        // A disc, and a 3×3 certain speck (0.36 cm²) across an uncertain band from it.
        let mut s = Scene::new();
        s.disc(120.0, 120.0, R_PX, 255)
            .rect(136, 110, 146, 131, 130)
            .rect(140, 119, 143, 122, 255);
        let cfg = Config::PAPER;
        let report = s.run(&cfg).unwrap();
        assert_eq!(report.certain().len(), 1, "{:?}", report.certain());
        assert_eq!(report.pair(), None);
        // Control: a lower minimum keeps the speck, and the two form a pair.
        let mut cfg = cfg;
        cfg.region_min_area_m2 = 0.2e-4;
        let report = s.run(&cfg).unwrap();
        assert_eq!(report.certain().len(), 2, "{:?}", report.certain());
        assert!(report.pair().is_some());
    }

    #[test]
    fn no_pair_across_the_table() {
        // Two discs 8 cm apart; an uncertain patch in the middle of the gap, with 8 px
        // (1.6 cm) of table between it and the discs.
        let mut s = Scene::new();
        s.disc(110.0, 120.0, 12.0, 255)
            .disc(150.0, 120.0, 12.0, 255)
            .rect(127, 112, 134, 129, 130);
        let cfg = Config::PAPER;
        let on_segment = [uncertain_at(130.0, 120.0)];
        let (certain, pairs) = ranked(&s, &cfg, &on_segment);
        assert_eq!(certain.len(), 2);
        assert!(pairs.is_empty(), "{pairs:?}");
        assert_eq!(s.run(&cfg).unwrap().pair(), None);
        // Control: with the gap filled, the pair qualifies.
        s.rect(122, 112, 139, 129, 130);
        let (_, pairs) = ranked(&s, &cfg, &on_segment);
        assert_eq!(pairs.len(), 1);
        assert!(s.run(&cfg).unwrap().push().is_some());
    }

    #[test]
    fn no_pair_through_a_third_object() {
        // A, M, B in a row, 4.8 cm apart, with bands between neighbours: A–B (9.6 cm,
        // within d_a) crosses M, so only A–M and M–B are pairs.
        let mut s = Scene::new();
        s.disc(100.0, 120.0, 9.0, 255)
            .disc(124.0, 120.0, 9.0, 255)
            .disc(148.0, 120.0, 9.0, 255)
            .rect(108, 112, 117, 129, 130)
            .rect(132, 112, 141, 129, 130);
        let cfg = Config::PAPER;
        let (certain, pairs) = ranked(&s, &cfg, &[uncertain_at(124.0, 120.0)]);
        let a = find(&certain, 100.0, 120.0).unwrap();
        let m = find(&certain, 124.0, 120.0).unwrap();
        let b = find(&certain, 148.0, 120.0).unwrap();
        let mut got: Vec<[usize; 2]> = pairs.iter().map(members).collect();
        got.sort_unstable();
        let mut want = vec![[a.min(m), a.max(m)], [m.min(b), m.max(b)]];
        want.sort_unstable();
        assert_eq!(got, want, "{pairs:?}");
    }

    #[test]
    fn a_one_pixel_diagonal_cut_separates_two_regions() {
        // A 6 cm square cut along its anti-diagonal by a one-pixel uncertain line; the
        // two halves touch diagonally across it (8-connected) but are two regions.
        let mut s = Scene::new();
        s.rect(100, 100, 130, 130, 255);
        for i in 0..30 {
            s.heat[(100 + i) * W + 129 - i] = 130;
        }
        let report = s.run(&Config::PAPER).unwrap();
        let certain = report.certain();
        assert_eq!(certain.len(), 2, "{certain:?}");
        let sides: Vec<bool> = certain
            .iter()
            .map(|c| c.centre_px[0] + c.centre_px[1] < 229.0)
            .collect();
        assert!(sides[0] != sides[1], "{certain:?}");
        let pair = report.pair().expect("the halves touch across the cut");
        assert!(report.push().is_some(), "{pair:?}");
    }

    #[test]
    fn runs_label_the_4_connected_certain_regions() {
        let mut rng = Pcg32::new(17);
        for trial in 0..40 {
            let (w, h) = (1 + rng.below(40) as usize, 1 + rng.below(30) as usize);
            let density = rng.below(100);
            let heat: Vec<u8> = (0..w * h)
                .map(|_| if rng.below(100) < density { 200 } else { 130 })
                .collect();
            let view = ImageView::packed(w, h, &heat).unwrap();
            let len = ActionScratchLen::for_config(&Config::PAPER, w, h);
            let mut buf = vec![0u32; len.runs];
            let mut row_runs = vec![0u32; len.row_runs];
            let mut runs = RunPlanes::split(&mut buf, len.max_runs).unwrap();
            let n = label_runs(&view, 150, &mut runs, &mut row_runs);
            assert!(n <= len.max_runs);
            let view_runs = Runs {
                x0: &runs.x0[..n],
                x1: &runs.x1[..n],
                aux: &runs.aux[..n],
            };
            // Reference: flood fill over 4-neighbours.
            let certain = |x: usize, y: usize| heat[y * w + x] >= 150;
            let mut comp = vec![usize::MAX; w * h];
            let mut next = 0;
            for start in 0..w * h {
                if !certain(start % w, start / w) || comp[start] != usize::MAX {
                    continue;
                }
                let mut stack = vec![start];
                comp[start] = next;
                while let Some(i) = stack.pop() {
                    let (x, y) = (i % w, i / w);
                    let around = [
                        (x > 0).then(|| i - 1),
                        (x + 1 < w).then(|| i + 1),
                        (y > 0).then(|| i - w),
                        (y + 1 < h).then(|| i + w),
                    ];
                    for j in around.into_iter().flatten() {
                        if certain(j % w, j / w) && comp[j] == usize::MAX {
                            comp[j] = next;
                            stack.push(j);
                        }
                    }
                }
                next += 1;
            }
            // Same partition: the root run of each certain pixel maps one-to-one to the
            // reference component.
            let mut root_of_comp = vec![usize::MAX; next];
            let mut comp_of_root = std::collections::BTreeMap::new();
            for y in 0..h {
                for x in 0..w {
                    let run = view_runs.at(&row_runs, x, y);
                    assert_eq!(run.is_some(), certain(x, y), "trial {trial} ({x}, {y})");
                    let Some(r) = run else { continue };
                    let root = find_root(runs.parent, r);
                    let c = comp[y * w + x];
                    if root_of_comp[c] == usize::MAX {
                        root_of_comp[c] = root;
                    }
                    assert_eq!(root_of_comp[c], root, "trial {trial}");
                    assert_eq!(*comp_of_root.entry(root).or_insert(c), c, "trial {trial}");
                }
            }
        }
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
            // Off the object (table), just outside the pushed disc.
            assert!(
                s.heat_at(push.start_px) < cfg.uncertain_from,
                "seed {seed}: {push:?}"
            );
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
        let mut runs = vec![0u32; len.runs];
        let mut row_runs = vec![0u32; len.row_runs];
        let hv = ImageView::packed(W, H, &heat).unwrap();
        let short_depth = ImageView::packed(W, H - 1, &depth).unwrap();
        let scratch = ActionScratch {
            certain: &mut c,
            uncertain: &mut u,
            dist2: &mut d,
            nearest: &mut n,
            row_counts: &mut r,
            runs: &mut runs,
            row_runs: &mut row_runs,
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
            runs: &mut runs,
            row_runs: &mut row_runs,
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
            runs: &mut runs,
            row_runs: &mut row_runs,
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
        assert_eq!(len.max_runs, 480 * 320);
        assert_eq!(len.runs, 4 * 480 * 320);
        assert_eq!(len.row_runs, 481);
        assert_eq!(
            len.bytes(),
            cfg.kmeans_samples * (12 + 12 + 4 + 4) + (960 + 4 * 480 * 320 + 481) * 4
        );
        assert_eq!(ActionScratchLen::for_config(&cfg, 7, 3).max_runs, 12);
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
