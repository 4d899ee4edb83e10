//! The UOIS segmentation metrics: overlap and boundary precision / recall / F-measure with
//! Hungarian object matching, and the share of objects detected with F > 0.75.
//!
//! These are the numbers of the unseen-object instance segmentation papers (UOIS-Net,
//! UCN, MSMFormer, RISeg's Table 1), computed as UnseenObjectClustering's
//! `multilabel_metrics` computes them, so riseg's numbers can be set beside published ones.
//!
//! # Contract
//!
//! [`image_metrics`] takes two label maps of one image, row-major `&[u16]` of
//! `width · height` values: ground truth `G` and prediction `P`. Label `0` is background
//! (table, floor, unknown); every other value is one object, whatever its number (labels
//! need not be contiguous, and the prediction's numbers need not match the ground truth's).
//! It returns fractions in `[0, 1]`, never NaN. It is a pure function: same input, same
//! output, and renumbering the objects of either map does not change the result (see
//! "Ties" below for the one exception).
//!
//! # Formulas
//!
//! Write `g_i` for the pixels of ground-truth object `i`, `p_j` for predicted object `j`,
//! and `|·|` for a pixel count.
//!
//! * **Pair scores.** `tp_ij = |g_i ∩ p_j|`, `F_ij = 2·tp_ij / (|g_i| + |p_j|)` (the F of
//!   precision `tp/|p_j|` and recall `tp/|g_i|`; 0 when they do not overlap).
//! * **Matching.** A one-to-one assignment of `min(#G, #P)` pairs maximising `Σ F_ij`
//!   (Kuhn-Munkres). Pairs with `F = 0` can be matched: the reference does the same, and
//!   their boundary matches count below.
//! * **Overlap.** `P = Σ_matched tp / Σ_j |p_j|`, `R = Σ_matched tp / Σ_i |g_i|`,
//!   `F = 2PR / (P + R)` (0 when `P + R = 0`).
//! * **Boundary.** `∂m` is the one-pixel boundary of a binary mask `m`: pixel `x` is in
//!   `∂m` when `m(x)` differs from `m` at its right, lower or lower-right neighbour
//!   (neighbours outside the image are not compared, so the bottom-right pixel never is).
//!   `D(b)` dilates a boundary by the disk `{(dx, dy) : dx² + dy² ≤ r²}` with
//!   `r = ⌈0.003 · √(width² + height²)⌉` ([`boundary_radius_px`]: 3 px at 640×480).
//!   `bp_ij = |∂p_j ∩ D(∂g_i)|`, `br_ij = |∂g_i ∩ D(∂p_j)|`;
//!   `P = Σ_matched bp / Σ_j |∂p_j|`, `R = Σ_matched br / Σ_i |∂g_i|`, `F` as above.
//! * **Objects detected.** Matched pairs with `F_ij > 0.75` (compared exactly:
//!   `8·tp > 3·(|g_i| + |p_j|)`); the share is that count `/ #G`.
//! * **Empty maps** (the reference's edge cases): no predicted and some ground-truth
//!   objects: `P = 1, R = 0, F = 0` for overlap and boundary, share 0; predicted but no
//!   ground-truth objects: `P = 0, R = 1, F = 0`, share 0; neither: everything 1.
//!
//! # Where riseg pins down what the reference leaves open
//!
//! * **Ties.** Assignments with the same `Σ F` give different boundary numbers, and the
//!   reference takes whichever its solver reaches first (so its result depends on the
//!   label numbering). Here the matching maximises, in this order, `Σ F` (quantised to
//!   units of 2⁻²⁴ per pair, in exact integer arithmetic), then `Σ bp`, then `Σ br`. The
//!   result then depends on the numbering only if two matchings tie in all three sums yet
//!   differ in `Σ tp` or in detections, which takes exactly equal F values on different
//!   pairs.
//! * **No boundary pixels.** A prediction whose only object fills the whole image has
//!   `Σ_j |∂p_j| = 0`; the reference divides 0 by 0 (NaN). Here a boundary precision or
//!   recall over no boundary pixels is 1 (nothing claimed, nothing wrong), like the empty
//!   overlap cases.
//!
//! # Cost
//!
//! One pass over the pixels for the overlap counts and one per map for the boundaries;
//! dilation writes row spans of a precomputed disk around each boundary pixel into one
//! reused stamp buffer; only pairs whose dilated boundary boxes meet are compared. The
//! assignment is O(n³) in the object count, which is bounded by
//! [`MAX_OBJECT_PAIRS`].
//!
//! # Checked against
//!
//! `bench/metrics_reference.py`, an independent numpy/scipy implementation of the same
//! formulas, on 240 random label-map pairs (`host/tests/metrics_vs_python.rs`).

use std::collections::BTreeMap;

use pathfinding::prelude::{Matrix, kuhn_munkres};

/// Largest `#G · #P` accepted by [`image_metrics`]: the pair tables and the O(n³)
/// assignment grow with it. 6 objects against 65 535 fragments (every `u16` label) fit;
/// 1100 against 1000 do not.
pub const MAX_OBJECT_PAIRS: usize = 1 << 20;

/// Bits of the fixed-point `F_ij` the matching maximises (see the module docs, "Ties").
const F_SCALE_BITS: u32 = 24;

/// Why [`image_metrics`] could not compute the metrics.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum MetricsError {
    /// A label slice does not hold `width · height` values.
    #[error("{map} label map has {got} values, but a {width}x{height} image needs {expected}")]
    SizeMismatch {
        /// `"ground-truth"` or `"predicted"`.
        map: &'static str,
        /// Image width in pixels.
        width: usize,
        /// Image height in pixels.
        height: usize,
        /// `width · height`.
        expected: usize,
        /// The slice's length.
        got: usize,
    },
    /// `#G · #P` exceeds [`MAX_OBJECT_PAIRS`].
    #[error(
        "{gt} ground-truth objects against {pred} predicted objects: more pairs than the \
         {limit} the matching handles"
    )]
    TooManyObjects {
        /// Ground-truth object count.
        gt: usize,
        /// Predicted object count.
        pred: usize,
        /// [`MAX_OBJECT_PAIRS`].
        limit: usize,
    },
}

/// Precision, recall and F-measure, as fractions in `[0, 1]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prf {
    /// Share of what was predicted that is right.
    pub precision: f64,
    /// Share of the ground truth that was found.
    pub recall: f64,
    /// Harmonic mean `2PR / (P + R)`, 0 when both are 0.
    pub f_measure: f64,
}

impl Prf {
    /// The F-measure of `precision` and `recall`; 0 when both are 0.
    fn new(precision: f64, recall: f64) -> Self {
        let sum = precision + recall;
        let f_measure = if sum > 0.0 {
            2.0 * precision * recall / sum
        } else {
            0.0
        };
        Self {
            precision,
            recall,
            f_measure,
        }
    }

    const ONE: Self = Self {
        precision: 1.0,
        recall: 1.0,
        f_measure: 1.0,
    };
}

/// The metrics of one image (see the module docs for every formula).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageMetrics {
    /// Overlap (pixel) precision / recall / F of the matched objects.
    pub overlap: Prf,
    /// Boundary precision / recall / F of the matched objects.
    pub boundary: Prf,
    /// Number of ground-truth objects `#G`.
    pub objects_gt: usize,
    /// Number of predicted objects `#P`.
    pub objects_pred: usize,
    /// Matched pairs with overlap F > 0.75.
    pub objects_detected: usize,
    /// `objects_detected / objects_gt`, in `[0, 1]` (1 when both maps are empty).
    pub objects_detected_share: f64,
}

/// The dilation radius of the boundary measure: `⌈0.003 · √(width² + height²)⌉` pixels,
/// as the reference computes it (3 at 640×480, 1 for images up to 333 px across).
#[must_use]
pub fn boundary_radius_px(width: usize, height: usize) -> usize {
    let diagonal_px = ((width * width + height * height) as f64).sqrt();
    (0.003 * diagonal_px).ceil() as usize
}

/// Computes the UOIS metrics of `pred` against `gt`, two row-major label maps of one
/// `width × height` image (see the module docs for the formulas and edge cases).
///
/// # Errors
/// [`MetricsError::SizeMismatch`] if a slice does not hold `width · height` labels;
/// [`MetricsError::TooManyObjects`] if `#G · #P > MAX_OBJECT_PAIRS`.
///
/// # Examples
/// ```
/// use riseg::eval::metrics::image_metrics;
/// // 4×1 image: one ground-truth object of 2 px, predicted as 3 px.
/// let gt = [0, 1, 1, 0];
/// let pred = [0, 5, 5, 5];
/// let m = image_metrics(&gt, &pred, 4, 1)?;
/// assert_eq!(m.overlap.precision, 2.0 / 3.0);
/// assert_eq!(m.overlap.recall, 1.0);
/// assert_eq!(m.objects_detected, 1); // F = 2·2 / (2 + 3) = 0.8 > 0.75
/// # Ok::<(), riseg::eval::metrics::MetricsError>(())
/// ```
pub fn image_metrics(
    gt: &[u16],
    pred: &[u16],
    width: usize,
    height: usize,
) -> Result<ImageMetrics, MetricsError> {
    // Saturating: no slice holds usize::MAX labels, so an overflowing size is a mismatch.
    let expected = width.saturating_mul(height);
    for (map, labels) in [("ground-truth", gt), ("predicted", pred)] {
        if labels.len() != expected {
            return Err(MetricsError::SizeMismatch {
                map,
                width,
                height,
                expected,
                got: labels.len(),
            });
        }
    }
    let gt_ids = ObjectIds::of(gt);
    let pred_ids = ObjectIds::of(pred);
    let (n_gt, n_pred) = (gt_ids.count, pred_ids.count);
    if let Some(edge) = empty_case(n_gt, n_pred) {
        return Ok(edge);
    }
    if n_gt.saturating_mul(n_pred) > MAX_OBJECT_PAIRS {
        return Err(MetricsError::TooManyObjects {
            gt: n_gt,
            pred: n_pred,
            limit: MAX_OBJECT_PAIRS,
        });
    }

    let overlap = Contingency::count(gt, &gt_ids, pred, &pred_ids);
    let gt_boundary = Boundaries::extract(gt, &gt_ids, width, height);
    let pred_boundary = Boundaries::extract(pred, &pred_ids, width, height);
    let disk = Disk::new(boundary_radius_px(width, height));
    let pairs = BoundaryMatches::count(&gt_boundary, &pred_boundary, &disk, width, height);

    let gt_boundary_px = gt_boundary.total();
    let pred_boundary_px = pred_boundary.total();
    let matched = match_objects(&overlap, &pairs, gt_boundary_px, pred_boundary_px);

    let (mut tp_sum, mut bp_sum, mut br_sum, mut detected) = (0u64, 0u64, 0u64, 0usize);
    for &(i, j) in &matched {
        let tp = overlap.tp(i, j);
        tp_sum += tp;
        bp_sum += pairs.precision_hits(i, j);
        br_sum += pairs.recall_hits(i, j);
        // F_ij > 3/4  <=>  2·tp / (|g| + |p|) > 3/4  <=>  8·tp > 3·(|g| + |p|).
        if 8 * tp > 3 * (overlap.gt_size(i) + overlap.pred_size(j)) {
            detected += 1;
        }
    }
    Ok(ImageMetrics {
        overlap: Prf::new(
            ratio(tp_sum, overlap.pred_foreground()),
            ratio(tp_sum, overlap.gt_foreground()),
        ),
        boundary: Prf::new(
            ratio(bp_sum, pred_boundary_px),
            ratio(br_sum, gt_boundary_px),
        ),
        objects_gt: n_gt,
        objects_pred: n_pred,
        objects_detected: detected,
        objects_detected_share: detected as f64 / n_gt as f64,
    })
}

/// The reference's answers when either map has no object; `None` when both have some.
fn empty_case(n_gt: usize, n_pred: usize) -> Option<ImageMetrics> {
    let both = |prf: Prf, share: f64| ImageMetrics {
        overlap: prf,
        boundary: prf,
        objects_gt: n_gt,
        objects_pred: n_pred,
        objects_detected: 0,
        objects_detected_share: share,
    };
    match (n_gt, n_pred) {
        (0, 0) => Some(both(Prf::ONE, 1.0)),
        // Everything missed: nothing predicted is wrong (P = 1), nothing found (R = 0).
        (_, 0) => Some(both(Prf::new(1.0, 0.0), 0.0)),
        // Everything predicted is a false positive (P = 0); nothing to find (R = 1).
        (0, _) => Some(both(Prf::new(0.0, 1.0), 0.0)),
        _ => None,
    }
}

/// `hits / total`, or 1 for an empty total (nothing claimed, nothing wrong).
fn ratio(hits: u64, total: u64) -> f64 {
    if total == 0 {
        1.0
    } else {
        hits as f64 / total as f64
    }
}

/// Dense object numbering of one label map: label value -> `1..=count`, background and
/// absent labels -> 0, in increasing label order.
struct ObjectIds {
    dense_of: Box<[u16; 1 << 16]>,
    count: usize,
}

impl ObjectIds {
    fn of(labels: &[u16]) -> Self {
        let mut present = Box::new([false; 1 << 16]);
        for &label in labels {
            present[usize::from(label)] = true;
        }
        let mut dense_of = Box::new([0u16; 1 << 16]);
        let mut count = 0u16;
        // Label 0 is background; at most 65 535 objects, so `count` fits in u16.
        for (label, _) in present.iter().enumerate().skip(1).filter(|(_, p)| **p) {
            count += 1;
            dense_of[label] = count;
        }
        Self {
            dense_of,
            count: usize::from(count),
        }
    }

    /// Dense number of `label`: 0 for background, else `1..=count`.
    fn get(&self, label: u16) -> usize {
        usize::from(self.dense_of[usize::from(label)])
    }
}

/// Pixel counts of every (ground-truth, predicted) label pair, background included:
/// `cells[i · (n_pred + 1) + j]` counts pixels with dense gt number `i` and pred number
/// `j` (0 = background). Object `i` of the public formulas is dense number `i + 1`.
struct Contingency {
    cells: Vec<u64>,
    stride: usize,
    gt_sizes: Vec<u64>,
    pred_sizes: Vec<u64>,
}

impl Contingency {
    /// One pass over the pixels.
    fn count(gt: &[u16], gt_ids: &ObjectIds, pred: &[u16], pred_ids: &ObjectIds) -> Self {
        let stride = pred_ids.count + 1;
        let mut cells = vec![0u64; (gt_ids.count + 1) * stride];
        for (&g, &p) in gt.iter().zip(pred) {
            cells[gt_ids.get(g) * stride + pred_ids.get(p)] += 1;
        }
        let gt_sizes = cells
            .chunks_exact(stride)
            .map(|row| row.iter().sum())
            .collect();
        let pred_sizes = (0..stride)
            .map(|j| cells.iter().skip(j).step_by(stride).sum())
            .collect();
        Self {
            cells,
            stride,
            gt_sizes,
            pred_sizes,
        }
    }

    /// `tp_ij = |g_i ∩ p_j|` for object indices `i`, `j` (0-based).
    fn tp(&self, i: usize, j: usize) -> u64 {
        self.cells[(i + 1) * self.stride + j + 1]
    }

    /// `|g_i|`.
    fn gt_size(&self, i: usize) -> u64 {
        self.gt_sizes[i + 1]
    }

    /// `|p_j|`.
    fn pred_size(&self, j: usize) -> u64 {
        self.pred_sizes[j + 1]
    }

    /// `Σ_i |g_i|`: ground-truth pixels that are not background.
    fn gt_foreground(&self) -> u64 {
        self.gt_sizes.iter().skip(1).sum()
    }

    /// `Σ_j |p_j|`: predicted pixels that are not background.
    fn pred_foreground(&self) -> u64 {
        self.pred_sizes.iter().skip(1).sum()
    }
}

/// An axis-aligned pixel box, inclusive on all sides.
#[derive(Debug, Clone, Copy)]
struct PixelBox {
    x_min: usize,
    y_min: usize,
    x_max: usize,
    y_max: usize,
}

impl PixelBox {
    /// Whether `self` grown by `margin` on every side meets `other`.
    fn meets_within(&self, other: &Self, margin: usize) -> bool {
        self.x_min <= other.x_max + margin
            && other.x_min <= self.x_max + margin
            && self.y_min <= other.y_max + margin
            && other.y_min <= self.y_max + margin
    }
}

/// The boundary pixels `∂m` of every object of one label map, grouped by object.
struct Boundaries {
    /// Object `k`'s (0-based) boundary pixels, as row-major indices, are
    /// `pixels[start[k]..start[k + 1]]`, in increasing order.
    start: Vec<usize>,
    pixels: Vec<usize>,
    /// Bounding box of each object's boundary; `None` for an empty boundary.
    boxes: Vec<Option<PixelBox>>,
}

impl Boundaries {
    /// One pass over the pixels. A pixel whose right, lower or lower-right neighbour
    /// (where it exists) has another label is on the boundary of its own object and of
    /// each such neighbour's object: `[m(x) ≠ m(y)]` holds exactly for the masks `m` of
    /// those labels. Background (0) is not an object and gets no boundary.
    fn extract(labels: &[u16], ids: &ObjectIds, width: usize, height: usize) -> Self {
        // (object index, pixel index), in pixel order.
        let mut hits: Vec<(usize, usize)> = Vec::new();
        let mut on_boundary = |index: usize, own: u16, neighbours: &[u16]| {
            // Slow path, for the few pixels with a differing neighbour: `own` and every
            // distinct neighbour label, background excepted.
            let mut seen = [own; 4];
            let mut n_seen = 1;
            for &label in neighbours {
                if !seen[..n_seen].contains(&label) {
                    seen[n_seen] = label;
                    n_seen += 1;
                }
            }
            for &label in seen[..n_seen].iter().filter(|&&l| l != 0) {
                hits.push((ids.get(label) - 1, index));
            }
        };
        for y in 0..height {
            let row = &labels[y * width..(y + 1) * width];
            let start = y * width;
            if y + 1 < height {
                let below = &labels[(y + 1) * width..(y + 2) * width];
                // All three neighbours exist left of the last column.
                for (x, (pair, pair_below)) in row.windows(2).zip(below.windows(2)).enumerate() {
                    let (own, right, down, down_right) =
                        (pair[0], pair[1], pair_below[0], pair_below[1]);
                    if own != right || own != down || own != down_right {
                        on_boundary(start + x, own, &[right, down, down_right]);
                    }
                }
                // Last column: only the lower neighbour.
                let x = width - 1;
                if row[x] != below[x] {
                    on_boundary(start + x, row[x], &[below[x]]);
                }
            } else {
                // Last row: only the right neighbour.
                for (x, pair) in row.windows(2).enumerate() {
                    if pair[0] != pair[1] {
                        on_boundary(start + x, pair[0], &[pair[1]]);
                    }
                }
            }
        }

        // Counting sort by object, keeping pixel order within each object.
        let mut start = vec![0usize; ids.count + 1];
        for &(object, _) in &hits {
            start[object + 1] += 1;
        }
        for k in 1..start.len() {
            start[k] += start[k - 1];
        }
        let mut next = start[..ids.count].to_vec();
        let mut pixels = vec![0usize; hits.len()];
        for &(object, index) in &hits {
            pixels[next[object]] = index;
            next[object] += 1;
        }

        let boxes = (0..ids.count)
            .map(|object| {
                let own = &pixels[start[object]..start[object + 1]];
                own.iter().fold(None, |acc: Option<PixelBox>, &p| {
                    let (x, y) = (p % width, p / width);
                    Some(match acc {
                        None => PixelBox {
                            x_min: x,
                            y_min: y,
                            x_max: x,
                            y_max: y,
                        },
                        Some(b) => PixelBox {
                            x_min: b.x_min.min(x),
                            y_min: b.y_min.min(y),
                            x_max: b.x_max.max(x),
                            y_max: b.y_max.max(y),
                        },
                    })
                })
            })
            .collect();
        Self {
            start,
            pixels,
            boxes,
        }
    }

    /// `∂` of object `k` (0-based).
    fn of(&self, object: usize) -> &[usize] {
        &self.pixels[self.start[object]..self.start[object + 1]]
    }

    fn len(&self) -> usize {
        self.boxes.len()
    }

    /// `Σ_k |∂m_k|`.
    fn total(&self) -> u64 {
        self.pixels.len() as u64
    }
}

/// The dilation disk `{(dx, dy) : dx² + dy² ≤ r²}` as one horizontal span per row.
struct Disk {
    radius_px: usize,
    /// `half_width_px[dy + r]` = largest `dx` with `dx² + dy² ≤ r²`.
    half_width_px: Vec<usize>,
}

impl Disk {
    fn new(radius_px: usize) -> Self {
        let r2 = radius_px * radius_px;
        let half_width_px = (0..=2 * radius_px)
            .map(|k| {
                let dy = k.abs_diff(radius_px);
                let room = r2 - dy * dy;
                (0..=radius_px)
                    .take_while(|dx| dx * dx <= room)
                    .last()
                    .unwrap_or(0)
            })
            .collect();
        Self {
            radius_px,
            half_width_px,
        }
    }

    /// Writes `stamp` into `mark` over the dilation `D(pixels)`.
    fn stamp(&self, pixels: &[usize], width: usize, height: usize, mark: &mut [u32], stamp: u32) {
        for &p in pixels {
            let (x, y) = (p % width, p / width);
            for (k, &half) in self.half_width_px.iter().enumerate() {
                let Some(yy) = (y + k).checked_sub(self.radius_px) else {
                    continue;
                };
                if yy >= height {
                    break;
                }
                let row = yy * width;
                let x0 = x.saturating_sub(half);
                let x1 = (x + half).min(width - 1);
                mark[row + x0..=row + x1].fill(stamp);
            }
        }
    }
}

/// `bp_ij = |∂p_j ∩ D(∂g_i)|` and `br_ij = |∂g_i ∩ D(∂p_j)|` for every pair.
struct BoundaryMatches {
    n_pred: usize,
    /// Row-major `n_gt × n_pred`.
    bp: Vec<u64>,
    br: Vec<u64>,
}

impl BoundaryMatches {
    fn count(gt: &Boundaries, pred: &Boundaries, disk: &Disk, width: usize, height: usize) -> Self {
        let (n_gt, n_pred) = (gt.len(), pred.len());
        let mut bp = vec![0u64; n_gt * n_pred];
        let mut br = vec![0u64; n_gt * n_pred];
        // One buffer for every dilation: `mark[x] == stamp` means "x is in the current
        // dilated boundary", so no clearing between objects.
        let mut mark = vec![0u32; width * height];
        let mut stamp = 0u32;
        // Pixels of `b` within D(∂a) need the boxes to meet within the radius.
        let margin = disk.radius_px;
        let mut dilate_and_count =
            |dilated: &Boundaries,
             a: usize,
             tested: &Boundaries,
             out: &mut dyn FnMut(usize, u64)| {
                let Some(a_box) = dilated.boxes[a] else {
                    return;
                };
                stamp += 1;
                disk.stamp(dilated.of(a), width, height, &mut mark, stamp);
                for b in 0..tested.len() {
                    if tested.boxes[b].is_some_and(|b_box| a_box.meets_within(&b_box, margin)) {
                        let hits = tested.of(b).iter().filter(|&&p| mark[p] == stamp).count();
                        out(b, hits as u64);
                    }
                }
            };
        for i in 0..n_gt {
            dilate_and_count(gt, i, pred, &mut |j, hits| bp[i * n_pred + j] = hits);
        }
        for j in 0..n_pred {
            dilate_and_count(pred, j, gt, &mut |i, hits| br[i * n_pred + j] = hits);
        }
        Self { n_pred, bp, br }
    }

    /// `bp_ij`: predicted boundary pixels of `j` near the boundary of gt object `i`.
    fn precision_hits(&self, i: usize, j: usize) -> u64 {
        self.bp[i * self.n_pred + j]
    }

    /// `br_ij`: ground-truth boundary pixels of `i` near the boundary of `j`.
    fn recall_hits(&self, i: usize, j: usize) -> u64 {
        self.br[i * self.n_pred + j]
    }
}

/// The optimal one-to-one matching as `(gt object, pred object)` pairs, `min(#G, #P)`
/// of them.
///
/// Each pair's weight packs the lexicographic objective (`F`, then `bp`, then `br`) into
/// one integer: `((F_q · (B_p + 1)) + bp) · (B_g + 1) + br`, where `F_q = ⌊F · 2²⁴⌋` and
/// `B_p`, `B_g` are the total boundary pixel counts. Any matching's `Σ bp ≤ B_p` and
/// `Σ br ≤ B_g`, so a larger `Σ F_q` always wins, and `Σ bp`, `Σ br` only break ties.
fn match_objects(
    overlap: &Contingency,
    pairs: &BoundaryMatches,
    gt_boundary_px: u64,
    pred_boundary_px: u64,
) -> Vec<(usize, usize)> {
    let n_gt = overlap.gt_sizes.len() - 1;
    let n_pred = overlap.pred_sizes.len() - 1;
    // At most 2^24 · (4·pixels + 1)^2: below 2^100 for images under 2^37 pixels, and
    // kuhn_munkres sums at most 2^10 of them (MAX_OBJECT_PAIRS), far from i128::MAX.
    let weight = |i: usize, j: usize| -> i128 {
        let scaled_f = (i128::from(2 * overlap.tp(i, j)) << F_SCALE_BITS)
            / i128::from(overlap.gt_size(i) + overlap.pred_size(j));
        let with_bp =
            scaled_f * (i128::from(pred_boundary_px) + 1) + i128::from(pairs.precision_hits(i, j));
        with_bp * (i128::from(gt_boundary_px) + 1) + i128::from(pairs.recall_hits(i, j))
    };
    // kuhn_munkres assigns every row, so the smaller side goes on the rows.
    if n_gt <= n_pred {
        let weights = Matrix::from_fn(n_gt, n_pred, |(i, j)| weight(i, j));
        let (_, col_of_row) = kuhn_munkres(&weights);
        col_of_row.into_iter().enumerate().collect()
    } else {
        let weights = Matrix::from_fn(n_pred, n_gt, |(j, i)| weight(i, j));
        let (_, col_of_row) = kuhn_munkres(&weights);
        col_of_row
            .into_iter()
            .enumerate()
            .map(|(j, i)| (i, j))
            .collect()
    }
}

/// The mean metrics of the images of one push index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MetricsRow {
    /// Push index: frame `t` shows the scene after `t` pushes (0 = before any push).
    pub push: u32,
    /// Images averaged.
    pub images: usize,
    /// Mean of the per-image overlap P, R and F (each averaged on its own).
    pub overlap: Prf,
    /// Mean of the per-image boundary P, R and F.
    pub boundary: Prf,
    /// Mean of the per-image share of objects detected with F > 0.75, in `[0, 1]`.
    pub objects_detected_share: f64,
}

/// Averages [`ImageMetrics`] over the images of each push index, as the UOIS papers
/// average over a test set: every image weighs the same, whatever its object count.
#[derive(Debug, Clone, Default)]
pub struct PushAverages {
    sums: BTreeMap<u32, Sums>,
}

#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    images: usize,
    values: [f64; 7],
}

impl PushAverages {
    /// An empty accumulator.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one image's metrics to the mean of push index `push`.
    pub fn add(&mut self, push: u32, metrics: &ImageMetrics) {
        let sums = self.sums.entry(push).or_default();
        sums.images += 1;
        let values = [
            metrics.overlap.precision,
            metrics.overlap.recall,
            metrics.overlap.f_measure,
            metrics.boundary.precision,
            metrics.boundary.recall,
            metrics.boundary.f_measure,
            metrics.objects_detected_share,
        ];
        for (sum, value) in sums.values.iter_mut().zip(values) {
            *sum += value;
        }
    }

    /// One row per push index seen, in increasing push order.
    #[must_use]
    pub fn rows(&self) -> Vec<MetricsRow> {
        self.sums
            .iter()
            .map(|(&push, sums)| {
                let n = sums.images as f64;
                let [op, or, of, bp, br, bf, share] = sums.values.map(|v| v / n);
                MetricsRow {
                    push,
                    images: sums.images,
                    overlap: Prf {
                        precision: op,
                        recall: or,
                        f_measure: of,
                    },
                    boundary: Prf {
                        precision: bp,
                        recall: br,
                        f_measure: bf,
                    },
                    objects_detected_share: share,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A label map from rows of literals: `labels![0, 1; 2, 2]` is 2×2.
    /// Returns `(labels, width, height)`.
    macro_rules! labels {
        ($($($v:expr),+);+ $(;)?) => {{
            let rows: Vec<Vec<u16>> = vec![$(vec![$($v),+]),+];
            let width = rows[0].len();
            assert!(rows.iter().all(|r| r.len() == width), "ragged label rows");
            (rows.concat(), width, rows.len())
        }};
    }

    /// A `row.len() × height` map whose every row is `row` (vertical stripes). In such a
    /// map the boundary of label `l` is every full column `x < width − 1` where
    /// `row[x] ≠ row[x + 1]` and `l` is one of the two (the down neighbour is equal, the
    /// lower-right one equals the right one).
    fn stripes(row: &[u16], height: usize) -> Vec<u16> {
        row.repeat(height)
    }

    fn metrics(gt: &[u16], pred: &[u16], width: usize, height: usize) -> ImageMetrics {
        image_metrics(gt, pred, width, height).unwrap()
    }

    fn assert_prf(got: Prf, precision: f64, recall: f64, f_measure: f64) {
        let want = Prf {
            precision,
            recall,
            f_measure,
        };
        for (g, w) in [
            (got.precision, precision),
            (got.recall, recall),
            (got.f_measure, f_measure),
        ] {
            assert!((g - w).abs() < 1e-12, "got {got:?}, want {want:?}");
        }
    }

    #[test]
    fn boundary_radius_follows_the_image_diagonal() {
        // 0.003 · 800 = 2.4 -> 3; 0.003 · √80 = 0.027 -> 1; 0.003 · √(1280² + 720²) =
        // 0.003 · 1468.6 = 4.41 -> 5; 0.003 · 1000 = 3 exactly -> 3.
        assert_eq!(boundary_radius_px(640, 480), 3);
        assert_eq!(boundary_radius_px(8, 4), 1);
        assert_eq!(boundary_radius_px(1280, 720), 5);
        assert_eq!(boundary_radius_px(600, 800), 3);
    }

    #[test]
    fn disk_spans_are_the_integer_disk() {
        // r = 3: rows dy = ±3 hold dx ∈ [0, 0]; ±2: 2² + 2² = 8 ≤ 9, 3² + 2² > 9 -> 2;
        // ±1: 2² + 1 = 5, 3² + 1 = 10 > 9 -> 2; 0 -> 3. 1+5+5+7+5+5+1 = 29 pixels.
        assert_eq!(Disk::new(3).half_width_px, [0, 2, 2, 3, 2, 2, 0]);
        assert_eq!(Disk::new(1).half_width_px, [0, 1, 0]);
    }

    #[test]
    fn single_pixel_object_boundary() {
        // 3×3 with one object pixel at the centre (1, 1). The pixels whose right, lower or
        // lower-right neighbour differs from them: (0,0) via lower-right, (1,0) via lower,
        // (0,1) via right, (1,1) itself via right/lower. Index = y·3 + x: 0, 1, 3, 4.
        let (map, w, h) = labels![0, 0, 0; 0, 7, 0; 0, 0, 0];
        let b = Boundaries::extract(&map, &ObjectIds::of(&map), w, h);
        assert_eq!(b.of(0), [0, 1, 3, 4]);
        assert_eq!(b.total(), 4);
    }

    #[test]
    fn a_pixel_can_be_on_several_boundaries() {
        // Pixel (0,0) has label 1, its right neighbour 2, its lower neighbour 3: it is on
        // the boundary of all three objects. Pixels in the last row compare only to the
        // right, those in the last column only downwards; (1,1) is never compared.
        let (map, w, h) = labels![1, 2; 3, 3];
        let b = Boundaries::extract(&map, &ObjectIds::of(&map), w, h);
        assert_eq!(b.of(0), [0]); // label 1
        assert_eq!(b.of(1), [0, 1]); // label 2: (0,0), and (1,0) whose lower neighbour is 3
        assert_eq!(b.of(2), [0, 1]); // label 3: the same two pixels
    }

    #[test]
    fn perfect_prediction_scores_one_whatever_the_label_numbers() {
        // Objects of 2 and 3 columns; predicted with other ids in the other order.
        let row_gt = [0, 1, 1, 0, 2, 2, 2, 0];
        let row_pred = [0, 9, 9, 0, 4, 4, 4, 0];
        let m = metrics(&stripes(&row_gt, 4), &stripes(&row_pred, 4), 8, 4);
        assert_prf(m.overlap, 1.0, 1.0, 1.0);
        assert_prf(m.boundary, 1.0, 1.0, 1.0);
        assert_eq!(
            (m.objects_gt, m.objects_pred, m.objects_detected),
            (2, 2, 2)
        );
        assert_eq!(m.objects_detected_share, 1.0);
    }

    #[test]
    fn merged_pair() {
        // 8×4 stripes. GT: A = columns 2-3 (8 px), B = columns 4-5 (8 px).
        // Pred: one object M = columns 2-5 (16 px).
        //   tp(A,M) = tp(B,M) = 8; F = 2·8 / (8 + 16) = 2/3 each: one is matched.
        //   Overlap P = 8 / 16 = 0.5, R = 8 / 16 = 0.5, F = 0.5.
        // Boundaries (full columns of 4 px): ∂A = {1, 3}, ∂B = {3, 5} -> 16 px;
        //   ∂M = {1, 5} -> 8 px. r = ⌈0.003·√80⌉ = 1, so a dilation adds ±1 column.
        //   Matched with A: bp = |∂M ∩ D∂A = {0..4}| = column 1 = 4 px;
        //                   br = |∂A ∩ D∂M = {0,1,2,4,5,6}| = column 1 = 4 px.
        //   (With B, by symmetry, also 4 and 4: the tie does not change the result.)
        //   Boundary P = 4 / 8 = 0.5, R = 4 / 16 = 0.25, F = 2·0.5·0.25 / 0.75 = 1/3.
        // Objects: F = 2/3 ≤ 0.75 -> 0 detected, share 0 / 2.
        let gt = stripes(&[0, 0, 1, 1, 2, 2, 0, 0], 4);
        let pred = stripes(&[0, 0, 5, 5, 5, 5, 0, 0], 4);
        let m = metrics(&gt, &pred, 8, 4);
        assert_prf(m.overlap, 0.5, 0.5, 0.5);
        assert_prf(m.boundary, 0.5, 0.25, 1.0 / 3.0);
        assert_eq!(
            (m.objects_gt, m.objects_pred, m.objects_detected),
            (2, 1, 0)
        );
        assert_eq!(m.objects_detected_share, 0.0);
    }

    #[test]
    fn split_object() {
        // 8×4 stripes. GT: G = columns 2-5 (16 px). Pred: S = columns 2-3, T = 4-5 (8 px).
        //   tp = 8 each, F = 2·8 / (16 + 8) = 2/3 each; one is matched.
        //   Overlap P = 8 / 16 (both halves are predicted foreground) = 0.5,
        //   R = 8 / 16 = 0.5, F = 0.5.
        // Boundaries: ∂G = {1, 5} -> 8 px; ∂S = {1, 3}, ∂T = {3, 5} -> 16 px; r = 1.
        //   Matched with S: bp = |∂S ∩ D∂G = {0,1,2,4,5,6}| = column 1 = 4 px;
        //                   br = |∂G ∩ D∂S = {0..4}| = column 1 = 4 px (T: the same).
        //   Boundary P = 4 / 16 = 0.25, R = 4 / 8 = 0.5, F = 1/3.
        // Objects: 0 of 1 detected.
        let gt = stripes(&[0, 0, 1, 1, 1, 1, 0, 0], 4);
        let pred = stripes(&[0, 0, 3, 3, 4, 4, 0, 0], 4);
        let m = metrics(&gt, &pred, 8, 4);
        assert_prf(m.overlap, 0.5, 0.5, 0.5);
        assert_prf(m.boundary, 0.25, 0.5, 1.0 / 3.0);
        assert_eq!(
            (m.objects_gt, m.objects_pred, m.objects_detected),
            (1, 2, 0)
        );
        assert_eq!(m.objects_detected_share, 0.0);
    }

    #[test]
    fn empty_prediction() {
        // Some ground truth, nothing predicted: everything missed, nothing wrongly
        // claimed: P = 1, R = 0, F = 0 for overlap and boundary; 0 of 2 detected.
        let gt = stripes(&[0, 1, 1, 0, 2, 2, 0, 0], 4);
        let m = metrics(&gt, &[0; 32], 8, 4);
        assert_prf(m.overlap, 1.0, 0.0, 0.0);
        assert_prf(m.boundary, 1.0, 0.0, 0.0);
        assert_eq!(
            (m.objects_gt, m.objects_pred, m.objects_detected),
            (2, 0, 0)
        );
        assert_eq!(m.objects_detected_share, 0.0);
    }

    #[test]
    fn empty_ground_truth() {
        // Nothing to find, something predicted: all of it wrong (P = 0), nothing missed
        // (R = 1), F = 0; share 0 (the reference's convention).
        let pred = stripes(&[0, 1, 1, 0, 0, 0, 0, 0], 4);
        let m = metrics(&[0; 32], &pred, 8, 4);
        assert_prf(m.overlap, 0.0, 1.0, 0.0);
        assert_prf(m.boundary, 0.0, 1.0, 0.0);
        assert_eq!(
            (m.objects_gt, m.objects_pred, m.objects_detected),
            (0, 1, 0)
        );
        assert_eq!(m.objects_detected_share, 0.0);
    }

    #[test]
    fn both_empty() {
        // Correctly predicted nothing: every number is 1, including the share.
        let m = metrics(&[0; 32], &[0; 32], 8, 4);
        assert_prf(m.overlap, 1.0, 1.0, 1.0);
        assert_prf(m.boundary, 1.0, 1.0, 1.0);
        assert_eq!(
            (m.objects_gt, m.objects_pred, m.objects_detected),
            (0, 0, 0)
        );
        assert_eq!(m.objects_detected_share, 1.0);
    }

    #[test]
    fn detection_needs_f_strictly_above_three_quarters() {
        // 8×1. GT: columns 0-3 (4 px). Pred: columns 1-4 (4 px): tp = 3,
        // F = 2·3 / (4 + 4) = 0.75 exactly: not detected (the test is F > 0.75).
        let gt = [1, 1, 1, 1, 0, 0, 0, 0];
        let m = metrics(&gt, &[0, 1, 1, 1, 1, 0, 0, 0], 8, 1);
        assert_eq!(m.objects_detected, 0);
        // Pred: columns 0-4 (5 px): tp = 4, F = 8 / 9 = 0.889: detected.
        let m = metrics(&gt, &[1, 1, 1, 1, 1, 0, 0, 0], 8, 1);
        assert_eq!(m.objects_detected, 1);
        assert_eq!(m.objects_detected_share, 1.0);
    }

    #[test]
    fn a_prediction_filling_the_image_has_no_boundary() {
        // Pred: one object over all 8×4 pixels: no boundary pixel, so boundary precision
        // is over nothing: 1 (the reference gives NaN). GT: columns 2-3, ∂ = {1, 3},
        // 8 px; the prediction has no boundary to dilate, so boundary R = 0, F = 0.
        // Overlap: tp = 8, P = 8 / 32 = 0.25, R = 1, F = 2·0.25 / 1.25 = 0.4.
        let gt = stripes(&[0, 0, 1, 1, 0, 0, 0, 0], 4);
        let m = metrics(&gt, &[3; 32], 8, 4);
        assert_prf(m.overlap, 0.25, 1.0, 0.4);
        assert_prf(m.boundary, 1.0, 0.0, 0.0);
    }

    #[test]
    fn zero_overlap_ties_go_to_the_nearer_boundary_whatever_the_numbering() {
        // 12×4 stripes. GT: A = columns 1-2, B = columns 5-6, C = columns 9-10.
        // Pred: D = columns 1-2 (= A), E = column 8 (touches nothing, next to C).
        // E has F = 0 with every GT object, so matching it to B or C gives the same ΣF;
        // the tie goes to C, whose boundary (columns 8, 10) lies within 1 px of E's
        // (columns 7, 8): bp = 8 (both columns), br = 4 (column 8).
        // ∂D = {0, 2} and ∂A = {0, 2} match fully: bp = br = 8.
        // Boundary P = (8 + 8) / (8 + 8) = 1; R = (8 + 4) / 24 = 0.5.
        let gt_row = [0, 1, 1, 0, 0, 2, 2, 0, 0, 3, 3, 0];
        let pred_row = [0, 1, 1, 0, 0, 0, 0, 0, 2, 0, 0, 0];
        let (gt, pred) = (stripes(&gt_row, 4), stripes(&pred_row, 4));
        let m = metrics(&gt, &pred, 12, 4);
        assert_prf(m.boundary, 1.0, 0.5, 2.0 / 3.0);
        // Renumbering either map changes nothing.
        for (a, b, c) in [(3, 2, 1), (2, 3, 1), (40000, 7, 9)] {
            let renumber = |l: u16| [0, a, b, c][usize::from(l)];
            let gt2: Vec<u16> = gt.iter().map(|&l| renumber(l)).collect();
            let pred2: Vec<u16> = pred.iter().map(|&l| renumber(l)).collect();
            assert_eq!(metrics(&gt2, &pred, 12, 4), m);
            assert_eq!(metrics(&gt, &pred2, 12, 4), m);
        }
    }

    #[test]
    fn wrong_sizes_are_errors() {
        let err = image_metrics(&[0; 6], &[0; 5], 3, 2).unwrap_err();
        assert_eq!(
            err,
            MetricsError::SizeMismatch {
                map: "predicted",
                width: 3,
                height: 2,
                expected: 6,
                got: 5
            }
        );
        assert!(err.to_string().contains("predicted label map has 5 values"));
    }

    /// Found by the `image_metrics` fuzz target: `width · height` overflowed (a panic in
    /// debug builds; in release a wrapped product of 0 accepted empty maps as a 2³²×2³²
    /// image).
    #[test]
    fn a_size_whose_pixel_count_overflows_is_a_mismatch() {
        for (width, height) in [(usize::MAX, 2), (1 << 32, 1 << 32)] {
            let err = image_metrics(&[], &[], width, height).unwrap_err();
            assert!(
                matches!(err, MetricsError::SizeMismatch { got: 0, .. }),
                "{width}x{height}: {err:?}"
            );
        }
    }

    #[test]
    fn too_many_object_pairs_is_an_error() {
        // 1100 GT objects × 1000 predicted objects > 2^20 pairs.
        let gt: Vec<u16> = (1..=1100).collect();
        let pred: Vec<u16> = (0..1100).map(|i| (i % 1000) + 1).collect();
        let err = image_metrics(&gt, &pred, 1100, 1).unwrap_err();
        assert!(matches!(
            err,
            MetricsError::TooManyObjects {
                gt: 1100,
                pred: 1000,
                ..
            }
        ));
    }

    #[test]
    fn push_averages_weigh_every_image_the_same() {
        let gt = stripes(&[0, 0, 1, 1, 2, 2, 0, 0], 4);
        let perfect = metrics(&gt, &gt, 8, 4);
        let merged = metrics(&gt, &stripes(&[0, 0, 5, 5, 5, 5, 0, 0], 4), 8, 4);
        let mut averages = PushAverages::new();
        averages.add(1, &merged);
        averages.add(0, &perfect);
        averages.add(0, &merged);
        let rows = averages.rows();
        assert_eq!(rows.len(), 2);
        assert_eq!((rows[0].push, rows[0].images), (0, 2));
        assert_eq!((rows[1].push, rows[1].images), (1, 1));
        // Push 0: mean of perfect (1) and merged (0.5, 0.5, 0.5 / 0.5, 0.25, 1/3 / 0).
        assert_prf(rows[0].overlap, 0.75, 0.75, 0.75);
        assert_prf(rows[0].boundary, 0.75, 0.625, (1.0 + 1.0 / 3.0) / 2.0);
        assert_eq!(rows[0].objects_detected_share, 0.5);
        assert_eq!(rows[1].overlap, merged.overlap);
    }
}
