//! The FindAction heatmap, calibrated to the paper's thresholds `l_u = 150`, `l_l = 120`.
//!
//! Rule (distances are Euclidean in the image, converted to metres at the pixel's depth by
//! `z / sqrt(fx·fy)`; a filled hole uses its segment's mean depth):
//!
//! 1. **Uncertainty sources** `S`:
//!    - segment pixels on a soft (or blocking) concave crease: a bend where two objects may
//!      meet inside one segment;
//!    - segment pixels on a step: a neighbour they did not join in region growing (a depth
//!      step or sharp concave bend; inside one segment it means the segment went around
//!      it). Convex bends, an object's own edges, are not flagged (see `grow`);
//!    - segment pixels of a filled hole in depth;
//!    - necks: a *notch* is a segment pixel on the segment's outline (a 4-neighbour is
//!      unlabelled or off the image) whose disc of radius `neck_radius_m` holds at least
//!      `neck_notch_share` pixels of its own segment (a straight outline holds about half,
//!      a convex one less). Each notch is joined to the nearest other notch of its segment
//!      between `neck_radius_m / 2` and `neck_chord_max_m` away whose straight chord lies
//!      in the segment, and the chord's pixels are sources. Two convex objects merged
//!      into one segment meet at a waist with a notch on either side; this is the only cue
//!      where they touch at a point, such as two cylinders side by side, with no crease
//!      or step in view;
//!    - contacts: a segment pixel from which, along +x, −x, +y or −y, the first labelled
//!      pixel has another label and a depth within `contact_depth_m`, and the unlabelled
//!      pixels in between with a depth reading span at most `contact_gap_m` (pixels
//!      without depth, such as the shadow a structured-light camera casts beside an
//!      object, do not count, up to 32 pixels in all); the unlabelled pixels in between are
//!      sources too.
//!    - packs: a segment larger than one object (the two in-plane principal axes of its
//!      3-D points give lengths `L₁ ≥ L₂`, `L = √(12 λ)` as for a uniform rectangle;
//!      oversized when `L₁ > pack_max_len_m` or `L₁·L₂ > pack_max_area_m2`) is a pack of
//!      look-alike objects the segmenter could not tell apart: it is cut into a grid of
//!      `round(L / pack_cell_m)` cells along each axis longer than `pack_max_len_m` (at
//!      least two along `L₁`), and the one-pixel cut lines are sources. A segment that
//!      already holds sources of the rules above in its interior (farther than `band_m`
//!      from the background; at least half its width `L₂` in pixels) is left as it is: those show where its objects meet. The cuts need not fall on
//!      the true seams: they
//!      give FindAction certain cells with uncertain bands between, so a push shears one
//!      part of the pack along another instead of stopping the loop;
//! 2. **Background** `B`: unlabelled pixels that are not contact-gap pixels.
//! 3. With `d_S`, `d_B` the distances (metres) to `S` and `B`, a segment pixel gets
//!    - `120 + ⌊30 · d_S / band_m⌋` (120..=149) if `d_S < band_m` (uncertain band);
//!    - else `rim_heat` (< 120) if `d_B < rim_m` (object rim next to the table);
//!    - else `150 + ⌊105 · min(1, min(d_S − band_m, d_B − rim_m) / certain_ramp_m)⌋`
//!      (150..=255, certain, growing away from every source and the table).
//! 4. Contact-gap pixels get 120. Every other pixel keeps the background value the caller
//!    wrote: `⌊100 · max(0, h / h_min(z))⌋` for a point at height `h` below the object
//!    threshold `h_min` ([`SegmenterParams::min_height_at_m`]) over the table, so the table
//!    is 0 and the value rises towards 100 just under the threshold; 0 for pixels without
//!    depth and for points at or above `h_min` that are in no segment (outside the table's
//!    hull, too high, or dropped as too small).

use super::{
    CHUNK_PX, HEAT_CERTAIN, HEAT_UNCERTAIN, SegmenterParams,
    edt::{EdtScratch, Window, squared_distance},
    geometry::{CREASE_SOFT, P3},
    grow::HOLE,
};
use crate::par::*;

const SOURCE: u8 = 1;
const GAP: u8 = 2;
/// Longest contact scan, pixels (bounds the work, and the width of a shadow in depth that
/// may separate two touching objects).
const MAX_SCAN_PX: usize = 32;
/// Largest notch disc radius, pixels (bounds the work on close-up frames).
const MAX_NECK_RADIUS_PX: isize = 24;

/// Scratch of [`heatmap`], reused across frames.
#[derive(Debug, Default)]
pub(super) struct HeatScratch {
    mark: Vec<u8>,
    d_source: Vec<f32>,
    d_background: Vec<f32>,
    mean_z: Vec<(f64, u32)>,
    notch: Vec<u32>,
    /// Segment pixels with a 4-neighbour off the image or in another segment (or none),
    /// in row-major order: the candidates of the necks' outline.
    rim: Vec<u32>,
    moments: Vec<Moments>,
    cuts: Vec<Option<Cut>>,
    edt: EdtScratch,
}

/// Inputs of [`heatmap`].
pub(super) struct HeatInput<'a> {
    pub(super) w: usize,
    pub(super) h: usize,
    pub(super) pts: &'a [P3],
    pub(super) crease: &'a [u8],
    pub(super) hole: &'a [u8],
    /// Pixels flagged by region growing as not joining a neighbour (non-zero).
    pub(super) step: &'a [u8],
    pub(super) labels: &'a [u16],
    pub(super) segments: usize,
    /// `1 / sqrt(fx·fy)`: metres per pixel per metre of depth.
    pub(super) inv_focal: f32,
    /// Unit normal of the table plane, camera frame.
    pub(super) table_normal: P3,
}

/// Writes the heat of segment and contact-gap pixels into `heat` (module docs); other
/// pixels keep their value.
pub(super) fn heatmap(
    inp: &HeatInput<'_>,
    params: &SegmenterParams,
    s: &mut HeatScratch,
    heat: &mut [u8],
) {
    let (w, h) = (inp.w, inp.h);
    let n = w * h;
    let labels = inp.labels;
    s.mark.clear();
    s.mark.resize(n, 0);
    s.rim.clear();
    s.d_source.resize(n, 0.0);
    s.d_background.resize(n, 0.0);
    // Every pass that reads only segment pixels (and the contact gaps between them) runs
    // over the segments' bounding box alone, in row-major order: the pixels it skips are
    // unlabelled, so it does exactly what a pass over the whole frame does.
    let Some(inner) = bounding_box(w, labels) else {
        return;
    };

    // Mean depth per segment, for pixels without a reading.
    s.mean_z.clear();
    s.mean_z.resize(inp.segments + 1, (0.0, 0));
    // The current label's sum stays in registers along a run of its pixels (the same
    // additions in the same order).
    let mut run: Option<(usize, (f64, u32))> = None;
    // The least depth of a segment pixel (a filled hole's mean depth is no less).
    let mut z_min = f32::INFINITY;
    for (y, xs) in labelled_runs(w, inner, labels) {
        let run_px = y * w + xs.start..y * w + xs.end;
        for (&l, p) in labels[run_px.clone()].iter().zip(&inp.pts[run_px]) {
            if l == 0 || p[2] <= 0.0 {
                continue;
            }
            z_min = z_min.min(p[2]);
            let l = usize::from(l);
            match &mut run {
                Some((rl, m)) if *rl == l => *m = (m.0 + f64::from(p[2]), m.1 + 1),
                _ => {
                    if let Some((rl, m)) = run {
                        s.mean_z[rl] = m;
                    }
                    let m = s.mean_z[l];
                    run = Some((l, (m.0 + f64::from(p[2]), m.1 + 1)));
                }
            }
        }
    }
    if let Some((rl, m)) = run {
        s.mean_z[rl] = m;
    }
    let mean_z: &[(f64, u32)] = &s.mean_z;
    let depth = |i: usize| -> f32 {
        let z = inp.pts[i][2];
        if z > 0.0 {
            return z;
        }
        match mean_z.get(usize::from(labels[i])) {
            Some(&(sum, c)) if c > 0 => (sum / f64::from(c)) as f32,
            _ => 0.0,
        }
    };

    // 1a. Contacts and their gaps (and 1b. creases, steps and holes).
    for (y, xs) in labelled_runs(w, inner, labels) {
        for x in xs {
            let i = y * w + x;
            let a = labels[i];
            if a == 0 {
                continue;
            }
            // 1b. Creases, steps and holes.
            if inp.crease[i] & CREASE_SOFT != 0 || inp.step[i] != 0 || inp.hole[i] == HOLE {
                s.mark[i] |= SOURCE;
            }
            // Every scan stops at once where each 4-neighbour is off the image or in `a`.
            let same = |j: usize| labels[j] == a;
            let inner = [x > 0, x + 1 < w, y > 0, y + 1 < h];
            if !inner.contains(&false) && same(i - 1) && same(i + 1) && same(i - w) && same(i + w) {
                continue;
            }
            s.rim.push(i as u32);
            if (x == 0 || same(i - 1))
                && (x + 1 == w || same(i + 1))
                && (y == 0 || same(i - w))
                && (y + 1 == h || same(i + w))
            {
                continue;
            }
            let z = depth(i);
            let m_per_px = z * inp.inv_focal;
            let gap_px = if m_per_px > 0.0 {
                ((params.contact_gap_m / m_per_px) as usize).min(MAX_SCAN_PX)
            } else {
                0
            };
            let (x, y) = (x as isize, y as isize);
            for (dx, dy) in [(1isize, 0isize), (-1, 0), (0, 1), (0, -1)] {
                // Unlabelled pixels with depth count against the gap; holes do not.
                let mut open = gap_px;
                for t in 1..=MAX_SCAN_PX as isize {
                    let (qx, qy) = (x + dx * t, y + dy * t);
                    if qx < 0 || qy < 0 || qx >= w as isize || qy >= h as isize {
                        break;
                    }
                    let q = qy as usize * w + qx as usize;
                    let b = labels[q];
                    if b == a {
                        break;
                    }
                    if b == 0 {
                        if inp.pts[q][2] > 0.0 {
                            if open == 0 {
                                break;
                            }
                            open -= 1;
                        }
                        continue;
                    }
                    if (depth(q) - z).abs() < params.contact_depth_m {
                        s.mark[i] |= SOURCE;
                        for u in 1..t {
                            s.mark[(y + dy * u) as usize * w + (x + dx * u) as usize] |= GAP;
                        }
                    }
                    break;
                }
            }
        }
    }

    // 1c. Necks.
    necks(inp, params, &s.rim, &mut s.notch, &mut s.mark);

    // 2. Distance to the background. Only segment pixels read the distances, and every
    // source lies in the segments' bounding box: the distance to the sources is exact
    // there over the box alone, and the distance to the background over the box grown by a
    // pixel (a background pixel beyond it is farther than the grown box's edge, which is
    // background, in both coordinates).
    let outer = Window {
        x0: inner.x0.saturating_sub(1),
        x1: (inner.x1 + 1).min(w),
        y0: inner.y0.saturating_sub(1),
        y1: (inner.y1 + 1).min(h),
    };
    // Farther than these (pixels) the distances change no heat (rule 3: the band and the
    // ramp end, as does the interior of the pack rule) at any segment pixel, whose depth is
    // at least `z_min`; with 1 % to spare for rounding. Beyond them the transforms need not
    // be exact.
    let has_depth = mean_z[1..].iter().all(|&(_, c)| c > 0);
    let m_min = z_min * inp.inv_focal;
    let beyond_px = |m: f32| {
        if has_depth && m_min.is_finite() && m_min > 0.0 {
            1.01 * m / m_min + 1.0
        } else {
            f32::INFINITY
        }
    };
    let source_px = beyond_px(params.band_m + params.certain_ramp_m);
    let background_px = beyond_px((params.rim_m + params.certain_ramp_m).max(params.band_m));
    let mark = &s.mark;
    squared_distance(
        w,
        outer,
        background_px,
        |i| labels[i] == 0 && mark[i] & GAP == 0,
        &mut s.edt,
        &mut s.d_background,
    );

    // 1d. Packs: segments larger than one object (needs the distance to the background).
    pack_cuts(
        inp,
        inner,
        params,
        &s.d_background,
        (&mut s.moments, &mut s.cuts),
        &mut s.mark,
    );

    // 3. Heat.
    let mark = &s.mark;
    squared_distance(
        w,
        inner,
        source_px,
        |i| mark[i] != 0,
        &mut s.edt,
        &mut s.d_source,
    );
    let (d_source, d_background) = (&s.d_source, &s.d_background);
    // Contact gaps lie between segment pixels of one row or column: in the box too.
    heat[inner.y0 * w..inner.y1 * w]
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(k, heat)| {
            let y = inner.y0 + k;
            for (x, heat) in heat.iter_mut().enumerate().take(inner.x1).skip(inner.x0) {
                let i = y * w + x;
                let label = labels[i];
                if label == 0 {
                    if mark[i] & GAP != 0 {
                        *heat = HEAT_UNCERTAIN;
                    }
                    continue;
                }
                let m_per_px = depth(i) * inp.inv_focal;
                let d_s = d_source[i].sqrt() * m_per_px;
                let d_b = d_background[i].sqrt() * m_per_px;
                *heat = if d_s < params.band_m {
                    let band = f32::from(HEAT_CERTAIN - HEAT_UNCERTAIN);
                    HEAT_UNCERTAIN
                        + ((band * d_s / params.band_m) as u8)
                            .min(HEAT_CERTAIN - HEAT_UNCERTAIN - 1)
                } else if d_b < params.rim_m {
                    params.rim_heat
                } else {
                    let t = ((d_s - params.band_m).min(d_b - params.rim_m) / params.certain_ramp_m)
                        .clamp(0.0, 1.0);
                    HEAT_CERTAIN + (f32::from(u8::MAX - HEAT_CERTAIN) * t) as u8
                };
            }
        });
}

/// The rows of `win` cut into runs of up to [`CHUNK_PX`] pixels, `(y, xs)` in row-major
/// order, leaving out the runs without a labelled pixel (one test without branches a run):
/// what a pass over the segment pixels of the window visits.
fn labelled_runs(
    w: usize,
    win: Window,
    labels: &[u16],
) -> impl Iterator<Item = (usize, core::ops::Range<usize>)> {
    win.rows()
        .flat_map(|(y, xs)| {
            let end = xs.end;
            xs.step_by(CHUNK_PX)
                .map(move |x0| (y, x0..(x0 + CHUNK_PX).min(end)))
        })
        .filter(move |(y, xs)| {
            labels[y * w + xs.start..y * w + xs.end]
                .iter()
                .fold(0, |any, &l| any | l)
                != 0
        })
}

/// The smallest window holding every labelled pixel; `None` if there is none.
fn bounding_box(w: usize, labels: &[u16]) -> Option<Window> {
    let rows = |(_, row): &(usize, &[u16])| row.iter().any(|&l| l != 0);
    let y0 = labels.chunks_exact(w).enumerate().find(rows)?.0;
    let y1 = labels.chunks_exact(w).enumerate().rfind(rows)?.0 + 1;
    let (mut x0, mut x1) = (w, 0);
    for row in labels[y0 * w..y1 * w].chunks_exact(w) {
        if let Some(first) = row[..x0].iter().position(|&l| l != 0) {
            x0 = first;
        }
        if let Some(last) = row[x1..].iter().rposition(|&l| l != 0) {
            x1 = x1 + last + 1;
        }
    }
    Some(Window { x0, x1, y0, y1 })
}

/// A unit direction and the length along it, metres.
type Axis = ([f64; 3], f64);

/// First and second moments of a segment's 3-D points (camera frame, metres).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Moments {
    count: f64,
    /// Source pixels (rules 1a-1c) in the segment's interior (farther than `band_m`
    /// from the background).
    sources: u32,
    /// Sum of the points' depths, metres.
    depth_sum_m: f64,
    sum: [f64; 3],
    /// Sums of the products of coordinates `a <= b` at `[a][b]` (the rest stays zero).
    outer: [[f64; 3]; 3],
}

impl Moments {
    fn add(&mut self, p: [f64; 3]) {
        self.count += 1.0;
        for (a, pa) in p.iter().enumerate() {
            self.sum[a] += pa;
            // The upper triangle: the lower one is the same sums (`pa · pb = pb · pa`).
            for (b, pb) in p.iter().enumerate().skip(a) {
                self.outer[a][b] += pa * pb;
            }
        }
    }

    /// Centroid and the two in-plane principal axes with their lengths: a uniform
    /// rectangle of side `L` along an axis has variance `L²/12` there, so `L = √(12 λ)`
    /// (robust to a few stray points, unlike the span).
    fn axes(&self) -> Option<([f64; 3], [Axis; 2])> {
        if self.count < 3.0 {
            return None;
        }
        let mean = self.sum.map(|v| v / self.count);
        let cov = nalgebra::Matrix3::from_fn(|a, b| {
            self.outer[a.min(b)][a.max(b)] / self.count - mean[a] * mean[b]
        });
        let eig = cov.symmetric_eigen();
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let axis = |k: usize| {
            let v = eig.eigenvectors.column(order[k]);
            (
                [v[0], v[1], v[2]],
                (12.0 * eig.eigenvalues[order[k]].max(0.0)).sqrt(),
            )
        };
        Some((mean, [axis(0), axis(1)]))
    }
}

/// Marks cut lines through segments larger than one object as sources (module docs,
/// rule 1, packs).
fn pack_cuts(
    inp: &HeatInput<'_>,
    inner: Window,
    params: &SegmenterParams,
    d_background: &[f32],
    (moments, cuts): (&mut Vec<Moments>, &mut Vec<Option<Cut>>),
    mark: &mut [u8],
) {
    moments.clear();
    moments.resize(inp.segments + 1, Moments::default());
    // Labels are `0..=segments`; label 0 is never cut.
    cuts.clear();
    cuts.resize(inp.segments + 1, None);
    // Points are flattened onto the table plane, so an object's sides fold onto its
    // footprint's outline and the axes measure the footprint.
    let n = inp.table_normal.map(f64::from);
    let flatten = |p: P3| {
        let p = p.map(f64::from);
        let h = p[0] * n[0] + p[1] * n[1] + p[2] * n[2];
        [p[0] - h * n[0], p[1] - h * n[1], p[2] - h * n[2]]
    };
    for (y, xs) in labelled_runs(inp.w, inner, inp.labels) {
        for i in y * inp.w + xs.start..y * inp.w + xs.end {
            let (l, p, mk, d2_px) = (inp.labels[i], inp.pts[i], mark[i], d_background[i]);
            if l != 0
                && let Some(m) = moments.get_mut(usize::from(l))
            {
                // Sources in the interior: a hole or contact at the rim divides nothing.
                if mk & SOURCE != 0 && d2_px.sqrt() * p[2].max(0.0) * inp.inv_focal > params.band_m
                {
                    m.sources += 1;
                }
                if p[2] > 0.0 {
                    m.add(flatten(p));
                    m.depth_sum_m += f64::from(p[2]);
                }
            }
        }
    }
    for (label, m) in moments.iter().enumerate().skip(1) {
        let Some((centre, axes)) = m.axes() else {
            continue;
        };
        let [(_, long_m), (_, short_m)] = axes;
        let oversized = long_m > f64::from(params.pack_max_len_m)
            || long_m * short_m > f64::from(params.pack_max_area_m2);
        // Sources already inside the segment (a contact, crease or step as long as half
        // its width) divide it where the objects really meet: no guessed cuts then.
        let m_per_px = m.depth_sum_m / m.count * f64::from(inp.inv_focal);
        let seam_px = 0.5 * short_m / m_per_px;
        if !oversized || f64::from(m.sources) >= seam_px {
            continue;
        }
        let cell_m = f64::from(params.pack_cell_m);
        // Cells per axis: an axis longer than one object is cut into object-sized cells;
        // the long axis is cut at least once.
        let max_len_m = f64::from(params.pack_max_len_m);
        let cells_along = |len_m: f64| {
            if len_m > max_len_m {
                ((len_m / cell_m).round() as usize).clamp(1, 16)
            } else {
                1
            }
        };
        let cells = [cells_along(long_m).max(2), cells_along(short_m)];
        cuts[label] = Some(Cut {
            centre,
            axes,
            cells,
        });
    }
    if cuts.iter().all(Option::is_none) {
        return;
    }
    for (y, xs) in labelled_runs(inp.w, inner, inp.labels) {
        let run_px = y * inp.w + xs.start..y * inp.w + xs.end;
        for (i, (&l, &p)) in run_px
            .clone()
            .zip(inp.labels[run_px.clone()].iter().zip(&inp.pts[run_px]))
        {
            if l == 0 || p[2] <= 0.0 {
                continue;
            }
            let Some(Cut {
                centre,
                axes,
                cells,
            }) = cuts.get(usize::from(l)).and_then(Option::as_ref)
            else {
                continue;
            };
            // A cut is one pixel wide: within half a pixel of a cut position.
            let half_px_m = 0.5 * f64::from(p[2] * inp.inv_focal);
            let q = flatten(p);
            let d = [0, 1, 2].map(|a| q[a] - centre[a]);
            let on_cut = axes.iter().zip(*cells).any(|((axis, len_m), n)| {
                let along = d[0] * axis[0] + d[1] * axis[1] + d[2] * axis[2];
                // Position in cells from the start of the axis.
                let pos = (along / len_m + 0.5) * n as f64;
                let nearest = pos.round();
                nearest >= 1.0
                    && nearest <= (n - 1) as f64
                    && ((pos - nearest) * len_m / n as f64).abs() <= half_px_m
            });
            if on_cut {
                mark[i] |= SOURCE;
            }
        }
    }
}

/// The cut grid of one oversized segment: centroid, in-plane axes and cells per axis.
#[derive(Debug, Clone, Copy)]
pub(super) struct Cut {
    centre: [f64; 3],
    axes: [Axis; 2],
    cells: [usize; 2],
}

/// Marks the necks of the segments as sources (module docs, rule 1).
/// `rim`: the segment pixels that may be on an outline (see [`HeatScratch`]), in row-major
/// order.
fn necks(
    inp: &HeatInput<'_>,
    params: &SegmenterParams,
    rim: &[u32],
    notch: &mut Vec<u32>,
    mark: &mut [u8],
) {
    let (w, h) = (inp.w, inp.h);
    let labels = inp.labels;
    let px_per_m = |z: f32| 1.0 / (z * inp.inv_focal);

    // Notches: outline pixels (a 4-neighbour unlabelled or off the image) whose disc holds
    // at least `neck_notch_share` of pixels of their own segment.
    notch.clear();
    // The last disc's radius and half-widths.
    let mut disc: (isize, Vec<isize>) = (0, Vec::new());
    for &i in rim {
        let i = i as usize;
        let (x, y) = (i % w, i / w);
        let (a, z) = (labels[i], inp.pts[i][2]);
        if z <= 0.0 {
            continue;
        }
        let outline = [
            (x > 0).then(|| i - 1),
            (x + 1 < w).then(|| i + 1),
            (y > 0).then(|| i - w),
            (y + 1 < h).then(|| i + w),
        ]
        .into_iter()
        .any(|j| j.is_none_or(|j| labels[j] == 0));
        if !outline {
            continue;
        }
        let r = ((params.neck_radius_m * px_per_m(z)) as isize).clamp(1, MAX_NECK_RADIUS_PX);
        // The disc row by row: `half[|dy|]` is its half-width at `dy`; pixels off the
        // image count in `all`, never in `same`.
        if disc.0 != r {
            disc.1.clear();
            disc.1.extend((0..=r).map(|dy| {
                (0..=r)
                    .rev()
                    .find(|dx| dx * dx + dy * dy <= r * r)
                    .unwrap_or(0)
            }));
            disc.0 = r;
        }
        let half = &disc.1;
        let (mut same, mut all) = (0u32, 0u32);
        for dy in -r..=r {
            let hw = half[dy.unsigned_abs()];
            all += (2 * hw + 1) as u32;
            let qy = y as isize + dy;
            if qy < 0 || qy as usize >= h {
                continue;
            }
            let lo = (x as isize - hw).max(0) as usize;
            let hi = ((x as isize + hw) as usize).min(w - 1);
            let row = &labels[qy as usize * w..(qy as usize + 1) * w];
            same += row[lo..=hi].iter().map(|&l| u32::from(l == a)).sum::<u32>();
        }
        if same as f32 >= params.neck_notch_share * all as f32 {
            notch.push(i as u32);
        }
    }

    // Each notch's shortest chord to another notch of its segment: at least half the disc
    // radius and at most `neck_chord_max_m` long, every pixel on it in the segment.
    let on_chord = |p: (f32, f32), q: (f32, f32), steps: usize, t: usize| {
        let f = t as f32 / steps as f32;
        let x = (p.0 + f * (q.0 - p.0)).round() as usize;
        let y = (p.1 + f * (q.1 - p.1)).round() as usize;
        y * w + x
    };
    let xy = |i: usize| ((i % w) as f32, (i / w) as f32);
    for (k, &p) in notch.iter().enumerate() {
        let p = p as usize;
        let a = labels[p];
        let scale = px_per_m(inp.pts[p][2]);
        let (max_px, min_px) = (
            params.neck_chord_max_m * scale,
            0.5 * params.neck_radius_m * scale,
        );
        let pp = xy(p);
        let mut best: Option<(f32, (f32, f32))> = None;
        // Notches are in row-major order: later ones more than `max_px` rows down are out
        // of reach.
        for &q in &notch[k + 1..] {
            let q = q as usize;
            let qq = xy(q);
            if qq.1 - pp.1 > max_px {
                break;
            }
            let d = libm::hypotf(qq.0 - pp.0, qq.1 - pp.1);
            if labels[q] != a || d > max_px || d < min_px || best.is_some_and(|(b, _)| b <= d) {
                continue;
            }
            let steps = d.ceil() as usize;
            if (1..steps).all(|t| labels[on_chord(pp, qq, steps, t)] == a) {
                best = Some((d, qq));
            }
        }
        if let Some((d, qq)) = best {
            let steps = d.ceil() as usize;
            for t in 0..=steps {
                mark[on_chord(pp, qq, steps, t)] |= SOURCE;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two discs of radius 20 px whose centres are 38 px apart, both in segment 1, flat
    /// at 0.6 m with no crease, step or hole: only the neck can make the waist uncertain.
    #[test]
    fn the_waist_of_two_merged_discs_is_uncertain() {
        let (w, h) = (120, 60);
        let inside = |x: usize, y: usize, cx: f32| {
            let (dx, dy) = (x as f32 - cx, y as f32 - 30.0);
            dx * dx + dy * dy <= 400.0
        };
        let labels: Vec<u16> = (0..w * h)
            .map(|i| u16::from(inside(i % w, i / w, 41.0) || inside(i % w, i / w, 79.0)))
            .collect();
        let pts: Vec<P3> = (0..w * h).map(|_| [0.0, 0.0, 0.6]).collect();
        let zeros = vec![0u8; w * h];
        let inp = HeatInput {
            w,
            h,
            pts: &pts,
            crease: &zeros,
            hole: &zeros,
            step: &zeros,
            labels: &labels,
            segments: 1,
            inv_focal: 1.0 / 600.0,
            table_normal: [0.0, 0.0, -1.0],
        };
        let mut heat = vec![0u8; w * h];
        heatmap(
            &inp,
            &SegmenterParams::default(),
            &mut HeatScratch::default(),
            &mut heat,
        );
        let at = |x: usize, y: usize| heat[y * w + x];
        assert!(
            (HEAT_UNCERTAIN..HEAT_CERTAIN).contains(&at(60, 30)),
            "{}",
            at(60, 30)
        );
        assert!(at(41, 30) >= HEAT_CERTAIN && at(79, 30) >= HEAT_CERTAIN);
        // One disc alone has no neck: its centre stays certain and nothing is uncertain.
        let one: Vec<u16> = (0..w * h)
            .map(|i| u16::from(inside(i % w, i / w, 41.0)))
            .collect();
        let mut heat = vec![0u8; w * h];
        heatmap(
            &HeatInput {
                labels: &one,
                ..inp
            },
            &SegmenterParams::default(),
            &mut HeatScratch::default(),
            &mut heat,
        );
        assert!(
            heat.iter()
                .all(|v| !(HEAT_UNCERTAIN..HEAT_CERTAIN).contains(v))
        );
    }

    /// A flat square segment of `side_px` pixels at 0.6 m (1 mm per pixel), centred.
    fn flat_square(w: usize, h: usize, side_px: usize) -> (Vec<u16>, Vec<P3>) {
        let (x0, y0) = ((w - side_px) / 2, (h - side_px) / 2);
        let inside =
            |x: usize, y: usize| (x0..x0 + side_px).contains(&x) && (y0..y0 + side_px).contains(&y);
        let labels = (0..w * h)
            .map(|i| u16::from(inside(i % w, i / w)))
            .collect();
        let pts = (0..w * h)
            .map(|i| {
                let (x, y) = (
                    (i % w) as f32 - w as f32 / 2.0,
                    (i / w) as f32 - h as f32 / 2.0,
                );
                [x * 0.001, y * 0.001, 0.6]
            })
            .collect();
        (labels, pts)
    }

    fn heat_of(w: usize, h: usize, labels: &[u16], pts: &[P3]) -> Vec<u8> {
        let zeros = vec![0u8; w * h];
        let mut heat = vec![0u8; w * h];
        heatmap(
            &HeatInput {
                w,
                h,
                pts,
                crease: &zeros,
                hole: &zeros,
                step: &zeros,
                labels,
                segments: 1,
                inv_focal: 1.0 / 600.0,
                table_normal: [0.0, 0.0, -1.0],
            },
            &SegmenterParams::default(),
            &mut HeatScratch::default(),
            &mut heat,
        );
        heat
    }

    /// A 12 cm square (a 2x2 pack of 6 cm boxes flush, nothing to see between them) is
    /// cut: its middle is uncertain, the cells on either side certain. A 6 cm square (one
    /// box) is not.
    #[test]
    fn a_segment_larger_than_one_object_is_cut_into_cells() {
        let (w, h) = (200, 200);
        let (labels, pts) = flat_square(w, h, 120);
        let heat = heat_of(w, h, &labels, &pts);
        let uncertain = |v: u8| (HEAT_UNCERTAIN..HEAT_CERTAIN).contains(&v);
        let at = |x: usize, y: usize| heat[y * w + x];
        assert!(
            uncertain(at(100, 70)) || uncertain(at(70, 100)),
            "{}",
            at(100, 70)
        );
        assert!(at(70, 70) >= HEAT_CERTAIN && at(130, 130) >= HEAT_CERTAIN);
        let (labels, pts) = flat_square(w, h, 60);
        let heat = heat_of(w, h, &labels, &pts);
        assert!(heat.iter().all(|&v| !uncertain(v)));
        assert!(heat[100 * w + 100] >= HEAT_CERTAIN);
    }
}
