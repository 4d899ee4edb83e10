"""A plain numpy/scipy reference of one riseg UpdateMask step, and its per-stage timing.

It mirrors riseg-core's `pipeline::update_mask` (core/src/frames.rs, group.rs, mask.rs):

- frames:   CreateFrames. Stratified seeded sampling of `n` labelled pixels with valid
            depth, tracking by the flow with bilinear depth at t+1 (dropped on a depth
            edge), one frame per tracked sample (second point the farthest same-label
            sample within d_c, third the one spanning the largest triangle), rigidity check.
- twists:   CalcBFIFs. The spatial twist log(T_t1 T_t^-1) of each frame, in a space
            frame at the centroid of the samples.
- grouping: GroupBFIFs. Binned Gaussian KDE of pairwise twist distances split at its
            first valley, mask prior, posterior links inside one segment, quick shift
            along link density, connected components, small groups dropped.
- mask:     CorrectMask. Forward splat with depth ordering, intersection with the static
            mask, 4-connected components with small-segment merging, seeded region
            growing under the rigid-motion flow residual, relabelling, final cleanup.

It is written the way a Python robotics engineer would write it: vectorised numpy,
scipy.spatial for neighbours and rotations, scipy.ndimage for labelling, no compiled code
of its own. It is not bit-identical to riseg (numpy's generator draws the samples, and
region growing resolves ties between regions that reach a pixel in the same wave in its
own order), but it makes the same decisions.

Inputs come from `cargo run --release -p riseg --example dump_synthetic_step -- DIR`.
Run: `python3 bench/update_mask_reference.py DIR [--repeat 7] [--json FILE]`.
Each stage is timed on the outputs of one full step, as the criterion bench does; a figure
is the median of `--repeat` runs after one warm-up, on one thread.
"""

import os

# One thread, like the criterion bench; BLAS reads these when numpy is first imported.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402
from scipy import ndimage  # noqa: E402
from scipy.sparse import coo_matrix  # noqa: E402
from scipy.sparse.csgraph import connected_components  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402
from scipy.spatial.distance import pdist  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

# Constants riseg-core fixes in code rather than in Config.
KDE_BINS = 120  # group.rs
FAR_UNIFORM_SHARE = 1e-3  # group.rs: uniform floor of the far-pair likelihood
MIN_FRAME_SIN = 1e-3  # se3.rs: collinearity limit of a frame's triangle
SERIES_BELOW_RAD = 0.3  # se3.rs: series form of the SE(3) coefficients below this angle
MIN_SEEDS = 3  # mask.rs: seed pixels a group needs to count in a segment
NO_GROUP = -1
SIDES = ((0, 1), (0, 2), (1, 2))  # point pairs of a frame's triangle
HOLE = -2  # growth decision of a pixel with no observation: any region may pass


@dataclass(frozen=True)
class Config:
    """The fields of riseg's `Config` that one step reads (dumped from `Config::PAPER`)."""

    frame_samples: int
    frame_max_side_m: float
    frame_min_side_m: float
    frame_min_sin: float
    depth_edge_m: float
    frame_rigid_tol_m: float
    length_scale_m: float
    static_below_m: float
    kde_range_m: float
    kde_bandwidth_m: float
    link_posterior: float
    min_group_frames: int
    min_segment_px: int
    grow_tol_px: float
    seed: int


@dataclass(frozen=True)
class Step:
    """One step's observations; images are (H, W), flow (H, W, 2)."""

    labels_t: np.ndarray  # accumulated mask at t
    depth_t: np.ndarray
    depth_t1: np.ndarray
    flow: np.ndarray
    static_t1: np.ndarray  # static mask at t+1
    fx: float
    fy: float
    cx: float
    cy: float

    def back_project(self, u, v, z):
        """Camera-frame points (..., 3) seen at pixels (u, v) with depth z."""
        return np.stack(((u - self.cx) * z / self.fx, (v - self.cy) * z / self.fy, z), axis=-1)


@dataclass(frozen=True)
class Frames:
    """CreateFrames' output: m frames of three points each."""

    p_t: np.ndarray  # (m, 3, 3) points at t, camera frame
    p_t1: np.ndarray  # (m, 3, 3) points at t+1
    px_t1: np.ndarray  # (m, 3, 2) tracked pixels at t+1
    label: np.ndarray  # (m,) accumulated-mask label
    space_origin: np.ndarray  # (3,) centroid of the samples at t
    sampled: int


@dataclass(frozen=True)
class Grouping:
    """GroupBFIFs' output."""

    frame_group: np.ndarray  # (m,) group id or NO_GROUP
    twist: np.ndarray  # (groups, 6) mean twist [w, v] of each group


def round_half_away(x):
    """Rounds like C's `round` (riseg's libm), not numpy's half-to-even."""
    return np.copysign(np.floor(np.abs(x) + 0.5), x)


def valid_depth(z):
    return np.isfinite(z) & (z > 0)


def first_per_run(keys):
    """Mask of the first element of each run of equal values in a sorted array."""
    return np.r_[True, keys[1:] != keys[:-1]]


# --- frames -----------------------------------------------------------------------------


def bilinear_depth(depth, u, v, edge_m):
    """Depth at sub-pixel (u, v) from its four neighbours; NaN outside the image, on a
    missing reading, or where the four span more than `edge_m` (a depth edge)."""
    h, w = depth.shape
    ok = np.isfinite(u) & np.isfinite(v) & (u >= 0) & (v >= 0)
    x0 = np.floor(np.where(ok, u, 0))
    y0 = np.floor(np.where(ok, v, 0))
    fx, fy = u - x0, v - y0
    # At the last row/column the far neighbour has zero weight.
    x1, y1 = x0 + (fx > 0), y0 + (fy > 0)
    ok &= (x1 < w) & (y1 < h)
    x0, x1 = (np.where(ok, x, 0).astype(np.intp) for x in (x0, x1))
    y0, y1 = (np.where(ok, y, 0).astype(np.intp) for y in (y0, y1))
    z00, z10, z01, z11 = corners = np.stack(
        (depth[y0, x0], depth[y0, x1], depth[y1, x0], depth[y1, x1])
    )
    ok &= valid_depth(corners).all(axis=0)
    ok &= corners.max(axis=0) - corners.min(axis=0) <= edge_m
    top = z00 + (z10 - z00) * fx
    bottom = z01 + (z11 - z01) * fx
    return np.where(ok, top + (bottom - top) * fy, np.nan)


def best_per_origin(origin, score, other, samples):
    """For pairs (origin, other) with a score, the `other` of each origin's best-scoring
    pair (ties to the smallest `other`, -1 if the origin has no pair), and that score."""
    best_score = np.full(samples, -np.inf)
    np.maximum.at(best_score, origin, score)
    best_other = np.full(samples, samples)
    top = score == best_score[origin]
    np.minimum.at(best_other, origin[top], other[top])
    return np.where(best_other < samples, best_other, -1), best_score


def side_lengths(triangles):
    """Lengths (3, m) of the sides 01, 02 and 12 of triangles (m, 3, 3)."""
    return np.stack(
        [np.linalg.norm(triangles[:, p] - triangles[:, q], axis=1) for p, q in SIDES]
    )


def create_frames(step, cfg):
    w = step.labels_t.shape[1]
    labels = step.labels_t.ravel()
    depth = step.depth_t.ravel()

    # Stratified sampling: eligible pixels in row-major order, one draw per equal run.
    eligible = np.flatnonzero((labels != 0) & valid_depth(depth))
    want = min(cfg.frame_samples, eligible.size)
    bounds = np.arange(want + 1) * eligible.size // want
    rng = np.random.default_rng(cfg.seed)
    pick = eligible[rng.integers(bounds[:-1], bounds[1:])]
    ys, xs = np.divmod(pick, w)
    label = labels[pick]
    p_t = step.back_project(xs, ys, depth[pick])

    # Track by the flow; depth at t+1 read bilinearly.
    flow = step.flow.reshape(-1, 2)[pick]
    px_t1 = np.stack((xs + flow[:, 0], ys + flow[:, 1]), axis=-1)
    z1 = bilinear_depth(step.depth_t1, px_t1[:, 0], px_t1[:, 1], cfg.depth_edge_m)
    p_t1 = step.back_project(px_t1[:, 0], px_t1[:, 1], z1)
    tracked = np.flatnonzero(np.isfinite(z1))

    # Candidate pairs: tracked samples of one label within [d_min, d_c] of each other.
    pairs = tracked[cKDTree(p_t[tracked]).query_pairs(cfg.frame_max_side_m, output_type="ndarray")]
    origin = np.concatenate((pairs[:, 0], pairs[:, 1]))
    other = np.concatenate((pairs[:, 1], pairs[:, 0]))
    dist = np.linalg.norm(p_t[other] - p_t[origin], axis=1)
    keep = (label[origin] == label[other]) & (dist >= cfg.frame_min_side_m)
    origin, other, dist = origin[keep], other[keep], dist[keep]

    # Second point: the farthest candidate of each origin.
    second, second_dist = best_per_origin(origin, dist, other, len(pick))

    # Third point: the candidate spanning the largest triangle with a wide enough angle.
    j = second[origin]
    a = p_t[j] - p_t[origin]
    b = p_t[other] - p_t[origin]
    area = np.linalg.norm(np.cross(a, b), axis=1)
    side_jk = np.linalg.norm(p_t[other] - p_t[j], axis=1)
    ok = (
        (other != j)
        & (side_jk >= cfg.frame_min_side_m)
        & (side_jk <= cfg.frame_max_side_m)
        & (area >= cfg.frame_min_sin * second_dist[origin] * dist)
    )
    third, _ = best_per_origin(origin[ok], area[ok], other[ok], len(pick))
    origins = np.flatnonzero(third >= 0)
    tri = np.stack((origins, second[origins], third[origins]), axis=1)

    # Rigidity: no side may change by frame_rigid_tol_m or more; the moved triangle must
    # not be degenerate (at t the angle test above already rules that out).
    q_t, q_t1 = p_t[tri], p_t1[tri]
    stretch = np.abs(side_lengths(q_t1) - side_lengths(q_t))
    rigid = np.all(stretch < cfg.frame_rigid_tol_m, axis=0)
    a1, b1 = q_t1[:, 1] - q_t1[:, 0], q_t1[:, 2] - q_t1[:, 0]
    cross = np.linalg.norm(np.cross(a1, b1), axis=1)
    rigid &= cross > MIN_FRAME_SIN * np.linalg.norm(a1, axis=1) * np.linalg.norm(b1, axis=1)
    tri = tri[rigid]
    return Frames(
        p_t=p_t[tri],
        p_t1=p_t1[tri],
        px_t1=px_t1[tri],
        label=label[tri[:, 0]],
        space_origin=p_t.mean(axis=0),
        sampled=len(pick),
    )


# --- twists -----------------------------------------------------------------------------


def frame_poses(points, origin):
    """Rotation (m, 3, 3) and translation (m, 3) of frames on three points: origin at the
    first, x towards the second, z normal to the plane, in a space frame at `origin`."""
    p = points - origin
    a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    x = a / np.linalg.norm(a, axis=1, keepdims=True)
    n = np.cross(a, b)
    z = n / np.linalg.norm(n, axis=1, keepdims=True)
    return np.stack((x, np.cross(z, x), z), axis=-1), p[:, 0]


def compute_twists(frames):
    """Spatial twists [w, v] (m, 6): log of M = T_t1 T_t^-1 for each frame."""
    r0, t0 = frame_poses(frames.p_t, frames.space_origin)
    r1, t1 = frame_poses(frames.p_t1, frames.space_origin)
    r = r1 @ r0.transpose(0, 2, 1)
    t = t1 - np.einsum("mij,mj->mi", r, t0)
    w = Rotation.from_matrix(r).as_rotvec()
    # v = V^-1 t, V^-1 = I - [w]x/2 + c [w]x^2, c = (1 - (θ/2) cot(θ/2)) / θ².
    theta = np.linalg.norm(w, axis=1)
    th2 = theta**2
    c = 1 / 12 + th2 / 720 + th2**2 / 30240
    big = theta >= SERIES_BELOW_RAD
    half = theta[big] / 2
    c[big] = (1 - half / np.tan(half)) / th2[big]
    wt = np.cross(w, t)
    v = t - 0.5 * wt + c[:, None] * np.cross(w, wt)
    return np.hstack((w, v))


# --- grouping ---------------------------------------------------------------------------


def smooth(hist, sigma_bins):
    """Gaussian KDE of a histogram: the kernel riseg uses (unnormalised, 3σ reach)."""
    sigma = max(sigma_bins, 0.5)
    reach = int(3 * sigma) + 1
    d = np.arange(-reach + 1, reach)
    return np.convolve(hist, np.exp(-0.5 * (d / sigma) ** 2), mode="same")


def normalised(density, uniform_share):
    total = density.sum()
    p = density / total if total > 0 else np.full(KDE_BINS, 1 / KDE_BINS)
    return (1 - uniform_share) * p + uniform_share / KDE_BINS


def first_valley(density):
    """First clear valley after the first peak: a bin at most 2/3 of a later bin and of
    the peak; None when the density only falls after its first peak."""
    peak_level = density.max()
    if peak_level <= 0:
        return None
    b = 0
    while b + 1 < KDE_BINS and density[b + 1] >= density[b]:
        b += 1
    first_peak = low = density[b]
    low_bin = b
    for i in range(b + 1, KDE_BINS):
        d = density[i]
        if d < low:
            low_bin, low = i, d
        elif d > 1.5 * low and d > 0.02 * peak_level and low < first_peak / 1.5:
            return low_bin
    return None


def link_posterior(hist_inside, hist_all, cfg):
    """P(same body | distance bin) for pairs inside one segment."""
    sigma_bins = cfg.kde_bandwidth_m / (cfg.kde_range_m / KDE_BINS)
    cut = first_valley(smooth(hist_all, sigma_bins))
    cut = KDE_BINS if cut is None else cut
    near_part = np.where(np.arange(KDE_BINS) < cut, hist_all, 0)
    near = normalised(smooth(near_part, sigma_bins), 0.0)
    far = normalised(smooth(hist_all - near_part, sigma_bins), FAR_UNIFORM_SHARE)
    prior = (hist_inside[:cut].sum() + 1) / (hist_inside.sum() + 2)
    a, b = prior * near, (1 - prior) * far
    return np.divide(a, a + b, out=np.zeros(KDE_BINS), where=a + b > 0)


def group_frames(twists, labels, cfg):
    m = len(twists)
    scaled = np.hstack((cfg.length_scale_m * twists[:, :3], twists[:, 3:]))
    moving = np.einsum("ij,ij->i", scaled, scaled) >= cfg.static_below_m**2

    # Pairs in pdist's condensed order; across segments only moving pairs are data.
    i, j = np.triu_indices(m, 1)
    bins = np.minimum(pdist(scaled) * (KDE_BINS / cfg.kde_range_m), KDE_BINS - 1).astype(np.intp)
    inside = labels[i] == labels[j]
    data = inside | (moving[i] & moving[j])
    hist_inside = np.bincount(bins[inside], minlength=KDE_BINS)
    hist_all = np.bincount(bins[data], minlength=KDE_BINS)
    posterior = link_posterior(hist_inside, hist_all, cfg)

    # Links inside one segment; density = number of links.
    linked = inside & (posterior[bins] > cfg.link_posterior)
    li, lj, lb = i[linked], j[linked], bins[linked]
    density = np.bincount(li, minlength=m) + np.bincount(lj, minlength=m)

    # Quick shift: each frame attaches to its nearest (by bin) linked frame of higher
    # rank (density, then lower index); ties in distance go to the higher rank.
    rank = density * (m + 1) + (m - np.arange(m))
    i_low = rank[li] < rank[lj]
    low, high = np.where(i_low, li, lj), np.where(i_low, lj, li)
    order = np.lexsort((-rank[high], lb, low))
    low, high = low[order], high[order]
    first = first_per_run(low)
    forest = coo_matrix((np.ones(first.sum()), (low[first], high[first])), shape=(m, m))
    _, component = connected_components(forest, directed=False)

    # Components are numbered by their smallest frame, like riseg's union-find roots.
    sizes = np.bincount(component)
    kept = sizes >= max(cfg.min_group_frames, 1)
    group_id = np.full(len(sizes), NO_GROUP)
    group_id[kept] = np.arange(kept.sum())
    frame_group = group_id[component]
    grouped = frame_group != NO_GROUP
    sums = np.zeros((kept.sum(), 6))
    np.add.at(sums, frame_group[grouped], twists[grouped])
    return Grouping(frame_group=frame_group, twist=sums / sizes[kept][:, None])


# --- mask -------------------------------------------------------------------------------


def merge_small_segments(segment, count, min_px):
    """Segments smaller than `min_px` join their largest (size, id) neighbour that ranks
    above them; merges are followed to the end."""
    size = np.bincount(segment.ravel(), minlength=count + 1)
    if not (size[1:] < min_px).any():
        return segment
    # Pairs of different segments that touch horizontally or vertically.
    a, b = [], []
    for first, second in ((segment[:, :-1], segment[:, 1:]), (segment[:-1], segment[1:])):
        edge = (first != second) & (first != 0) & (second != 0)
        a.append(first[edge])
        b.append(second[edge])
    small = np.concatenate(a + b)
    big = np.concatenate(b + a)
    rank = size * (count + 1) + np.arange(count + 1)
    ok = (size[small] < min_px) & (rank[big] > rank[small])
    best = np.zeros(count + 1, dtype=rank.dtype)
    np.maximum.at(best, small[ok], rank[big[ok]])
    target = np.where(best > 0, best % (count + 1), np.arange(count + 1))
    while True:
        onward = target[target]
        if np.array_equal(onward, target):
            return target[segment]
        target = onward


def label_segments(key, min_px):
    """4-connected components of equal non-zero `key`, small ones merged. Returns the
    segment image, each segment's key, and the number of components."""
    segment = np.zeros(key.shape, dtype=np.int64)
    rows, cols = np.flatnonzero(key.any(axis=1)), np.flatnonzero(key.any(axis=0))
    if rows.size == 0:
        return segment, np.zeros(1, dtype=np.int64), 0
    # Work on the bounding box of the foreground.
    box = np.s_[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
    crop = key[box]
    crop_segment = np.zeros(crop.shape, dtype=np.int64)
    keys = [0]
    for k in np.unique(crop[crop != 0]):
        component, n = ndimage.label(crop == k)
        inside = component > 0
        crop_segment[inside] = component[inside] + (len(keys) - 1)
        keys.extend([k] * n)
    count = len(keys) - 1
    segment[box] = merge_small_segments(crop_segment, count, min_px)
    return segment, np.array(keys, dtype=np.int64), count


def camera_motions(grouping, origin):
    """Rotation (g, 3, 3) and translation (g, 3) of exp(twist) of each group, moved from
    the space frame at `origin` to the camera frame."""
    w, v = grouping.twist[:, :3], grouping.twist[:, 3:]
    r = Rotation.from_rotvec(w).as_matrix()
    # V v = v + b [w]x v + c [w]x^2 v, b = (1 - cos θ)/θ², c = (θ - sin θ)/θ³.
    theta = np.linalg.norm(w, axis=1)
    th2 = theta**2
    b = 0.5 - th2 / 24 + th2**2 / 720
    c = 1 / 6 - th2 / 120 + th2**2 / 5040
    big = theta >= SERIES_BELOW_RAD
    b[big] = (1 - np.cos(theta[big])) / th2[big]
    c[big] = (theta[big] - np.sin(theta[big])) / (th2[big] * theta[big])
    wv = np.cross(w, v)
    t = v + b[:, None] * wv + c[:, None] * np.cross(w, wv)
    return r, origin + t - r @ origin


def grow_decisions(step, source, pixels, candidates, motions, tol_px):
    """For each pixel, the candidate group (index into `motions`) whose rigid motion best
    predicts the observed flow at its source pixel, within `tol_px`; NO_GROUP if none,
    HOLE if the pixel has no source. `candidates` is (pixels, groups) bool."""
    w = step.labels_t.shape[1]
    src = source[pixels]
    has_source = src >= 0
    sy, sx = np.divmod(src[has_source], w)
    p = step.back_project(sx, sy, step.depth_t.ravel()[src[has_source]])
    observed = np.stack((sx, sy), axis=-1) + step.flow.reshape(-1, 2)[src[has_source]]
    r, t = motions
    q = p @ r.transpose(0, 2, 1) + t[:, None, :]  # (groups, pixels, 3)
    z = np.where(q[..., 2] > 1e-6, q[..., 2], np.nan)
    ex = step.fx * q[..., 0] / z + step.cx - observed[:, 0]
    ey = step.fy * q[..., 1] / z + step.cy - observed[:, 1]
    r2 = ex * ex + ey * ey
    r2 = np.where(candidates[has_source].T & (r2 <= tol_px**2), r2, np.inf)
    # The last group wins a tie, as in riseg.
    best = len(r2) - 1 - np.argmin(r2[::-1], axis=0)
    decision = np.full(len(pixels), HOLE)
    decision[has_source] = np.where(np.isfinite(r2.min(axis=0)), best, NO_GROUP)
    return decision


def grow(segment, claim, decision, width):
    """Breadth-first growth of the claimed pixels (flat `claim`, group + 1, 0 = free) to
    4-neighbours of their segment whose decision is their group or HOLE."""
    n = segment.size
    frontier = np.flatnonzero(claim)
    while frontier.size:
        x = frontier % width
        steps = (
            (frontier - 1, x > 0),
            (frontier + 1, x + 1 < width),
            (frontier - width, frontier >= width),
            (frontier + width, frontier + width < n),
        )
        # A step off the image stays on its (claimed) pixel, which the claim test drops.
        to = np.concatenate([np.where(ok, nb, frontier) for nb, ok in steps])
        src = np.tile(frontier, 4)
        group = claim[src]
        ok = (claim[to] == 0) & (segment[to] == segment[src])
        ok &= (decision[to] == HOLE) | (decision[to] == group - 1)
        to, first = np.unique(to[ok], return_index=True)
        claim[to] = group[ok][first]
        frontier = to


def correct_mask(step, frames, grouping, cfg):
    h, w = step.labels_t.shape
    labels = step.labels_t.ravel()
    depth = step.depth_t.ravel()

    # 1. Carry: splat every labelled pixel to its rounded flow target; nearer depth wins.
    src = np.flatnonzero((labels != 0) & valid_depth(depth))
    sy, sx = np.divmod(src, w)
    flow = step.flow.reshape(-1, 2)[src]
    u, v = round_half_away(sx + flow[:, 0]), round_half_away(sy + flow[:, 1])
    inside = (u >= 0) & (v >= 0) & (u < w) & (v < h)
    src = src[inside]
    target = v[inside].astype(np.intp) * w + u[inside].astype(np.intp)
    order = np.lexsort((depth[src], target))  # stable: equal depths keep scan order
    target, src = target[order], src[order]
    first = first_per_run(target)
    source = np.full(h * w, -1)
    source[target[first]] = src[first]
    carried = np.zeros(h * w, dtype=np.uint32)
    carried[target[first]] = labels[src[first]]

    # 2. Intersect with the static mask: segments are components of equal (carried, static).
    static = step.static_t1.ravel().astype(np.uint32)
    key = np.where(static != 0, (carried << 16) | static, 0).reshape(h, w)
    segment, _, count = label_segments(key, cfg.min_segment_px)
    segment = segment.ravel()

    # 3. Seed: (segment, group) pairs with at least MIN_SEEDS tracked frame pixels.
    groups = len(grouping.twist)
    grouped = grouping.frame_group != NO_GROUP
    px = round_half_away(frames.px_t1[grouped]).reshape(-1, 2)
    seed_group = np.repeat(grouping.frame_group[grouped], 3)
    in_image = (px[:, 0] >= 0) & (px[:, 1] >= 0) & (px[:, 0] < w) & (px[:, 1] < h)
    seed_px = px[in_image, 1].astype(np.intp) * w + px[in_image, 0].astype(np.intp)
    seed_group = seed_group[in_image]
    seed_seg = segment[seed_px]
    pair, seeds = np.unique(seed_seg * groups + seed_group, return_counts=True)
    real = (pair // groups != 0) & (seeds >= MIN_SEEDS)
    pair, seeds = pair[real], seeds[real]
    in_segment = np.zeros((count + 1, groups), dtype=bool)
    in_segment[pair // groups, pair % groups] = True
    split = in_segment.sum(axis=1) >= 2

    # 4. Grow in split segments from the seed pixels (the first frame to mark a pixel wins).
    claim = np.zeros(h * w, dtype=np.int64)
    if split.any():
        ok = split[seed_seg] & in_segment[seed_seg, seed_group]
        first_px, first = np.unique(seed_px[ok], return_index=True)
        claim[first_px] = seed_group[ok][first] + 1
        pixels = np.flatnonzero(split[segment])
        decision = np.full(h * w, NO_GROUP)
        decision[pixels] = grow_decisions(
            step,
            source,
            pixels,
            in_segment[segment[pixels]],
            camera_motions(grouping, frames.space_origin),
            cfg.grow_tol_px,
        )
        grow(segment, claim, decision, w)

    # 5. Label: in a split segment the group with most seeds keeps the segment's label,
    # the others get new ones; then fragments are cleaned up once more.
    relabel = np.repeat(np.arange(count + 1)[:, None], groups, axis=1)
    next_label = count + 1
    for seg in np.flatnonzero(split):
        mine = pair // groups == seg
        members, counts = pair[mine] % groups, seeds[mine]
        largest = members[np.argmax(counts)]  # ties: the smaller group id
        for g in members[members != largest]:
            relabel[seg, g] = next_label
            next_label += 1
    out = segment.copy()
    claimed = claim != 0
    out[claimed] = relabel[segment[claimed], claim[claimed] - 1]
    final, final_key, _ = label_segments(out.reshape(h, w), cfg.min_segment_px)
    return final_key[final].astype(np.uint16)


# --- driver -----------------------------------------------------------------------------


def update_mask(step, cfg):
    frames = create_frames(step, cfg)
    twists = compute_twists(frames)
    grouping = group_frames(twists, frames.label, cfg)
    return correct_mask(step, frames, grouping, cfg)


def load(directory):
    d = Path(directory)
    k = json.loads((d / "intrinsics.json").read_text())
    cfg = Config(**json.loads((d / "config.json").read_text()))
    step = Step(
        labels_t=np.load(d / "merged_t.npy"),
        depth_t=np.load(d / "depth_t.npy"),
        depth_t1=np.load(d / "depth_t1.npy"),
        flow=np.load(d / "flow.npy"),
        static_t1=np.load(d / "merged_t1.npy"),
        fx=k["fx"],
        fy=k["fy"],
        cx=k["cx"],
        cy=k["cy"],
    )
    return step, cfg, np.load(d / "truth_t1.npy"), np.load(d / "riseg_t1.npy")


def best_ious(truth, predicted):
    """For each true object, the best IoU any predicted label reaches."""
    t, p = truth.ravel().astype(np.int64), predicted.ravel().astype(np.int64)
    joint = np.bincount(t * (p.max() + 1) + p, minlength=(t.max() + 1) * (p.max() + 1))
    joint = joint.reshape(t.max() + 1, p.max() + 1)
    union = joint.sum(axis=1)[:, None] + joint.sum(axis=0)[None, :] - joint
    iou = np.divide(joint, union, out=np.zeros(joint.shape), where=union > 0)
    return {int(obj): float(iou[obj, 1:].max()) for obj in np.unique(t) if obj != 0}


def median_ms(fn, repeat):
    fn()  # warm-up
    runs = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        runs.append(time.perf_counter() - start)
    return 1e3 * statistics.median(runs)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("inputs", help="directory written by the dump_synthetic_step example")
    parser.add_argument("--repeat", type=int, default=7, help="timed runs per stage")
    parser.add_argument("--json", metavar="FILE", help="write the figures to FILE")
    args = parser.parse_args()

    step, cfg, truth_t1, riseg_t1 = load(args.inputs)
    frames = create_frames(step, cfg)
    twists = compute_twists(frames)
    grouping = group_frames(twists, frames.label, cfg)
    labels_t1 = correct_mask(step, frames, grouping, cfg)

    stages = {
        "frames": lambda: create_frames(step, cfg),
        "twists": lambda: compute_twists(frames),
        "grouping": lambda: group_frames(twists, frames.label, cfg),
        "mask": lambda: correct_mask(step, frames, grouping, cfg),
        "total": lambda: update_mask(step, cfg),
    }
    timings = {name: median_ms(fn, args.repeat) for name, fn in stages.items()}

    ious = {"numpy": best_ious(truth_t1, labels_t1), "riseg": best_ious(truth_t1, riseg_t1)}
    h, w = step.labels_t.shape
    print(
        f"numpy reference, {w}x{h}: {frames.sampled} samples, {len(twists)} frames, "
        f"{len(grouping.twist)} groups, labels {[int(x) for x in np.unique(labels_t1) if x]}"
    )
    print("best IoU per true object:")
    print("  object " + " ".join(f"{obj:>6}" for obj in ious["numpy"]))
    for who, per_object in ious.items():
        print(f"  {who:<6} " + " ".join(f"{iou:6.3f}" for iou in per_object.values()))
    print(f"\nstage     | numpy ms (median of {args.repeat}, one thread)")
    for name, ms in timings.items():
        print(f"{name:<9} | {ms:9.2f}")
    if args.json:
        figures = {
            "stages_ms": timings,
            "repeat": args.repeat,
            "frames": len(twists),
            "groups": len(grouping.twist),
            "best_iou": ious,
            "numpy": np.__version__,
            "scipy": scipy.__version__,
        }
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
