//! The table: a robust plane fit to the back-projected points and the convex hull of its
//! inliers, in which objects must stand.
//!
//! Contract of [`fit_table`]:
//! 1. Candidates are the pixels of a regular grid (about 20 000 of them) with a depth
//!    reading and a normal.
//! 2. RANSAC (seeded [`Pcg32`]): planes through three random candidates, scored by the
//!    inliers among a fixed random subset of 1 000 candidates. An inlier lies within
//!    [`SegmenterParams::plane_tolerance_m`] of the plane and its normal within
//!    `plane_normal_deg` of the plane's. The first plane with the most inliers is the
//!    best (a hypothesis's count stops once it cannot beat it, with the same result). The
//!    best plane is refitted by least squares (the smallest principal axis of the
//!    inliers' covariance), twice.
//! 3. The dominant plane may be the floor under a small table. So the search repeats
//!    among candidates more than `table_step_m` above the current plane, allowing only
//!    planes within 10° of parallel; a plane found there with at least `min_table_share`
//!    of all candidates becomes the table (the highest large support wins).
//! 4. The table's normal faces the camera: the camera is at height `offset_m > 0`.
//! 5. A bend, a quadratic height correction over the plane clamped to ±5 cm, is fitted by
//!    least squares to the table's points (within 2.5 tolerances of the plane, then twice
//!    within one tolerance of plane plus bend). Heights of objects are measured from plane
//!    plus bend: real tables warp and real depth is biased with distance.
//! 6. The convex hull, in plane coordinates, of the largest 4-connected region of inlier
//!    candidates on the grid bounds where objects may stand (a second table further away
//!    does not stretch it over the floor in between).

use nalgebra::{Matrix3, Point3, SymmetricEigen, Vector3};
use riseg_core::rng::Pcg32;

use super::{
    SegmentError, SegmenterParams,
    geometry::{P3, cross, dot},
};

/// Candidate grid target: enough points for a stable fit, few enough to be fast.
const TARGET_CANDIDATES: usize = 20_000;
/// Candidates each hypothesis is scored on.
const SCORE_SAMPLES: usize = 1_000;
/// A higher support plane must be within this angle of parallel to the dominant one.
const PARALLEL_DEG: f32 = 10.0;
/// Higher support planes tried after the dominant one.
const MAX_RAISES: usize = 3;

/// A plane `normal · p + offset_m = 0` in the camera frame, `normal` a unit vector facing
/// the camera, so [`TablePlane::height_m`] is positive above the table (towards the camera).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TablePlane {
    /// Unit normal, camera frame, pointing from the table towards the camera.
    pub normal: Vector3<f32>,
    /// Signed offset, metres: the camera's height above the plane.
    pub offset_m: f32,
}

impl TablePlane {
    /// Signed distance of `p` (camera frame, metres) above the plane, metres.
    #[must_use]
    pub fn height_m(&self, p: &Point3<f32>) -> f32 {
        self.normal.dot(&p.coords) + self.offset_m
    }

    pub(super) fn height_of(&self, p: P3) -> f32 {
        self.normal.x * p[0] + self.normal.y * p[1] + self.normal.z * p[2] + self.offset_m
    }

    fn normal_array(&self) -> P3 {
        [self.normal.x, self.normal.y, self.normal.z]
    }

    /// Through three points; `None` if they are (nearly) collinear.
    fn through(a: P3, b: P3, c: P3) -> Option<Self> {
        let n = cross(
            [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
            [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
        );
        let len = dot(n, n).sqrt();
        if len.is_nan() || len <= 1e-9 {
            return None;
        }
        Self::oriented([n[0] / len, n[1] / len, n[2] / len], a)
    }

    /// Normal `n` (unit) through `p`, turned to face the camera; `None` if the plane passes
    /// through the camera.
    fn oriented(n: P3, p: P3) -> Option<Self> {
        let d = -dot(n, p);
        if d.is_nan() || d.abs() <= 1e-6 {
            return None;
        }
        let s = d.signum();
        Some(Self {
            normal: Vector3::new(n[0] * s, n[1] * s, n[2] * s),
            offset_m: d * s,
        })
    }
}

/// Point-in-convex-polygon test with an inward margin, in plane coordinates.
#[derive(Debug, Clone, Default)]
pub(super) struct Hull {
    /// In-plane axes (unit, orthogonal to the plane normal).
    e1: P3,
    e2: P3,
    /// Edges as `(a, b, c)`: `a·u + b·v + c` is the distance inside the edge, metres.
    edges: Vec<[f32; 3]>,
    /// [`HULL_SLACK`] times the hull's extent, metres.
    slack_m: f32,
}

/// Slack of [`Hull::keep_inside`] per metre of the hull's extent: far above the rounding
/// of an edge test in `f32` (about 1e-7 per metre).
const HULL_SLACK: f32 = 1e-4;

impl Hull {
    /// The hull of the convex polygon `vertices` (plane coordinates, counter-clockwise)
    /// with the in-plane axes `e1`, `e2`.
    fn new(e1: P3, e2: P3, vertices: &[[f32; 2]]) -> Self {
        let edges = vertices
            .iter()
            .zip(vertices.iter().cycle().skip(1))
            .filter_map(|(a, b)| {
                let (tx, ty) = (b[0] - a[0], b[1] - a[1]);
                let len = (tx * tx + ty * ty).sqrt();
                (len > 1e-9).then(|| {
                    let (nx, ny) = (-ty / len, tx / len);
                    [nx, ny, -(nx * a[0] + ny * a[1])]
                })
            })
            .collect();
        let extent = vertices
            .iter()
            .map(|v| v[0].abs() + v[1].abs())
            .fold(1.0f32, f32::max);
        Self {
            e1,
            e2,
            edges,
            slack_m: HULL_SLACK * extent,
        }
    }

    /// Keeps the `candidates` (a row of points as x, y and z planes) whose footprint on
    /// the plane is at least `margin_m` inside the hull (every edge at least `margin_m`
    /// away), and clears the others.
    ///
    /// Neighbouring pixels have nearby footprints. A point found inside with every edge
    /// farther than `margin_m + slack + r` vouches for the later points within `r` of it:
    /// they pass every edge test too (the slack covers the rounding), so their edge tests
    /// are skipped with the same answer.
    pub(super) fn keep_inside(
        &self,
        [px, py, pz]: [&[f32]; 3],
        margin_m: f32,
        candidates: &mut [bool],
    ) {
        if self.edges.len() < 3 {
            candidates.fill(false);
            return;
        }
        let mut anchor: Option<(f32, f32, f32)> = None;
        for (x, keep) in candidates.iter_mut().enumerate() {
            if !*keep {
                continue;
            }
            let p = [px[x], py[x], pz[x]];
            let (u, v) = (dot(self.e1, p), dot(self.e2, p));
            if let Some((au, av, r)) = anchor {
                let (du, dv) = (u - au, v - av);
                if du * du + dv * dv <= r * r {
                    continue;
                }
            }
            let (inside, least) =
                self.edges
                    .iter()
                    .fold((true, f32::INFINITY), |(inside, least), e| {
                        let d = e[0] * u + e[1] * v + e[2];
                        (inside & (d >= margin_m), least.min(d))
                    });
            *keep = inside;
            let r = least - margin_m - self.slack_m;
            if inside && r > 0.0 {
                anchor = Some((u, v, r));
            }
        }
    }
}

/// Scratch of [`fit_table`], reused across frames.
#[derive(Debug, Default)]
pub(super) struct PlaneScratch {
    /// The candidates' points, normals and inlier tolerances, gathered once from the
    /// grid: every pass over them reads memory in order.
    cands: Samples,
    /// Each candidate's cell in the padded grid.
    cand_cell: Vec<u32>,
    /// The candidates a search for a higher plane may use.
    raised: Samples,
    /// Pixels of the candidates, then candidates of `raised`.
    idx: Vec<u32>,
    ransac: RansacScratch,
    /// The candidates relative to the found plane.
    coords: PlaneCoords,
    /// Which candidates a pass over [`PlaneCoords`] selects.
    selected: Vec<bool>,
    flat: Vec<[f32; 2]>,
    keys: Vec<u64>,
    /// The bend's samples: plane coordinates and height.
    bend_samples: Vec<[f64; 3]>,
    hull: Vec<[f32; 2]>,
    grid: Vec<u32>,
    queue: Vec<u32>,
}

/// Scratch of [`ransac`].
#[derive(Debug, Default)]
struct RansacScratch {
    /// The scoring samples, and their indices among the allowed candidates.
    samples: Samples,
    drawn: Vec<u32>,
    /// Which of the allowed candidates are inliers of the plane being refitted.
    inlier: Vec<bool>,
}

/// Points with their normals and inlier tolerances as planes (point x, y, z, normal x, y,
/// z, tolerance), so that the inlier tests of a plane vectorise.
#[derive(Debug, Default)]
struct Samples {
    p: [Vec<f32>; 3],
    n: [Vec<f32>; 3],
    tol_m: Vec<f32>,
}

impl Samples {
    fn len(&self) -> usize {
        self.tol_m.len()
    }

    /// Sizes the planes for `k` samples and returns them: points, normals, tolerances.
    fn resized(&mut self, k: usize) -> ([&mut [f32]; 3], [&mut [f32]; 3], &mut [f32]) {
        for v in self.p.iter_mut().chain(&mut self.n) {
            v.resize(k, 0.0);
        }
        self.tol_m.resize(k, 0.0);
        let [px, py, pz] = &mut self.p;
        let [nx, ny, nz] = &mut self.n;
        (
            [&mut px[..k], &mut py[..k], &mut pz[..k]],
            [&mut nx[..k], &mut ny[..k], &mut nz[..k]],
            &mut self.tol_m[..k],
        )
    }

    /// The points `pts[i]`, normals `nrm[i]` and tolerances `tol_m(pts[i][2])` of the
    /// indices `i` of `idx`, in order.
    fn gather(&mut self, idx: &[u32], pts: &[P3], nrm: &[P3], tol_m: impl Fn(f32) -> f32) {
        let ([px, py, pz], [nx, ny, nz], tol) = self.resized(idx.len());
        for (j, &i) in idx.iter().enumerate() {
            let (p, n) = (pts[i as usize], nrm[i as usize]);
            [px[j], py[j], pz[j]] = p;
            [nx[j], ny[j], nz[j]] = n;
            tol[j] = tol_m(p[2]);
        }
    }

    /// Samples `j` of `other` for the indices `j` of `idx`, in order.
    fn gather_from(&mut self, other: &Self, idx: &[u32]) {
        let ([px, py, pz], [nx, ny, nz], tol) = self.resized(idx.len());
        for (j, &i) in idx.iter().enumerate() {
            let i = i as usize;
            [px[j], py[j], pz[j]] = other.point(i);
            [nx[j], ny[j], nz[j]] = other.n.each_ref().map(|v| v[i]);
            tol[j] = other.tol_m[i];
        }
    }

    /// How many of the points pass `test`.
    fn count(&self, test: impl Fn(P3) -> bool) -> usize {
        let k = self.len();
        let [px, py, pz] = self.p.each_ref().map(|v| &v[..k]);
        (0..k)
            .map(|j| usize::from(test([px[j], py[j], pz[j]])))
            .sum()
    }

    fn point(&self, j: usize) -> P3 {
        self.p.each_ref().map(|v| v[j])
    }

    /// The inlier tests of `plane` for the samples `range`, one per sample into `f(j, is)`:
    /// an inlier lies within its tolerance of the plane, its normal within
    /// `acos(cos_normal)` of the plane's.
    #[inline(always)]
    fn inlier_tests(
        &self,
        plane: &TablePlane,
        cos_normal: f32,
        range: core::ops::Range<usize>,
        mut f: impl FnMut(usize, bool),
    ) {
        let [a, b, c] = plane.normal_array();
        let [px, py, pz] = self.p.each_ref().map(|v| &v[range.clone()]);
        let [nx, ny, nz] = self.n.each_ref().map(|v| &v[range.clone()]);
        let tol_m = &self.tol_m[range.clone()];
        let k = tol_m.len();
        let (px, py, pz, nx, ny, nz) = (&px[..k], &py[..k], &pz[..k], &nx[..k], &ny[..k], &nz[..k]);
        for j in 0..k {
            let height = plane.height_of([px[j], py[j], pz[j]]);
            let facing = a * nx[j] + b * ny[j] + c * nz[j];
            f(j, (height.abs() <= tol_m[j]) & (facing >= cos_normal));
        }
    }

    /// How many samples are inliers of `plane` ([`Self::inlier_tests`]), if more than
    /// `beat`: `None` as soon as the samples left cannot lift the count above it (the
    /// count goes by blocks of [`INLIER_BLOCK`] samples).
    fn inliers_over(
        &self,
        plane: &TablePlane,
        cos_normal: f32,
        beat: Option<usize>,
    ) -> Option<usize> {
        let total = self.len();
        let mut count = 0;
        for start in (0..total).step_by(INLIER_BLOCK) {
            if beat.is_some_and(|b| count + (total - start) <= b) {
                return None;
            }
            let mut block = 0u32;
            let end = (start + INLIER_BLOCK).min(total);
            self.inlier_tests(plane, cos_normal, start..end, |_, is| {
                block += u32::from(is);
            });
            count += block as usize;
        }
        beat.is_none_or(|b| count > b).then_some(count)
    }

    /// The inliers of `plane` into `out`, one flag per sample.
    fn mark_inliers(&self, plane: &TablePlane, cos_normal: f32, out: &mut Vec<bool>) {
        out.clear();
        out.resize(self.len(), false);
        let out = &mut out[..];
        self.inlier_tests(plane, cos_normal, 0..out.len(), |j, is| out[j] = is);
    }
}

/// Samples per block of [`Samples::inliers_over`].
const INLIER_BLOCK: usize = 128;

/// The fitted table: plane, bend and the hull objects must stand in.
#[derive(Debug, Clone)]
pub(super) struct TableFit {
    pub(super) plane: TablePlane,
    bend: Bend,
    pub(super) hull: Hull,
}

impl TableFit {
    /// Height of `p` above the table surface (plane plus bend), metres.
    pub(super) fn height_of(&self, p: P3) -> f32 {
        self.plane.height_of(p) - self.bend.at(p)
    }
}

/// The candidate grid's spacing, pixels: the grid's cells are the pixels
/// `(step/2 + gx·step, step/2 + gy·step)`.
fn grid_step(w: usize, h: usize) -> usize {
    ((w * h / TARGET_CANDIDATES) as f64).sqrt().floor().max(1.0) as usize
}

/// `true` for the rows of a `w × h` frame that hold candidate grid cells: the only rows
/// whose points and normals [`fit_table`] reads.
pub(super) fn is_grid_row(w: usize, h: usize, y: usize) -> bool {
    let step = grid_step(w, h);
    y >= step / 2 && (y - step / 2).is_multiple_of(step)
}

/// Fits the table (see the module docs).
///
/// # Errors
/// [`SegmentError::NoTablePlane`] if no plane holds `min_table_share` of the candidates.
#[inline(never)] // called once a frame; kept apart so that profiles show it
pub(super) fn fit_table(
    w: usize,
    h: usize,
    pts: &[P3],
    nrm: &[P3],
    params: &SegmenterParams,
    s: &mut PlaneScratch,
) -> Result<TableFit, SegmentError> {
    let step = grid_step(w, h);
    let (gw, gh) = (
        w.saturating_sub(step / 2).div_ceil(step),
        h.saturating_sub(step / 2).div_ceil(step),
    );
    // Each grid cell's index in the grid padded by one cell on every side, and its pixel,
    // in cell order (row by row, without a division).
    let gwp = gw + 2;
    let grid_pixels = || {
        (0..gh).flat_map(move |gy| {
            (0..gw).map(move |gx| {
                let pixel = (step / 2 + gy * step) * w + step / 2 + gx * step;
                ((gy + 1) * gwp + gx + 1, pixel)
            })
        })
    };
    s.cand_cell.clear();
    s.idx.clear();
    for (cell, i) in grid_pixels() {
        if pts[i][2] > 0.0 && nrm[i] != [0.0; 3] {
            s.cand_cell.push(cell as u32);
            s.idx.push(i as u32);
        }
    }
    s.cands
        .gather(&s.idx, pts, nrm, |z| params.plane_tolerance_m(z));
    let cands = &s.cands;
    let candidates = cands.len();
    let needed = ((params.min_table_share * candidates as f32).ceil() as usize).max(3);
    let cos_normal = libm::cosf(params.plane_normal_deg.to_radians());
    let mut rng = Pcg32::new(params.seed);

    let rs = &mut s.ransac;
    let (mut plane, inliers) = ransac(cands, None, params, &mut rng, rs);
    if inliers < needed {
        return Err(SegmentError::NoTablePlane {
            inliers,
            candidates,
            needed,
        });
    }
    for _ in 0..MAX_RAISES {
        let base = plane;
        let raised = |p| base.height_of(p) > params.table_step_m;
        if cands.count(raised) < needed {
            break;
        }
        s.idx.clear();
        s.idx
            .extend((0..candidates as u32).filter(|&j| raised(cands.point(j as usize))));
        s.raised.gather_from(cands, &s.idx);
        let (higher, n) = ransac(&s.raised, Some(&base), params, &mut rng, rs);
        if n < needed {
            break;
        }
        plane = higher;
    }

    // In-plane axes, the candidates in plane coordinates, the bend, then the hull of the
    // largest connected inlier region.
    let n = plane.normal_array();
    let seed_axis = if n[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let e1 = normalise(cross(n, seed_axis));
    let e2 = cross(n, e1);
    let coords = &mut s.coords;
    coords.fill(cands, &plane, [e1, e2], cos_normal);
    let mut table = TableFit {
        plane,
        bend: Bend::flat(e1, e2),
        hull: Hull::new(e1, e2, &[]),
    };
    for widen in [2.5, 1.0, 1.0] {
        coords.select(&cands.tol_m, &table.bend, widen, &mut s.selected);
        coords.selected(&s.selected, &mut s.bend_samples);
        let Some(bend) = Bend::fit(e1, e2, &s.bend_samples) else {
            break;
        };
        table.bend = bend;
    }

    // Only candidates can be table cells (a cell without a normal fails the normal test),
    // and they are in cell order: both passes read the compact candidates.
    coords.select(&cands.tol_m, &table.bend, 1.0, &mut s.selected);
    s.grid.clear();
    s.grid.resize(gwp * (gh + 2), 0);
    for (&on, &cell) in s.selected.iter().zip(&s.cand_cell) {
        if on {
            s.grid[cell as usize] = 1;
        }
    }
    let largest = largest_component(gwp, &mut s.grid, &mut s.queue);
    s.flat.clear();
    for ((&u, &v), &cell) in coords.u_m.iter().zip(&coords.v_m).zip(&s.cand_cell) {
        if s.grid[cell as usize] == largest {
            s.flat.push([u, v]);
        }
    }
    convex_hull(&mut s.flat, &mut s.keys, &mut s.hull);
    table.hull = Hull::new(e1, e2, &s.hull);
    Ok(table)
}

/// The candidates relative to the table plane, computed once for the passes of the bend
/// and the hull: in-plane coordinates `u_m = e1 · p`, `v_m = e2 · p`, height over the
/// plane (metres), and whether the normal is within `plane_normal_deg` of the plane's.
#[derive(Debug, Default)]
struct PlaneCoords {
    u_m: Vec<f32>,
    v_m: Vec<f32>,
    height_m: Vec<f32>,
    facing: Vec<bool>,
}

impl PlaneCoords {
    fn fill(&mut self, cands: &Samples, plane: &TablePlane, [e1, e2]: [P3; 2], cos_normal: f32) {
        let k = cands.len();
        let n = plane.normal_array();
        self.u_m.resize(k, 0.0);
        self.v_m.resize(k, 0.0);
        self.height_m.resize(k, 0.0);
        self.facing.resize(k, false);
        let (u, v) = (&mut self.u_m[..k], &mut self.v_m[..k]);
        let (height_m, facing) = (&mut self.height_m[..k], &mut self.facing[..k]);
        let [px, py, pz] = cands.p.each_ref().map(|v| &v[..k]);
        let [nx, ny, nz] = cands.n.each_ref().map(|v| &v[..k]);
        for j in 0..k {
            let p = [px[j], py[j], pz[j]];
            u[j] = dot(e1, p);
            v[j] = dot(e2, p);
            height_m[j] = plane.height_of(p);
            facing[j] = dot(n, [nx[j], ny[j], nz[j]]) >= cos_normal;
        }
    }

    /// Marks in `out` the candidates within `widen` times their tolerances `tol_m` of
    /// plane plus `bend` whose normal faces the plane's.
    fn select(&self, tol_m: &[f32], bend: &Bend, widen: f32, out: &mut Vec<bool>) {
        let k = self.u_m.len();
        out.clear();
        out.resize(k, false);
        let (u, v, height_m) = (&self.u_m[..k], &self.v_m[..k], &self.height_m[..k]);
        let (tol_m, facing, out) = (&tol_m[..k], &self.facing[..k], &mut out[..k]);
        for j in 0..k {
            let off = height_m[j] - bend.at_uv(u[j], v[j]);
            out[j] = (off.abs() <= widen * tol_m[j]) & facing[j];
        }
    }

    /// `(u, v, height)` of the candidates marked in `selected`, in order, into `out`.
    fn selected(&self, selected: &[bool], out: &mut Vec<[f64; 3]>) {
        let k = selected.len();
        // Every candidate is written at the next free place, which moves on past the
        // selected ones only.
        out.clear();
        out.resize(k, [0.0; 3]);
        let (u, v, height_m) = (&self.u_m[..k], &self.v_m[..k], &self.height_m[..k]);
        let mut next = 0;
        for (j, &on) in selected.iter().enumerate() {
            if let Some(o) = out.get_mut(next) {
                *o = [u[j], v[j], height_m[j]].map(f64::from);
            }
            next += usize::from(on);
        }
        out.truncate(next);
    }
}

/// Labels the 4-connected components of the cells marked `1` in `grid` (rows of `gwp`
/// cells, the first and last row and column unmarked) with ids from 2 on, in the order of
/// their first cells, and returns the id of the largest (the first of equals; 0 if there
/// is none).
fn largest_component(gwp: usize, grid: &mut [u32], queue: &mut Vec<u32>) -> u32 {
    let (mut best, mut best_size, mut next) = (0, 0, 2);
    for start in 0..grid.len() {
        if grid[start] != 1 {
            continue;
        }
        queue.clear();
        queue.push(start as u32);
        grid[start] = next;
        let mut head = 0;
        while let Some(&g) = queue.get(head) {
            head += 1;
            // A marked cell is inside the unmarked border: its neighbours exist.
            let g = g as usize;
            for nb in [g - 1, g + 1, g - gwp, g + gwp] {
                if grid[nb] == 1 {
                    grid[nb] = next;
                    queue.push(nb as u32);
                }
            }
        }
        if queue.len() > best_size {
            (best, best_size) = (next, queue.len());
        }
        next += 1;
    }
    best
}

/// A smooth correction of the table's height over the plane: a quadratic in the in-plane
/// coordinates, least-squares fitted to the table's inliers and clamped to
/// `±MAX_BEND_M`. It absorbs a slightly warped table and the depth bias of real cameras,
/// which grows with distance (a far table end read a few centimetres high).
#[derive(Debug, Clone)]
pub(super) struct Bend {
    e1: P3,
    e2: P3,
    /// Centre of the fitted points in plane coordinates, metres.
    centre: [f32; 2],
    /// `c0 + c1 u + c2 v + c3 u² + c4 u v + c5 v²` (u, v relative to `centre`).
    coef: [f32; 6],
}

/// Largest correction the bend may apply, metres.
const MAX_BEND_M: f32 = 0.05;

impl Bend {
    fn flat(e1: P3, e2: P3) -> Self {
        Self {
            e1,
            e2,
            centre: [0.0; 2],
            coef: [0.0; 6],
        }
    }

    fn terms(u: f64, v: f64) -> [f64; 6] {
        [1.0, u, v, u * u, u * v, v * v]
    }

    /// Fits the plane heights `h` of the table's points `samples` (`[u, v, h]`, plane
    /// coordinates); `None` if there are too few or they do not determine a quadratic.
    fn fit(e1: P3, e2: P3, samples: &[[f64; 3]]) -> Option<Self> {
        if samples.len() < 12 {
            return None;
        }
        // The centre's sums in the order and from the `-0.0` that `Iterator::sum` uses.
        let (mut sum_u, mut sum_v) = (-0.0f64, -0.0f64);
        for &[u, v, _] in samples {
            sum_u += u;
            sum_v += v;
        }
        let k = samples.len() as f64;
        let (cu, cv) = (sum_u / k, sum_v / k);
        // The normal equations `Σ t tᵀ c = Σ t h` over the terms `t`. Each entry of the
        // symmetric `Σ t tᵀ` is one sum of products in sample order; `t₀ = 1`, so row 0
        // holds `k` and the sums of the terms, which are also the entries `(1, 1)`,
        // `(1, 2)` and `(2, 2)` (the same products). The other sums take two passes, so
        // that each pass's sums stay in registers.
        let mut low = [0.0f64; 11];
        for &[u, v, h] in samples.iter() {
            let [_, u, v, uu, uv, vv] = Self::terms(u - cu, v - cv);
            let add = [u, v, uu, uv, vv, h, u * h, v * h, uu * h, uv * h, vv * h];
            for (s, a) in low.iter_mut().zip(add) {
                *s += a;
            }
        }
        let mut high = [0.0f64; 12];
        for &[u, v, _] in samples.iter() {
            let [_, u, v, uu, uv, vv] = Self::terms(u - cu, v - cv);
            let add = [
                u * uu,
                u * uv,
                u * vv,
                v * uu,
                v * uv,
                v * vv,
                uu * uu,
                uu * uv,
                uu * vv,
                uv * uv,
                uv * vv,
                vv * vv,
            ];
            for (s, a) in high.iter_mut().zip(add) {
                *s += a;
            }
        }
        let [su, sv, suu, suv, svv, sh, suh, svh, suuh, suvh, svvh] = low;
        let [h13, h14, h15, h23, h24, h25, h33, h34, h35, h44, h45, h55] = high;
        let upper = [
            [k, su, sv, suu, suv, svv],
            [0.0, suu, suv, h13, h14, h15],
            [0.0, 0.0, svv, h23, h24, h25],
            [0.0, 0.0, 0.0, h33, h34, h35],
            [0.0, 0.0, 0.0, 0.0, h44, h45],
            [0.0, 0.0, 0.0, 0.0, 0.0, h55],
        ];
        let ata = nalgebra::Matrix6::from_fn(|a, b| upper[a.min(b)][a.max(b)]);
        let atb = nalgebra::Vector6::from([sh, suh, svh, suuh, suvh, svvh]);
        let c = ata.cholesky()?.solve(&atb);
        let coef = [c[0], c[1], c[2], c[3], c[4], c[5]].map(|v| v as f32);
        coef.iter().all(|v| v.is_finite()).then_some(Self {
            e1,
            e2,
            centre: [cu as f32, cv as f32],
            coef,
        })
    }

    /// The table's height over the plane under `p`, metres.
    fn at(&self, p: P3) -> f32 {
        self.at_uv(dot(self.e1, p), dot(self.e2, p))
    }

    /// [`Self::at`] at the plane coordinates `u = e1 · p`, `v = e2 · p`.
    fn at_uv(&self, u: f32, v: f32) -> f32 {
        let (u, v) = (u - self.centre[0], v - self.centre[1]);
        let c = &self.coef;
        (c[0] + c[1] * u + c[2] * v + c[3] * u * u + c[4] * u * v + c[5] * v * v)
            .clamp(-MAX_BEND_M, MAX_BEND_M)
    }
}

fn normalise(v: P3) -> P3 {
    let len = dot(v, v).sqrt();
    [v[0] / len, v[1] / len, v[2] / len]
}

/// Best plane among the candidates `allowed` (optionally near-parallel to
/// `parallel_to`), refitted; returns it and its inlier count among `allowed`.
fn ransac(
    allowed: &Samples,
    parallel_to: Option<&TablePlane>,
    params: &SegmenterParams,
    rng: &mut Pcg32,
    s: &mut RansacScratch,
) -> (TablePlane, usize) {
    let cos_normal = libm::cosf(params.plane_normal_deg.to_radians());
    let cos_parallel = libm::cosf(PARALLEL_DEG.to_radians());
    let fallback = TablePlane {
        normal: Vector3::new(0.0, 0.0, -1.0),
        offset_m: 1.0,
    };
    let m = allowed.len();
    if m < 3 {
        return (fallback, 0);
    }
    let bound = m as u32;
    s.drawn.clear();
    s.drawn
        .extend((0..SCORE_SAMPLES.min(m)).map(|_| rng.below(bound)));
    s.samples.gather_from(allowed, &s.drawn);
    // A hypothesis replaces the best only with more inliers, so its count stops as soon
    // as it cannot: the same best plane as full counts.
    let mut best: Option<(TablePlane, usize)> = None;
    for _ in 0..params.ransac_iterations {
        let pick = |rng: &mut Pcg32| allowed.point(rng.below(bound) as usize);
        let (a, b, c) = (pick(rng), pick(rng), pick(rng));
        let Some(plane) = TablePlane::through(a, b, c) else {
            continue;
        };
        if let Some(base) = parallel_to
            && plane.normal.dot(&base.normal) < cos_parallel
        {
            continue;
        }
        if let Some(count) = s
            .samples
            .inliers_over(&plane, cos_normal, best.map(|(_, n)| n))
        {
            best = Some((plane, count));
        }
    }
    let Some((mut plane, _)) = best else {
        return (fallback, 0);
    };
    for _ in 0..2 {
        allowed.mark_inliers(&plane, cos_normal, &mut s.inlier);
        let Some(refit) = refit(allowed, &s.inlier, &plane) else {
            break;
        };
        plane = refit;
    }
    let count = allowed
        .inliers_over(&plane, cos_normal, None)
        .unwrap_or_default();
    (plane, count)
}

/// Least-squares plane through the points of `pts` marked in `inlier` (the inliers of
/// `plane`).
fn refit(pts: &Samples, inlier: &[bool], plane: &TablePlane) -> Option<TablePlane> {
    // Count, sums and the upper triangle of the sums of `p pᵀ`, each in point order (the
    // lower triangle's products are the same, `x * y == y * x`, so the mirrored triangle
    // is the full sum).
    let mut n = 0.0f64;
    let mut sum = [0.0f64; 3];
    let mut sq = [0.0f64; 6];
    let [px, py, pz] = pts.p.each_ref().map(|v| &v[..inlier.len()]);
    for (j, _) in inlier.iter().enumerate().filter(|(_, on)| **on) {
        let [x, y, z] = [px[j], py[j], pz[j]].map(f64::from);
        n += 1.0;
        for (s, a) in sum.iter_mut().zip([x, y, z]) {
            *s += a;
        }
        for (s, a) in sq
            .iter_mut()
            .zip([x * x, x * y, x * z, y * y, y * z, z * z])
        {
            *s += a;
        }
    }
    if n < 3.0 {
        return None;
    }
    let sum = Vector3::from(sum);
    let [xx, xy, xz, yy, yz, zz] = sq;
    let sq = Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz);
    let mean = sum / n;
    let cov = sq / n - mean * mean.transpose();
    let eig = SymmetricEigen::new(cov);
    let k = eig.eigenvalues.imin();
    let e = eig.eigenvectors.column(k);
    let normal = [e[0] as f32, e[1] as f32, e[2] as f32];
    if !normal.iter().all(|v| v.is_finite()) {
        return None;
    }
    let mut fit = TablePlane::oriented(
        normalise(normal),
        [mean.x as f32, mean.y as f32, mean.z as f32],
    )?;
    // Keep the refit on the same side as the hypothesis (it is the same surface).
    if fit.normal.dot(&plane.normal) < 0.0 {
        fit.normal = -fit.normal;
        fit.offset_m = -fit.offset_m;
    }
    Some(fit)
}

/// The bits of `v` as an unsigned integer in [`f32::total_cmp`]'s order (a bijection).
fn total_order_key(v: f32) -> u32 {
    let bits = v.to_bits();
    // Negative values: flip all but the sign bit (as `total_cmp` does), then the sign bit
    // makes signed order unsigned.
    bits ^ ((((bits as i32) >> 31) as u32) >> 1) ^ 0x8000_0000
}

/// The inverse of [`total_order_key`].
fn from_total_order_key(key: u32) -> f32 {
    let bits = key ^ 0x8000_0000;
    f32::from_bits(bits ^ ((((bits as i32) >> 31) as u32) >> 1))
}

/// Sorts `pts` by `x`, then `y`, each in [`f32::total_cmp`]'s order, through one `u64` key
/// per point (`keys` is scratch): points with equal keys are equal bit for bit, so the
/// result is the one a comparison sort gives, at the cost of a sort of integers.
fn sort_points(pts: &mut [[f32; 2]], keys: &mut Vec<u64>) {
    keys.clear();
    keys.extend(
        pts.iter()
            .map(|p| u64::from(total_order_key(p[0])) << 32 | u64::from(total_order_key(p[1]))),
    );
    keys.sort_unstable();
    for (p, &k) in pts.iter_mut().zip(keys.iter()) {
        *p = [
            from_total_order_key((k >> 32) as u32),
            from_total_order_key(k as u32),
        ];
    }
}

/// Andrew's monotone chain: the convex hull of `pts` counter-clockwise into `out`
/// (`pts` is sorted in place, `keys` is scratch).
fn convex_hull(pts: &mut [[f32; 2]], keys: &mut Vec<u64>, out: &mut Vec<[f32; 2]>) {
    out.clear();
    sort_points(pts, keys);
    if pts.len() < 3 {
        out.extend_from_slice(pts);
        return;
    }
    let turn = |o: [f32; 2], a: [f32; 2], b: [f32; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    for &p in pts.iter() {
        while out.len() >= 2 && turn(out[out.len() - 2], out[out.len() - 1], p) <= 0.0 {
            out.pop();
        }
        out.push(p);
    }
    let lower = out.len() + 1;
    for &p in pts.iter().rev().skip(1) {
        while out.len() >= lower && turn(out[out.len() - 2], out[out.len() - 1], p) <= 0.0 {
            out.pop();
        }
        out.push(p);
    }
    out.pop();
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hull_of_a_square_with_interior_points_is_the_square_ccw() {
        let mut pts = vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [0.5, 0.5],
            [1.0, 1.0],
            [0.0, 1.0],
            [0.2, 0.7],
        ];
        let mut hull = Vec::new();
        convex_hull(&mut pts, &mut Vec::new(), &mut hull);
        assert_eq!(hull, vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    }

    #[test]
    fn points_sort_in_total_cmp_order() {
        let values = [
            f32::NEG_INFINITY,
            -2.5,
            -1e-30,
            -0.0,
            0.0,
            1e-30,
            0.25,
            7.0,
            f32::INFINITY,
            f32::NAN,
            -f32::NAN,
        ];
        for &v in &values {
            assert_eq!(
                from_total_order_key(total_order_key(v)).to_bits(),
                v.to_bits()
            );
        }
        let mut pts: Vec<[f32; 2]> = values
            .iter()
            .flat_map(|&a| values.iter().map(move |&b| [a, b]))
            .rev()
            .collect();
        let mut expected = pts.clone();
        expected.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
        sort_points(&mut pts, &mut Vec::new());
        let bits =
            |v: &[[f32; 2]]| -> Vec<[u32; 2]> { v.iter().map(|p| p.map(f32::to_bits)).collect() };
        assert_eq!(bits(&pts), bits(&expected));
    }

    #[test]
    fn an_early_stopped_inlier_count_says_only_whether_it_beats() {
        // 1 000 samples: 500 off the plane z = 1 (or facing away), then 500 on it.
        let plane = TablePlane::through([0.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 0.0, 1.0]).unwrap();
        let mut idx = Vec::new();
        let (mut pts, mut nrm) = (Vec::new(), Vec::new());
        for j in 0..1000u32 {
            let x = j as f32 * 1e-3;
            let (z, n) = match j {
                0..250 => (1.2, [0.0, 0.0, -1.0]),
                250..500 => (1.0, [1.0, 0.0, 0.0]),
                _ => (1.0 + 1e-4, [0.0, 0.0, -1.0]),
            };
            idx.push(j);
            pts.push([x, -x, z]);
            nrm.push(n);
        }
        let mut samples = Samples::default();
        samples.gather(&idx, &pts, &nrm, |_| 0.01);
        let cos_normal = 0.9;
        assert_eq!(samples.inliers_over(&plane, cos_normal, None), Some(500));
        for beat in 0..1000 {
            let want = (500 > beat).then_some(500);
            assert_eq!(
                samples.inliers_over(&plane, cos_normal, Some(beat)),
                want,
                "{beat}"
            );
        }
        let mut marks = Vec::new();
        samples.mark_inliers(&plane, cos_normal, &mut marks);
        assert!(marks.iter().enumerate().all(|(j, &m)| m == (j >= 500)));
    }

    #[test]
    fn plane_through_points_faces_the_camera() {
        let p = TablePlane::through([0.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 0.0, 1.0]).unwrap();
        assert!((p.normal.z + 1.0).abs() < 1e-6 && (p.offset_m - 1.0).abs() < 1e-6);
        assert!(p.height_m(&Point3::new(0.0, 0.0, 0.9)) > 0.0);
        assert!(TablePlane::through([0.0; 3], [1.0, 0.0, 1.0], [2.0, 0.0, 2.0]).is_none());
    }
}
