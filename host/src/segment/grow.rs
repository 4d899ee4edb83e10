//! Region growing over the object pixels, small-segment cleanup and hole filling.
//!
//! Contract of [`grow_segments`] (all buffers row-major, `width·height`):
//! 1. Two 4-neighbouring object pixels `p`, `q` join when neither is on a blocking crease,
//!    `q` lies within [`SegmenterParams::depth_jump_at_m`] of `p`'s tangent plane (of `p`'s
//!    depth where `p` has no normal) and their depths differ by at most three times that,
//!    and their normals (where both exist) are within `grow_normal_deg`. Joining is
//!    union-find, so the result does not depend on a visiting order. Two grown object
//!    pixels that do not join are flagged in `step` (a depth step or sharp bend: if they
//!    end up in one segment anyway, the segment is unsure there), unless the bend between
//!    them is convex (each point behind the other's tangent plane): that is an object's
//!    own edge, not a place where two objects meet.
//! 2. Pixels on a blocking crease take the segment of the nearest grown pixel (a
//!    breadth-first search from the grown pixels through the crease, across
//!    depth-continuous steps only): a crease is split between its two sides.
//! 3. A segment whose area (the sum of each pixel's footprint `(z/fx)·(z/fy)`) is below
//!    `min_segment_area_m2` joins the neighbouring large segment it shares the most
//!    depth-continuous 4-neighbour pairs with, or becomes background if there is none
//!    (one pass).
//! 4. Labels are `1..=n` by decreasing area (ties by first pixel in row-major order).
//! 5. A connected region of pixels without depth whose border (its 4-neighbours, the image
//!    edge counting as unlabelled) is at least 80 % labelled is an enclosed hole: it takes
//!    the most common label of its border; if its area (pixels times the mean footprint of
//!    its labelled border pixels) is at least `hole_min_area_m2` it is flagged [`HOLE`].

use super::{
    SegmentError, SegmenterParams,
    geometry::{CREASE_BLOCK, P3, dot, sub},
};

/// Flag of a filled hole pixel in the `hole` buffer.
pub(super) const HOLE: u8 = 1;
const NONE: u32 = u32::MAX;
/// Share of a hole's border that must be labelled for the hole to be filled.
const ENCLOSED_SHARE: f32 = 0.8;

/// Scratch of [`grow_segments`], reused across frames.
#[derive(Debug, Default)]
pub(super) struct GrowScratch {
    comp: Vec<u32>,
    queue: Vec<u32>,
    area: Vec<f32>,
    first: Vec<u32>,
    target: Vec<u32>,
    order: Vec<u32>,
    pairs: Vec<(u32, u32)>,
    tally: Vec<(u16, u32)>,
}

/// Inputs of [`grow_segments`].
pub(super) struct GrowInput<'a> {
    pub(super) w: usize,
    pub(super) h: usize,
    pub(super) pts: &'a [P3],
    pub(super) nrm: &'a [P3],
    pub(super) crease: &'a [u8],
    /// Object pixels (above the table, inside its hull).
    pub(super) object: &'a [bool],
    /// Footprint of each pixel, square metres per pixel at its depth.
    pub(super) px_area_m2: &'a [f32],
}

/// The root of `i` in the union-find forest `parent` (halving the path on the way).
pub(crate) fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let up = parent[parent[i as usize] as usize];
        parent[i as usize] = up;
        i = up;
    }
    i
}

/// Joins the trees of `a` and `b`; the smaller root becomes the root of both.
pub(crate) fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra.max(rb) as usize] = ra.min(rb);
    }
}

/// Whether the surface bends away from the camera between pixels `i` and `j` (a convex
/// edge): each point lies behind the other's tangent plane (normals face the camera). An
/// object's own edges are convex; where two objects meet, the surface folds towards the
/// camera (a concave crease) or one point lies in front of the other's plane (occlusion).
fn convex(pts: &[P3], nrm: &[P3], i: usize, j: usize) -> bool {
    let (p, q, np, nq) = (pts[i], pts[j], nrm[i], nrm[j]);
    np != [0.0; 3] && nq != [0.0; 3] && dot(np, sub(q, p)) < 0.0 && dot(nq, sub(p, q)) < 0.0
}

/// `true` if `q` continues `p`'s surface (module docs, rule 1).
fn continuous(p: P3, np: P3, q: P3, params: &SegmenterParams) -> bool {
    continuous_within(p, np, q, params.depth_jump_at_m(p[2]))
}

/// [`continuous`] with `p`'s tolerance `jump` ([`SegmenterParams::depth_jump_at_m`]).
fn continuous_within(p: P3, np: P3, q: P3, jump: f32) -> bool {
    let dz = (q[2] - p[2]).abs();
    if dz > 3.0 * jump {
        return false;
    }
    if np == [0.0; 3] {
        dz <= jump
    } else {
        dot(np, sub(q, p)).abs() <= jump
    }
}

/// Per-root sums `sums[root] += value` over a run of pixels, with the running sum of the
/// current root kept in a register: the same additions in the same order (so the same
/// bits), without a store and reload per pixel.
#[derive(Debug, Default)]
struct RootSum {
    /// The current root and its running sum.
    run: Option<(u32, f32)>,
}

impl RootSum {
    fn add(&mut self, sums: &mut [f32], root: u32, value: f32) {
        match &mut self.run {
            Some((r, sum)) if *r == root => *sum += value,
            _ => {
                self.flush(sums);
                self.run = Some((root, sums[root as usize] + value));
            }
        }
    }

    /// Writes the running sum back; call after the last [`Self::add`].
    fn flush(&mut self, sums: &mut [f32]) {
        if let Some((r, sum)) = self.run.take() {
            sums[r as usize] = sum;
        }
    }
}

/// Grows segments (module docs) into `labels` and flags filled holes in `hole`; returns the
/// number of segments.
///
/// # Errors
/// [`SegmentError::TooManySegments`] if more than 65 535 segments remain after cleanup.
pub(super) fn grow_segments(
    inp: &GrowInput<'_>,
    params: &SegmenterParams,
    s: &mut GrowScratch,
    labels: &mut [u16],
    hole: &mut [u8],
    step: &mut [u8],
) -> Result<usize, SegmentError> {
    let (w, h) = (inp.w, inp.h);
    let n = w * h;
    let cos_normal = libm::cosf(params.grow_normal_deg.to_radians());
    let blocked = |i: usize| inp.crease[i] & CREASE_BLOCK != 0;

    // 1. Union-find over the grown (non-crease) object pixels.
    s.comp.clear();
    s.comp
        .extend((0..n as u32).map(|i| if inp.object[i as usize] { i } else { NONE }));
    step.fill(0);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if !inp.object[i] || blocked(i) {
                continue;
            }
            let (p, np) = (inp.pts[i], inp.nrm[i]);
            let jump = params.depth_jump_at_m(p[2]);
            for j in [(x + 1 < w).then_some(i + 1), (y + 1 < h).then_some(i + w)]
                .into_iter()
                .flatten()
            {
                // Both grown object pixels: join them, or flag a step.
                if !inp.object[j] || blocked(j) {
                    continue;
                }
                let nq = inp.nrm[j];
                let joins = continuous_within(p, np, inp.pts[j], jump)
                    && (np == [0.0; 3] || nq == [0.0; 3] || dot(np, nq) >= cos_normal);
                if joins {
                    union(&mut s.comp, i as u32, j as u32);
                } else if !convex(inp.pts, inp.nrm, i, j) {
                    (step[i], step[j]) = (1, 1);
                }
            }
        }
    }
    for i in 0..n {
        if s.comp[i] != NONE {
            s.comp[i] = if blocked(i) {
                NONE
            } else {
                find(&mut s.comp, i as u32)
            };
        }
    }

    // 2. Crease pixels take the segment of the nearest grown pixel.
    s.queue.clear();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if s.comp[i] == NONE {
                continue;
            }
            let crease = |j: usize| s.comp[j] == NONE && inp.object[j];
            if (x > 0 && crease(i - 1))
                || (x + 1 < w && crease(i + 1))
                || (y > 0 && crease(i - w))
                || (y + 1 < h && crease(i + w))
            {
                s.queue.push(i as u32);
            }
        }
    }
    let mut head = 0;
    while let Some(&i) = s.queue.get(head) {
        head += 1;
        let i = i as usize;
        for j in neighbours(i, w, h) {
            if s.comp[j] == NONE
                && inp.object[j]
                && continuous(inp.pts[i], inp.nrm[i], inp.pts[j], params)
            {
                s.comp[j] = s.comp[i];
                s.queue.push(j as u32);
            }
        }
    }

    // 3. Areas per root, then small segments join their best large neighbour.
    s.area.clear();
    s.area.resize(n, 0.0);
    let mut sum = RootSum::default();
    for (&r, &a) in s.comp.iter().zip(inp.px_area_m2) {
        if r != NONE {
            sum.add(&mut s.area, r, a);
        }
    }
    sum.flush(&mut s.area);
    let small = |area: &[f32], r: u32| area[r as usize] < params.min_segment_area_m2;
    s.pairs.clear();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let a = s.comp[i];
            if a == NONE {
                continue;
            }
            for j in [
                Some(i + 1).filter(|_| x + 1 < w),
                Some(i + w).filter(|_| y + 1 < h),
            ]
            .into_iter()
            .flatten()
            {
                let b = s.comp[j];
                if b == NONE || b == a {
                    continue;
                }
                let (pi, pj) = (inp.pts[i], inp.pts[j]);
                let jump = params.depth_jump_at_m(pi[2]);
                if pi[2] > 0.0 && pj[2] > 0.0 && (pi[2] - pj[2]).abs() > jump {
                    continue;
                }
                match (small(&s.area, a), small(&s.area, b)) {
                    (true, false) => s.pairs.push((a, b)),
                    (false, true) => s.pairs.push((b, a)),
                    _ => {}
                }
            }
        }
    }
    s.pairs.sort_unstable();
    s.target.clear();
    s.target.resize(n, NONE);
    let mut k = 0;
    while k < s.pairs.len() {
        let from = s.pairs[k].0;
        let (mut best, mut best_count) = (NONE, 0);
        while k < s.pairs.len() && s.pairs[k].0 == from {
            let to = s.pairs[k].1;
            let mut count = 0;
            while k < s.pairs.len() && s.pairs[k] == (from, to) {
                count += 1;
                k += 1;
            }
            if count > best_count {
                (best, best_count) = (to, count);
            }
        }
        s.target[from as usize] = best;
    }
    for i in 0..n {
        let r = s.comp[i];
        if r != NONE && small(&s.area, r) {
            s.comp[i] = s.target[r as usize];
        }
    }

    // 4. Labels by decreasing area.
    s.area.fill(0.0);
    s.first.clear();
    s.first.resize(n, NONE);
    s.order.clear();
    let mut sum = RootSum::default();
    for i in 0..n {
        let r = s.comp[i];
        if r == NONE {
            continue;
        }
        if s.first[r as usize] == NONE {
            s.first[r as usize] = i as u32;
            s.order.push(r);
        }
        sum.add(&mut s.area, r, inp.px_area_m2[i]);
    }
    sum.flush(&mut s.area);
    let count = s.order.len();
    if count > usize::from(u16::MAX) {
        return Err(SegmentError::TooManySegments { count });
    }
    {
        let (area, first) = (&s.area, &s.first);
        s.order.sort_unstable_by(|&a, &b| {
            area[b as usize]
                .total_cmp(&area[a as usize])
                .then(first[a as usize].cmp(&first[b as usize]))
        });
    }
    // Reuse `target` as root -> label.
    for (rank, &r) in s.order.iter().enumerate() {
        s.target[r as usize] = rank as u32 + 1;
    }
    for (l, &r) in labels.iter_mut().zip(&s.comp) {
        *l = if r == NONE {
            0
        } else {
            s.target[r as usize] as u16
        };
    }

    fill_holes(inp, params, s, labels, hole);
    Ok(count)
}

/// Rule 5 of the module docs.
fn fill_holes(
    inp: &GrowInput<'_>,
    params: &SegmenterParams,
    s: &mut GrowScratch,
    labels: &mut [u16],
    hole: &mut [u8],
) {
    let (w, h) = (inp.w, inp.h);
    hole.fill(0);
    // `comp` marks visited hole pixels from here on.
    s.comp.fill(0);
    for start in 0..w * h {
        if inp.pts[start][2] > 0.0 || s.comp[start] != 0 {
            continue;
        }
        s.queue.clear();
        s.queue.push(start as u32);
        s.comp[start] = 1;
        s.tally.clear();
        let (mut border, mut labelled, mut border_area) = (0u32, 0u32, 0.0f32);
        let mut head = 0;
        while let Some(&i) = s.queue.get(head) {
            head += 1;
            let i = i as usize;
            let (x, y) = (i % w, i / w);
            border += u32::from(x == 0) + u32::from(x + 1 == w);
            border += u32::from(y == 0) + u32::from(y + 1 == h);
            for j in neighbours(i, w, h) {
                if inp.pts[j][2] <= 0.0 {
                    if s.comp[j] == 0 {
                        s.comp[j] = 1;
                        s.queue.push(j as u32);
                    }
                    continue;
                }
                border += 1;
                let l = labels[j];
                if l != 0 {
                    labelled += 1;
                    border_area += inp.px_area_m2[j];
                    match s.tally.iter_mut().find(|(t, _)| *t == l) {
                        Some((_, c)) => *c += 1,
                        None => s.tally.push((l, 1)),
                    }
                }
            }
        }
        if border == 0 || (labelled as f32) < ENCLOSED_SHARE * border as f32 {
            continue;
        }
        let Some(&(fill, _)) = s
            .tally
            .iter()
            .max_by(|a, b| a.1.cmp(&b.1).then(b.0.cmp(&a.0)))
        else {
            continue;
        };
        // Footprint of a hole pixel: that of its labelled border pixels on average.
        let area = s.queue.len() as f32 * border_area / labelled as f32;
        let flag = if area >= params.hole_min_area_m2 {
            HOLE
        } else {
            0
        };
        for &i in &s.queue {
            labels[i as usize] = fill;
            hole[i as usize] = flag;
        }
    }
}

/// The 4-neighbours of pixel `i` inside a `w × h` image.
pub(super) fn neighbours(i: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y) = (i % w, i / w);
    [
        (x > 0).then(|| i - 1),
        (x + 1 < w).then(|| i + 1),
        (y > 0).then(|| i - w),
        (y + 1 < h).then(|| i + w),
    ]
    .into_iter()
    .flatten()
}
