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
    CHUNK_PX, SegmentError, SegmenterParams,
    geometry::{CREASE_BLOCK, P3, dot, sub},
};
use crate::par::*;

/// Flag of a filled hole pixel in the `hole` buffer.
pub(super) const HOLE: u8 = 1;
const NONE: u32 = u32::MAX;
/// Share of a hole's border that must be labelled for the hole to be filled.
const ENCLOSED_SHARE: f32 = 0.8;

/// Scratch of [`grow_segments`], reused across frames.
#[derive(Debug, Default)]
pub(super) struct GrowScratch {
    /// Per pixel: the [`Links`] flags of rule 1.
    links: Vec<u8>,
    /// Union-find forest over the grown pixels (rule 1).
    parent: Vec<u32>,
    /// Per pixel: its segment as a dense id (segments numbered by their union-find root,
    /// the least pixel index of their grown pixels), [`NONE`] outside every segment.
    id: Vec<u32>,
    queue: Vec<u32>,
    /// Per segment id: area, first pixel, segment it ends in (rule 3), label (rule 4).
    area: Vec<f32>,
    first: Vec<u32>,
    fate: Vec<u32>,
    label: Vec<u32>,
    /// Per segment id: whether a small segment joins it (its area is summed again).
    grows: Vec<bool>,
    order: Vec<u32>,
    pairs: Vec<(u32, u32)>,
    tally: Vec<(u16, u32)>,
}

/// Flags of one pixel for rule 1, found for all pixels in parallel before the serial
/// union-find.
struct Links;

impl Links {
    /// A grown pixel: an object pixel not on a blocking crease.
    const GROWN: u8 = 1;
    /// Grown, and joins its right neighbour.
    const JOIN_RIGHT: u8 = 2;
    /// Grown, and joins the neighbour below.
    const JOIN_DOWN: u8 = 4;
    /// Grown, and a step to its right neighbour (grown, not joined, not convex).
    const STEP_RIGHT: u8 = 8;
    /// Grown, and a step to the neighbour below.
    const STEP_DOWN: u8 = 16;
    /// Grown, with a 4-neighbour on a blocking crease: where rule 2's search starts.
    const SEED: u8 = 32;
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
    /// The rows outside which `object` is all `false`
    /// ([`object_rows`](super::geometry::object_rows)).
    pub(super) object_rows: core::ops::Range<usize>,
    /// Footprint of each pixel, square metres per pixel at its depth.
    pub(super) px_area_m2: &'a [f32],
}

/// Whether every id of `ids` is `NONE` (no segment): one test without branches, for
/// chunks of up to [`CHUNK_PX`] pixels.
fn all_none(ids: &[u32]) -> bool {
    ids.iter().fold(true, |all, &d| all & (d == NONE))
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
///
/// Invariant (with [`find`]): a pixel's parent is never after it, `parent[i] <= i`, as
/// both only ever point a pixel to a smaller index; [`grow_segments`] reads ids through
/// it.
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

/// Rule 1's flags of row `y` into `links`, and its union-find parents (each grown pixel
/// its own root, [`NONE`] elsewhere) into `parent`.
fn link_row(
    inp: &GrowInput<'_>,
    params: &SegmenterParams,
    cos_normal: f32,
    y: usize,
    links: &mut [u8],
    parent: &mut [u32],
) {
    let w = inp.w;
    let object = &inp.object[y * w..(y + 1) * w];
    // Cleared a row at a time (a fill per chunk costs a call each).
    links.fill(0);
    parent.fill(NONE);
    for (c, ((links, parents), object)) in links
        .chunks_mut(CHUNK_PX)
        .zip(parent.chunks_mut(CHUNK_PX))
        .zip(object.chunks(CHUNK_PX))
        .enumerate()
    {
        let x0 = c * CHUNK_PX;
        // A chunk without object pixels has no grown one (a test without branches, which
        // the compiler vectorises).
        if !object.iter().fold(false, |any, &o| any | o) {
            continue;
        }
        for (k, (link, parent)) in links.iter_mut().zip(parents.iter_mut()).enumerate() {
            link_pixel(inp, params, cos_normal, (x0 + k, y), link, parent);
        }
    }
}

/// Rule 1's flags of pixel `(x, y)` into `link` and its union-find parent into `parent`
/// (see [`link_row`]); both start cleared.
fn link_pixel(
    inp: &GrowInput<'_>,
    params: &SegmenterParams,
    cos_normal: f32,
    (x, y): (usize, usize),
    link: &mut u8,
    parent: &mut u32,
) {
    let (w, h) = (inp.w, inp.h);
    let blocked = |i: usize| inp.crease[i] & CREASE_BLOCK != 0;
    let grown = |i: usize| inp.object[i] && !blocked(i);
    let on_crease = |i: usize| inp.object[i] && blocked(i);
    let i = y * w + x;
    if !grown(i) {
        return;
    }
    *parent = i as u32;
    *link = Links::GROWN;
    let (p, np) = (inp.pts[i], inp.nrm[i]);
    let jump = params.depth_jump_at_m(p[2]);
    for (j, join, step) in [
        (
            (x + 1 < w).then_some(i + 1),
            Links::JOIN_RIGHT,
            Links::STEP_RIGHT,
        ),
        (
            (y + 1 < h).then_some(i + w),
            Links::JOIN_DOWN,
            Links::STEP_DOWN,
        ),
    ] {
        // Both grown object pixels: join them, or flag a step.
        let Some(j) = j.filter(|&j| grown(j)) else {
            continue;
        };
        let nq = inp.nrm[j];
        let joins = continuous_within(p, np, inp.pts[j], jump)
            && (np == [0.0; 3] || nq == [0.0; 3] || dot(np, nq) >= cos_normal);
        if joins {
            *link |= join;
        } else if !convex(inp.pts, inp.nrm, i, j) {
            *link |= step;
        }
    }
    if (x > 0 && on_crease(i - 1))
        || (x + 1 < w && on_crease(i + 1))
        || (y > 0 && on_crease(i - w))
        || (y + 1 < h && on_crease(i + w))
    {
        *link |= Links::SEED;
    }
}

/// Grows segments (module docs) into `labels` and flags filled holes in `hole`; returns the
/// number of segments.
///
/// The per-pixel tests of rule 1 and the final labels run rows in parallel (with the
/// `threads` feature); the union-find, the search of rule 2 and the sums run in row-major
/// order, so every sum adds the same values in the same order whatever the thread count.
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

    // Only the rows `y0..y1` hold object pixels: the serial passes below skip the others,
    // whose pixels are in no segment (the same result as a pass over the whole frame).
    let (y0, y1) = (inp.object_rows.start, inp.object_rows.end);
    let rows = y0 * w..y1 * w;

    // 1. Union-find over the grown (non-crease) object pixels; a pixel's root is the least
    // index in its tree (see `union`), so the roots do not depend on the order of joins.
    s.links.resize(n, 0);
    s.parent.resize(n, NONE);
    s.links
        .par_chunks_mut(w)
        .zip(s.parent.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (links, parent))| {
            if (y0..y1).contains(&y) {
                link_row(inp, params, cos_normal, y, links, parent);
            } else {
                links.fill(0);
                parent.fill(NONE);
            }
        });
    let links: &[u8] = &s.links;
    step.par_chunks_mut(w).enumerate().for_each(|(y, step)| {
        if !(y0..y1).contains(&y) {
            step.fill(0);
            return;
        }
        let row = &links[y * w..(y + 1) * w];
        let above = y.checked_sub(1).map(|u| &links[u * w..(u + 1) * w]);
        for (x, st) in step.iter_mut().enumerate() {
            let mut f = row[x] & (Links::STEP_RIGHT | Links::STEP_DOWN);
            if x > 0 {
                f |= row[x - 1] & Links::STEP_RIGHT;
            }
            if let Some(above) = above {
                f |= above[x] & Links::STEP_DOWN;
            }
            *st = u8::from(f != 0);
        }
    });
    // The serial passes skip chunks of pixels whose flags `any` (the union of them) shows
    // nothing to do there.
    let chunks = || {
        rows.clone().step_by(CHUNK_PX).map(|i0| {
            let i1 = (i0 + CHUNK_PX).min(rows.end);
            (i0..i1, links[i0..i1].iter().fold(0, |any, &l| any | l))
        })
    };
    for (chunk, any) in chunks() {
        if any & (Links::JOIN_RIGHT | Links::JOIN_DOWN) == 0 {
            continue;
        }
        for i in chunk {
            let link = links[i];
            if link & Links::JOIN_RIGHT != 0 {
                union(&mut s.parent, i as u32, i as u32 + 1);
            }
            if link & Links::JOIN_DOWN != 0 {
                union(&mut s.parent, i as u32, (i + w) as u32);
            }
        }
    }
    // Dense ids in the order of the roots; the seeds of rule 2 in row-major order. A
    // pixel's parent is an earlier pixel of its tree (`union` and `find` only ever point
    // to a smaller index), whose id is already that of the root.
    s.id.resize(n, NONE);
    s.id.fill(NONE);
    s.queue.clear();
    let mut count = 0u32;
    for (chunk, any) in chunks() {
        if any & Links::GROWN == 0 {
            continue;
        }
        for i in chunk {
            let link = links[i];
            if link & Links::GROWN == 0 {
                // Already NONE, but with this store the scan measures fewer instructions
                // (callgrind, 3 packed frames: 531.83 M against 532.30 M without it).
                s.id[i] = NONE;
                continue;
            }
            let up = s.parent[i] as usize;
            debug_assert!(up <= i, "union-find parent after its pixel");
            s.id[i] = if up == i {
                count += 1;
                count - 1
            } else {
                s.id[up]
            };
            if link & Links::SEED != 0 {
                s.queue.push(i as u32);
            }
        }
    }

    // 2. Crease pixels take the segment of the nearest grown pixel.
    let mut head = 0;
    while let Some(&i) = s.queue.get(head) {
        head += 1;
        let i = i as usize;
        for j in neighbours(i, w, h) {
            if s.id[j] == NONE
                && inp.object[j]
                && continuous(inp.pts[i], inp.nrm[i], inp.pts[j], params)
            {
                s.id[j] = s.id[i];
                s.queue.push(j as u32);
            }
        }
    }

    // 3. Areas and first pixels per segment, and the depth-continuous 4-neighbour pairs of
    // different segments; then small segments join their best large neighbour.
    let count = count as usize;
    s.area.clear();
    s.area.resize(count, 0.0);
    s.first.clear();
    s.first.resize(count, NONE);
    s.pairs.clear();
    let mut sum = RootSum::default();
    for y in y0..y1 {
        for x0 in (0..w).step_by(CHUNK_PX) {
            let xs = x0..(x0 + CHUNK_PX).min(w);
            // A chunk of pixels in no segment adds nothing.
            if all_none(&s.id[y * w + xs.start..y * w + xs.end]) {
                continue;
            }
            for x in xs {
                let i = y * w + x;
                let a = s.id[i];
                if a == NONE {
                    continue;
                }
                sum.add(&mut s.area, a, inp.px_area_m2[i]);
                if s.first[a as usize] == NONE {
                    s.first[a as usize] = i as u32;
                }
                for j in [(x + 1 < w).then_some(i + 1), (y + 1 < h).then_some(i + w)]
                    .into_iter()
                    .flatten()
                {
                    let b = s.id[j];
                    if b == NONE || b == a {
                        continue;
                    }
                    let (pi, pj) = (inp.pts[i], inp.pts[j]);
                    let jump = params.depth_jump_at_m(pi[2]);
                    if pi[2] > 0.0 && pj[2] > 0.0 && (pi[2] - pj[2]).abs() > jump {
                        continue;
                    }
                    s.pairs.push((a, b));
                }
            }
        }
    }
    sum.flush(&mut s.area);
    let small = |area: &[f32], d: u32| area[d as usize] < params.min_segment_area_m2;
    // Each pair as (small, large); the others go.
    {
        let area = &s.area;
        s.pairs
            .retain_mut(|pair| match (small(area, pair.0), small(area, pair.1)) {
                (true, false) => true,
                (false, true) => {
                    *pair = (pair.1, pair.0);
                    true
                }
                _ => false,
            });
    }
    s.pairs.sort_unstable();
    // `fate`: the segment each ends in (itself if large, NONE if it becomes background).
    s.fate.clear();
    s.fate
        .extend((0..count as u32).map(|d| if small(&s.area, d) { NONE } else { d }));
    s.grows.clear();
    s.grows.resize(count, false);
    let mut k = 0;
    while k < s.pairs.len() {
        let from = s.pairs[k].0;
        let (mut best, mut best_count) = (NONE, 0);
        while k < s.pairs.len() && s.pairs[k].0 == from {
            let to = s.pairs[k].1;
            let mut c = 0;
            while k < s.pairs.len() && s.pairs[k] == (from, to) {
                c += 1;
                k += 1;
            }
            if c > best_count {
                (best, best_count) = (to, c);
            }
        }
        s.fate[from as usize] = best;
        if best != NONE {
            s.grows[best as usize] = true;
            s.first[best as usize] = s.first[best as usize].min(s.first[from as usize]);
        }
    }
    // A segment that small ones joined: its area again, over all its pixels in row-major
    // order (the same sum as over the merged labels).
    if s.grows.contains(&true) {
        for (d, area) in s.area.iter_mut().enumerate() {
            if s.grows[d] {
                *area = 0.0;
            }
        }
        let mut sum = RootSum::default();
        for (&d, &a) in s.id[rows.clone()].iter().zip(&inp.px_area_m2[rows.clone()]) {
            if d == NONE {
                continue;
            }
            let f = s.fate[d as usize];
            if f != NONE && s.grows[f as usize] {
                sum.add(&mut s.area, f, a);
            }
        }
        sum.flush(&mut s.area);
    }

    // 4. Labels by decreasing area.
    s.order.clear();
    s.order
        .extend((0..count as u32).filter(|&d| s.fate[d as usize] == d));
    let segments = s.order.len();
    if segments > usize::from(u16::MAX) {
        return Err(SegmentError::TooManySegments { count: segments });
    }
    {
        let (area, first) = (&s.area, &s.first);
        s.order.sort_unstable_by(|&a, &b| {
            area[b as usize]
                .total_cmp(&area[a as usize])
                .then(first[a as usize].cmp(&first[b as usize]))
        });
    }
    s.label.clear();
    s.label.resize(count, 0);
    for (rank, &d) in s.order.iter().enumerate() {
        s.label[d as usize] = rank as u32 + 1;
    }
    for d in 0..count {
        let f = s.fate[d];
        if f != NONE {
            s.label[d] = s.label[f as usize];
        }
    }
    let (id, label): (&[u32], &[u32]) = (&s.id, &s.label);
    labels
        .par_chunks_mut(w)
        .zip(id.par_chunks(w))
        .for_each(|(labels, id)| {
            labels.fill(0);
            for (labels, id) in labels.chunks_mut(CHUNK_PX).zip(id.chunks(CHUNK_PX)) {
                // Most chunks are in no segment at all: one test without branches.
                if all_none(id) {
                    continue;
                }
                for (l, &d) in labels.iter_mut().zip(id) {
                    if d != NONE {
                        *l = label[d as usize] as u16;
                    }
                }
            }
        });

    fill_holes(inp, params, s, labels, hole);
    Ok(segments)
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
    // Pixels without depth are in no segment (`id` is NONE there): from here on `id` marks
    // the visited ones (see `fill_hole_at`).
    for (c, chunk) in inp.pts[..w * h].chunks(CHUNK_PX).enumerate() {
        // Most chunks have a depth at every pixel: one test without branches skips them.
        if chunk.iter().fold(true, |all, p| all & (p[2] > 0.0)) {
            continue;
        }
        for start in c * CHUNK_PX..c * CHUNK_PX + chunk.len() {
            fill_hole_at(inp, params, s, start, labels, hole);
        }
    }
}

/// Rule 5 for the region of pixels without depth at `start`, unless `start` has a depth
/// or is visited (part of a region done before).
fn fill_hole_at(
    inp: &GrowInput<'_>,
    params: &SegmenterParams,
    s: &mut GrowScratch,
    start: usize,
    labels: &mut [u16],
    hole: &mut [u8],
) {
    let (w, h) = (inp.w, inp.h);
    let visited = 0;
    if inp.pts[start][2] > 0.0 || s.id[start] != NONE {
        return;
    }
    s.queue.clear();
    s.queue.push(start as u32);
    s.id[start] = visited;
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
                if s.id[j] == NONE {
                    s.id[j] = visited;
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
        return;
    }
    let Some(&(fill, _)) = s
        .tally
        .iter()
        .max_by(|a, b| a.1.cmp(&b.1).then(b.0.cmp(&a.0)))
    else {
        return;
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
