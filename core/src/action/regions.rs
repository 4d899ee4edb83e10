//! Steps 3-4 of FindAction: certain regions (runs of certain pixels joined by union-find)
//! and the certain clusters they give, long regions split into pieces.

use heapless::Vec as FixedVec;
use nalgebra::{Matrix3, Point3, Vector3, linalg::SymmetricEigen};

use super::*;
use crate::{
    Config, Intrinsics, MAX_CLUSTERS,
    image::ImageView,
    math::{Real, round, sqrt},
    union_find::{find, union},
};

/// Most pieces one oversized certain region is split into.
const MAX_PIECES: usize = 6;
/// Most pieces along a region's long axis.
const MAX_PIECES_LONG: usize = 5;
/// Most pieces along a region's short axis.
const MAX_PIECES_SHORT: usize = 2;
/// Most iterations of the eigen-solver for a region's 3-D covariance.
const EIGEN_ITERS: usize = 64;

/// "No region" in the run planes and in [`ActionScratch::nearest`].
pub(super) const NONE: u32 = u32::MAX;

/// Runs of certain pixels as four planes of equal length (module docs, step 3).
pub(super) struct RunPlanes<'a> {
    /// First pixel of the run.
    pub(super) x0: &'a mut [u32],
    /// One past the last pixel of the run.
    pub(super) x1: &'a mut [u32],
    /// Union-find parent; after [`certain_clusters`] the root run of the run's region.
    pub(super) parent: &'a mut [u32],
    /// Pixel count while labelling; then the index of the run's candidate region, or
    /// [`NONE`].
    pub(super) aux: &'a mut [u32],
}

impl<'a> RunPlanes<'a> {
    /// Splits `buf` into four planes of `r` entries; `None` if it is shorter than `4·r`.
    pub(super) fn split(buf: &'a mut [u32], r: usize) -> Option<Self> {
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

    pub(super) fn view(&self, n: usize) -> Runs<'_> {
        Runs {
            x0: self.x0.get(..n).unwrap_or(&[]),
            x1: self.x1.get(..n).unwrap_or(&[]),
            aux: self.aux.get(..n).unwrap_or(&[]),
        }
    }
}

/// Read-only view of the labelled runs.
#[derive(Clone, Copy)]
pub(super) struct Runs<'a> {
    pub(super) x0: &'a [u32],
    pub(super) x1: &'a [u32],
    pub(super) aux: &'a [u32],
}

impl Runs<'_> {
    /// The run holding pixel `(x, y)`, if that pixel is certain.
    pub(super) fn at(&self, row_runs: &[u32], x: usize, y: usize) -> Option<usize> {
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
    pub(super) fn region_at(&self, row_runs: &[u32], x: usize, y: usize) -> u32 {
        self.at(row_runs, x, y)
            .and_then(|r| self.aux.get(r).copied())
            .unwrap_or(NONE)
    }
}

/// Labels the 4-connected regions of certain pixels (`heat >= certain_from`; depth is not
/// consulted) as runs with union-find; returns the number of runs. Rows without a certain
/// pixel are skipped after a vectorised maximum.
pub(super) fn label_runs(
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
    pub(super) pixels: u32,
    pub(super) samples: u32,
    /// First sample's pixel; pixel sums are taken relative to it (precision).
    pub(super) px_ref: [Real; 2],
    /// Sum of `(x, y) − px_ref`.
    pub(super) s_px: [Real; 2],
    /// Sums of `dx²`, `dx·dy`, `dy²` relative to `px_ref`.
    pub(super) s_pxx: [Real; 3],
    /// First sample's back-projected point; 3-D sums are relative to it.
    pub(super) p_ref: Vector3<Real>,
    /// Sum of `p − p_ref`.
    pub(super) s_p: Vector3<Real>,
    /// Sum of `(p − p_ref)(p − p_ref)ᵀ`.
    pub(super) s_pp: Matrix3<Real>,
}

impl RegionSums {
    pub(super) const fn new(pixels: u32) -> Self {
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
pub(super) struct CertainClusters {
    pub(super) clusters: FixedVec<Cluster, MAX_CLUSTERS>,
    pub(super) region_of: FixedVec<u32, MAX_CLUSTERS>,
}

/// Certain clusters from the labelled runs and the certain samples (module docs,
/// steps 3-4). Leaves each run's candidate region (or [`NONE`]) in `runs.aux` and each
/// run's root in `runs.parent`; uses `nearest` for the samples' regions.
pub(super) fn certain_clusters(
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
        let root = find(runs.parent, r);
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
