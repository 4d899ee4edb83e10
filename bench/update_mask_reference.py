"""A plain numpy/scipy reference of one riseg UpdateMask step, and its per-stage timing.

It mirrors riseg-core's `pipeline::update_mask` (core/src/frames.rs, group.rs, split.rs,
mask.rs; their module docs state the contracts), stage by stage:

- frames:   CreateFrames. Stratified seeded sampling of `n` labelled pixels with valid
            depth; depth at t (at the pixel) and at t+1 (at the flow-tracked position)
            denoised by a least-squares plane fit over a small window (dropped on a depth
            edge); one frame per tracked sample (second point the farthest same-label
            sample within d_c, third the one spanning the largest triangle), rigidity check.
- twists:   CalcBFIFs. The spatial twist log(T_t1 T_t^-1) of each frame, in a space
            frame at the centroid of the samples.
- grouping: GroupBFIFs. Binned Gaussian KDE of pairwise twist distances split at its
            first valley, mask prior, posterior links inside one segment, quick shift
            along link density (parents within three bandwidths), small groups dropped,
            groups of one segment closer than the valley merged; then the second pass:
            groups that two rigid motions (Kabsch fits, alternated) explain far better
            than one are split, and still groups whose fit moved their points are moving.
- mask:     CorrectMask. Forward splat with depth ordering, intersection with the static
            mask (small segments merged, fragments of no object absorbed), seeds of a
            group's worth of frames (still groups as one identity group), seeded region
            growing under each group's fitted rigid motion, relabelling, same-motion merge,
            final components.

It is written the way a Python robotics engineer would write it: vectorised numpy,
scipy.spatial for neighbours and rotations, scipy.ndimage for labelling, no compiled code
of its own; python loops only over groups, rounds, segments and growth waves. It is not
bit-identical to riseg (numpy's generator draws the samples, float64 instead of float32,
eigh instead of power iteration, k-d tree neighbours break distance ties in their own
order, and segment ids are numbered per key rather than in scan order, which only matters
for exact size ties), but it makes the same decisions.

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
from dataclasses import dataclass, fields  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy  # noqa: E402
from scipy import ndimage  # noqa: E402
from scipy.sparse import coo_matrix  # noqa: E402
from scipy.sparse.csgraph import connected_components  # noqa: E402
from scipy.spatial import cKDTree  # noqa: E402
from scipy.spatial.distance import pdist, squareform  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

# Constants riseg-core fixes in code rather than in Config.
MAX_DEPTH_M = 100.0  # image.rs: readings beyond are no reading
KDE_BINS = 120  # group.rs
FAR_UNIFORM_SHARE = 1e-3  # group.rs: uniform floor of the far-pair likelihood
ATTACH_BANDWIDTHS = 3.0  # group.rs: farthest quick-shift parent, in KDE bandwidths
MIN_FRAME_SIN = 1e-3  # se3.rs: collinearity limit of a frame's triangle
SERIES_BELOW_RAD = 0.3  # se3.rs: series form of the SE(3) coefficients below this angle
MAX_ROUNDS = 8  # split.rs: reassignment rounds per split
MIN_PART_FRAMES_PER_GROUP = 3  # split.rs: each part needs 3 x min_group_frames frames
MIN_MOTION_GAP_M = 0.001  # split.rs: a fit moving its centroid this far moved
MIN_SPLIT_GAP_M = 0.0005  # split.rs: the two parts' motions must differ this much
MAX_MISS_RATIO = 0.9  # split.rs: the split's mean miss against the single motion's
MIN_COHERENCE = 0.8  # split.rs: share of a frame's neighbours in its own part
NEIGHBOURS = 4  # split.rs: neighbours per frame in the coherence test
SMOOTH_NEIGHBOURS = 8  # split.rs: neighbours a frame's miss is averaged with
OBJECT_SHARE = 3  # mask.rs: a component keeps its segment with 1/3 of its label's pixels
FIT_OUTLIER_FACTOR = 2.5  # mask.rs: refit without points missing by more than this x mean
FIT_OUTLIER_FLOOR_M = 1e-3  # mask.rs: ... or by more than this
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
    depth_window_px: int
    depth_window_tol_m: float
    frame_rigid_tol_m: float
    length_scale_m: float
    static_below_m: float
    kde_range_m: float
    kde_bandwidth_m: float
    link_posterior: float
    min_group_frames: int
    min_segment_px: int
    grow_tol_px: float
    merge_twist_m: float
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
    """CreateFrames' output: m frames of three points each, in sample (row-major) order."""

    p_t: np.ndarray  # (m, 3, 3) points at t, camera frame
    p_t1: np.ndarray  # (m, 3, 3) points at t+1
    px_t: np.ndarray  # (m, 2) pixel of each frame's origin at t
    px_t1: np.ndarray  # (m, 3, 2) tracked pixels at t+1
    label: np.ndarray  # (m,) accumulated-mask label
    space_origin: np.ndarray  # (3,) centroid of the samples at t
    sampled: int


@dataclass(frozen=True)
class Grouping:
    """GroupBFIFs' output (after the split pass)."""

    frame_group: np.ndarray  # (m,) group id or NO_GROUP
    twist: np.ndarray  # (groups, 6) twist [w, v] of each group, space frame
    moving: np.ndarray  # (groups,) twist or fitted motion above the noise floor
    label: np.ndarray  # (groups,) accumulated-mask label of the group's frames


def round_half_away(x):
    """Rounds like C's `round` (riseg's libm), not numpy's half-to-even."""
    return np.copysign(np.floor(np.abs(x) + 0.5), x)


def valid_depth(z):
    return (z > 0) & (z <= MAX_DEPTH_M)  # NaN fails both


def first_per_run(keys):
    """Mask of the first element of each run of equal values in a sorted array."""
    return np.r_[True, keys[1:] != keys[:-1]]


# --- rigid motions ----------------------------------------------------------------------


def twist_norm2(twists, length_scale_m):
    """Squared twist norms |v|² + L²|w|² (m², riseg's `Twist::norm_squared`)."""
    return np.einsum("...i,...i", twists[..., 3:], twists[..., 3:]) + length_scale_m**2 * (
        np.einsum("...i,...i", twists[..., :3], twists[..., :3])
    )


def se3_log(r, t):
    """Twists [w, v] (k, 6) of rigid motions with rotations r (k, 3, 3), translations t."""
    w = Rotation.from_matrix(r).as_rotvec()
    # v = V^-1 t, V^-1 = I - [w]x/2 + c [w]x^2, c = (1 - (θ/2) cot(θ/2)) / θ².
    theta = np.linalg.norm(w, axis=1)
    th2 = theta**2
    c = 1 / 12 + th2 / 720 + th2**2 / 30240
    big = theta >= SERIES_BELOW_RAD
    half = theta[big] / 2
    c[big] = (1 - half / np.tan(half)) / th2[big]
    wt = np.cross(w, t)
    return np.hstack((w, t - 0.5 * wt + c[:, None] * np.cross(w, wt)))


def se3_exp(twists):
    """Rotations (k, 3, 3) and translations (k, 3) of exp(twist)."""
    w, v = twists[:, :3], twists[:, 3:]
    # V v = v + b [w]x v + c [w]x^2 v, b = (1 - cos θ)/θ², c = (θ - sin θ)/θ³.
    theta = np.linalg.norm(w, axis=1)
    th2 = theta**2
    b = 0.5 - th2 / 24 + th2**2 / 720
    c = 1 / 6 - th2 / 120 + th2**2 / 5040
    big = theta >= SERIES_BELOW_RAD
    b[big] = (1 - np.cos(theta[big])) / th2[big]
    c[big] = (theta[big] - np.sin(theta[big])) / (th2[big] * theta[big])
    wv = np.cross(w, v)
    return Rotation.from_rotvec(w).as_matrix(), v + b[:, None] * wv + c[:, None] * np.cross(w, wv)


def kabsch(a, b):
    """The least-squares rigid motion (R, t) carrying points a (k, 3) to b; None with
    fewer than six pairs (riseg's `fit_rigid_motion`)."""
    if len(a) < 6:
        return None
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
    v = vt.T
    if np.linalg.det(v @ u.T) < 0:
        v[:, 2] = -v[:, 2]
    r = v @ u.T
    return r, cb - r @ ca


def apply(motion, p):
    r, t = motion
    return p @ r.T + t


def fitted_twist(motion, origin):
    """The twist, in the space frame at `origin`, of a camera-frame motion."""
    r, t = motion
    return se3_log(r[None], (t + r @ origin - origin)[None])[0]


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


def local_depth(depth, u, v, cfg):
    """Depth at sub-pixel (u, v), denoised: the least-squares plane z = a + b dx + c dy
    through the readings of the (2r+1)² window around the nearest pixel that lie within
    depth_window_tol_m of the bilinear depth, evaluated at (u, v). NaN where the bilinear
    depth is; the bilinear depth where the window has no well-posed plane."""
    z_ref = bilinear_depth(depth, u, v, cfg.depth_edge_m)
    r = cfg.depth_window_px
    if r == 0:
        return z_ref
    h, w = depth.shape
    ok = np.isfinite(z_ref)
    u, v = np.where(ok, u, 0), np.where(ok, v, 0)
    offsets = np.arange(-r, r + 1)
    xs = np.floor(u + 0.5).astype(np.intp)[:, None, None] + offsets[None, None, :]
    ys = np.floor(v + 0.5).astype(np.intp)[:, None, None] + offsets[None, :, None]
    inside = (xs >= 0) & (xs < w) & (ys >= 0) & (ys < h)
    z = depth[np.clip(ys, 0, h - 1), np.clip(xs, 0, w - 1)]
    dz = z - z_ref[:, None, None]
    use = inside & valid_depth(z) & (np.abs(dz) <= cfg.depth_window_tol_m)
    dx = np.where(use, xs - u[:, None, None], 0).reshape(len(u), -1)
    dy = np.where(use, ys - v[:, None, None], 0).reshape(len(u), -1)
    dz = np.where(use, dz, 0).reshape(len(u), -1)
    n = use.reshape(len(u), -1).sum(axis=1).astype(float)
    sx, sy, sz = dx.sum(axis=1), dy.sum(axis=1), dz.sum(axis=1)
    sxx, syy, sxy = (dx * dx).sum(axis=1), (dy * dy).sum(axis=1), (dx * dy).sum(axis=1)
    sxz, syz = (dx * dz).sum(axis=1), (dy * dz).sum(axis=1)
    # Cramer's rule for a in [[n sx sy] [sx sxx sxy] [sy sxy syy]] (a b c) = (sz sxz syz).
    minor = sxx * syy - sxy * sxy
    det = n * minor - sx * (sx * syy - sxy * sy) + sy * (sx * sxy - sxx * sy)
    det_a = sz * minor - sx * (sxz * syy - sxy * syz) + sy * (sxz * sxy - sxx * syz)
    posed = (n >= 6) & (np.abs(det) > 1e-3 * n**3)
    with np.errstate(divide="ignore", invalid="ignore"):
        fit = z_ref + det_a / det
    fit = np.where(np.isfinite(fit) & (fit > 0), fit, np.nan)
    return np.where(posed, fit, z_ref)


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
    z_t = local_depth(step.depth_t, xs.astype(float), ys.astype(float), cfg)
    p_t = step.back_project(xs, ys, np.where(np.isfinite(z_t), z_t, depth[pick]))

    # Track by the flow; depth at t+1 denoised the same way.
    flow = step.flow.reshape(-1, 2)[pick]
    px_t1 = np.stack((xs + flow[:, 0], ys + flow[:, 1]), axis=-1)
    z1 = local_depth(step.depth_t1, px_t1[:, 0], px_t1[:, 1], cfg)
    p_t1 = step.back_project(px_t1[:, 0], px_t1[:, 1], z1)
    tracked = np.flatnonzero(np.isfinite(z1))

    # Candidate pairs: tracked samples of one label within [d_min, d_c] of each other.
    pairs = tracked[cKDTree(p_t[tracked]).query_pairs(cfg.frame_max_side_m, output_type="ndarray")]
    pairs = pairs[label[pairs[:, 0]] == label[pairs[:, 1]]]
    dist = np.linalg.norm(p_t[pairs[:, 1]] - p_t[pairs[:, 0]], axis=1)
    pairs, dist = pairs[dist >= cfg.frame_min_side_m], dist[dist >= cfg.frame_min_side_m]
    origin = np.concatenate((pairs[:, 0], pairs[:, 1]))
    other = np.concatenate((pairs[:, 1], pairs[:, 0]))
    dist = np.concatenate((dist, dist))

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
        px_t=np.stack((xs, ys), axis=-1)[tri[:, 0]],
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
    return se3_log(r, t1 - np.einsum("mij,mj->mi", r, t0))


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
    """P(same body | distance bin) for pairs inside one segment, and the valley bin."""
    sigma_bins = cfg.kde_bandwidth_m / (cfg.kde_range_m / KDE_BINS)
    valley = first_valley(smooth(hist_all, sigma_bins))
    cut = KDE_BINS if valley is None else valley
    near_part = np.where(np.arange(KDE_BINS) < cut, hist_all, 0)
    near = normalised(smooth(near_part, sigma_bins), 0.0)
    far = normalised(smooth(hist_all - near_part, sigma_bins), FAR_UNIFORM_SHARE)
    prior = (hist_inside[:cut].sum() + 1) / (hist_inside.sum() + 2)
    a, b = prior * near, (1 - prior) * far
    return np.divide(a, a + b, out=np.zeros(KDE_BINS), where=a + b > 0), valley


class UnionFind:
    """riseg's union-find over a few items: the smaller root stays the root."""

    def __init__(self, n):
        self.parent = list(range(n))

    def find(self, i):
        while self.parent[i] != i:
            self.parent[i] = i = self.parent[self.parent[i]]
        return i

    def union(self, a, b):
        ra, rb = self.find(a), self.find(b)
        if ra == rb:
            return False
        self.parent[max(ra, rb)] = min(ra, rb)
        return True


def group_frames(twists, labels, cfg):
    """Twist groups: quick shift on the links, then groups of one segment that the KDE
    cannot tell apart merged."""
    m = len(twists)
    floor2 = cfg.static_below_m**2
    scaled = np.hstack((cfg.length_scale_m * twists[:, :3], twists[:, 3:]))
    moving = np.einsum("ij,ij->i", scaled, scaled) >= floor2

    # Pairs in pdist's condensed order; across segments only moving pairs are data.
    bins_per_m = KDE_BINS / cfg.kde_range_m
    i, j = np.triu_indices(m, 1)
    bins = np.minimum(pdist(scaled) * bins_per_m, KDE_BINS - 1).astype(np.intp)
    inside = labels[i] == labels[j]
    data = inside | (moving[i] & moving[j])
    hist_inside = np.bincount(bins[inside], minlength=KDE_BINS)
    hist_all = np.bincount(bins[data], minlength=KDE_BINS)
    posterior, valley = link_posterior(hist_inside, hist_all, cfg)

    # Links inside one segment; density = number of links.
    linked = inside & (posterior[bins] > cfg.link_posterior)
    li, lj, lb = i[linked], j[linked], bins[linked]
    density = np.bincount(li, minlength=m) + np.bincount(lj, minlength=m)

    # Quick shift: each frame attaches to its nearest (by bin) linked frame of higher
    # rank (density, then lower index) within a few bandwidths; ties in distance go to
    # the higher rank.
    near = lb <= int(ATTACH_BANDWIDTHS * cfg.kde_bandwidth_m * bins_per_m)
    li, lj, lb = li[near], lj[near], lb[near]
    rank = density * (m + 1) + (m - np.arange(m))  # unique: frame = m - rank % (m + 1)
    i_low = rank[li] < rank[lj]
    low, high = np.where(i_low, li, lj), np.where(i_low, lj, li)
    # One key per candidate parent, smaller is better: nearer bin, then higher rank.
    ranks = rank.max() + 1
    key = lb * ranks + (ranks - 1 - rank[high])
    best = np.full(m, np.iinfo(np.int64).max)
    np.minimum.at(best, low, key)
    child = np.flatnonzero(best < np.iinfo(np.int64).max)
    parent = m - (ranks - 1 - best[child] % ranks) % (m + 1)
    forest = coo_matrix((np.ones(child.size), (child, parent)), shape=(m, m))
    _, component = connected_components(forest, directed=False)

    # Components are numbered by their smallest frame, like riseg's union-find roots; a
    # group's twist is that frame's.
    sizes = np.bincount(component)
    _, root = np.unique(component, return_index=True)
    kept = sizes >= max(cfg.min_group_frames, 1)
    group_id = np.full(len(sizes), NO_GROUP)
    group_id[kept] = np.arange(kept.sum())
    twist = twists[root[kept]]
    grouping = Grouping(
        frame_group=group_id[component],
        twist=twist,
        moving=twist_norm2(twist, cfg.length_scale_m) >= floor2,
        label=labels[root[kept]],
    )
    resolution = np.inf if valley is None else valley / bins_per_m
    return merge_close_groups(grouping, sizes[kept], cfg, resolution)


def merge_close_groups(grouping, frames, cfg, resolution_m):
    """Groups of one segment closer than `resolution_m` (the KDE valley) are one motion:
    moving ones unite, then each set joins its nearest larger set within reach, compared
    by the twist of its largest group. Ids stay in order of each set's first group."""
    count = len(grouping.twist)
    if count < 2:
        return grouping
    scaled = np.hstack((cfg.length_scale_m * grouping.twist[:, :3], grouping.twist[:, 3:]))
    dist = squareform(pdist(scaled))
    close = (grouping.label[:, None] == grouping.label[None, :]) & (dist <= resolution_m)
    sets = UnionFind(count)
    for a, b in zip(*np.nonzero(np.triu(close & np.outer(grouping.moving, grouping.moving), 1))):
        sets.union(a, b)
    for g in range(count):
        roots = np.array([sets.find(h) for h in range(count)])
        if roots[g] != g:
            continue
        set_frames = np.bincount(roots, weights=frames, minlength=count)
        # Each set's largest group (the first of the largest).
        largest = np.lexsort((np.arange(count), -frames, roots))[first_per_run(np.sort(roots))]
        largest_of = np.zeros(count, dtype=np.intp)
        largest_of[np.unique(roots)] = largest
        others = np.unique(roots)
        larger = (set_frames[others] > set_frames[g]) | (
            (set_frames[others] == set_frames[g]) & (others < g)
        )
        others = others[(others != g) & larger & close[largest_of[g], largest_of[others]]]
        if others.size:
            d = dist[largest_of[g], largest_of[others]]
            sets.union(g, others[np.argmin(d)])
    roots = np.array([sets.find(h) for h in range(count)])
    is_root = roots == np.arange(count)
    new_id = np.cumsum(is_root) - 1
    new_id = new_id[roots]
    # Each merged group keeps the twist of its largest part (the first of the largest).
    largest = np.lexsort((np.arange(count), -frames, new_id))[first_per_run(np.sort(new_id))]
    frame_group = np.where(grouping.frame_group != NO_GROUP, new_id[grouping.frame_group], NO_GROUP)
    twist = grouping.twist[largest]
    return Grouping(
        frame_group=frame_group,
        twist=twist,
        moving=twist_norm2(twist, cfg.length_scale_m) >= cfg.static_below_m**2,
        label=grouping.label[largest],
    )


def frame_misses(motion, p_t, p_t1):
    """Mean miss vector (k, 3) and mean miss length (k,) of frames' three points."""
    miss = apply(motion, p_t) - p_t1
    return miss.mean(axis=1), np.linalg.norm(miss, axis=2).mean(axis=1)


def split_one(p_t, p_t1, px_t, cfg):
    """Tries to split one group's frames (module docs of split.rs); returns the side of
    each frame (True: the part that moved more, which leaves) and both parts' (motion,
    moved_m), or None."""
    min_part = MIN_PART_FRAMES_PER_GROUP * max(cfg.min_group_frames, 1)
    k = len(p_t)
    if k < 2 * min_part:
        return None
    one = kabsch(p_t.reshape(-1, 3), p_t1.reshape(-1, 3))
    if one is None:
        return None
    raw, total = frame_misses(one, p_t, p_t1)
    # Each frame's miss averaged with its nearest frames' (by first pixel at t); the
    # first parts are the sides of the misses' principal axis.
    tree = cKDTree(px_t)
    _, near = tree.query(px_t, k=min(SMOOTH_NEIGHBOURS, k - 1) + 1)
    smoothed = raw[near].mean(axis=1)
    centred = smoothed - smoothed.mean(axis=0)
    axis = np.linalg.eigh(centred.T @ centred)[1][:, -1]
    side = centred @ axis > 0
    for _ in range(MAX_ROUNDS):
        fits = (
            kabsch(p_t[~side].reshape(-1, 3), p_t1[~side].reshape(-1, 3)),
            kabsch(p_t[side].reshape(-1, 3), p_t1[side].reshape(-1, 3)),
        )
        if fits[0] is None or fits[1] is None:
            return None
        miss = np.stack([frame_misses(f, p_t, p_t1)[1] for f in fits])
        best = miss[1] < miss[0]
        changed = (best != side).any()
        side = best
        if not changed:
            break
    sizes = np.array([(~side).sum(), side.sum()])
    if sizes.min() < min_part:
        return None
    centres = p_t.mean(axis=1)
    c = np.stack((centres[~side].mean(axis=0), centres[side].mean(axis=0)))
    gap_m = np.linalg.norm(apply(fits[0], c) - apply(fits[1], c), axis=1).max()
    split_miss = np.where(side, miss[1], miss[0]).sum()
    _, near = tree.query(px_t, k=min(NEIGHBOURS, k - 1) + 1)
    coherence = (side[near[:, 1:]] == side[:, None]).mean()
    if gap_m < MIN_SPLIT_GAP_M or split_miss > MAX_MISS_RATIO * total.sum():
        return None
    if coherence < MIN_COHERENCE:
        return None
    moved = [np.linalg.norm(apply(f, p) - p) for f, p in zip(fits, c)]
    parts = [(fits[0], moved[0]), (fits[1], moved[1])]
    if moved[0] > moved[1]:
        return ~side, parts[1], parts[0]
    return side, parts[0], parts[1]


def split_mixed_groups(frames, grouping, cfg):
    """GroupBFIFs' second pass: groups that two rigid motions explain far better than
    one split (the part that moved more gets a new id, the rest is tried again); then a
    still group whose fitted motion moves its centroid by MIN_MOTION_GAP_M is moving."""
    frame_group = grouping.frame_group.copy()
    twist, moving, label = list(grouping.twist), list(grouping.moving), list(grouping.label)
    floor2 = cfg.static_below_m**2

    def fitted(motion, moved_m):
        t = fitted_twist(motion, frames.space_origin)
        return t, bool(twist_norm2(t, cfg.length_scale_m) >= floor2 or moved_m >= MIN_MOTION_GAP_M)

    g = 0
    while g < len(twist):
        members = np.flatnonzero(frame_group == g)
        split = split_one(frames.p_t[members], frames.p_t1[members], frames.px_t[members], cfg)
        if split is None:
            g += 1
            continue
        leaves, keep, away = split
        frame_group[members[leaves]] = len(twist)
        twist[g], moving[g] = fitted(*keep)
        new_twist, new_moving = fitted(*away)
        twist.append(new_twist)
        moving.append(new_moving)
        label.append(label[g])
    for g in np.flatnonzero(~np.array(moving, dtype=bool)):
        members = frame_group == g
        a, b = frames.p_t[members].reshape(-1, 3), frames.p_t1[members].reshape(-1, 3)
        motion = kabsch(a, b)
        if motion is None:
            continue
        c = a.mean(axis=0)
        moved_m = np.linalg.norm(apply(motion, c) - c)
        if moved_m >= MIN_MOTION_GAP_M:
            twist[g], moving[g] = fitted(motion, moved_m)
    return Grouping(
        frame_group=frame_group,
        twist=np.array(twist).reshape(-1, 6),
        moving=np.array(moving, dtype=bool),
        label=np.array(label),
    )


def group_bfifs(frames, twists, cfg):
    """GroupBFIFs: twist groups, then the split pass."""
    return split_mixed_groups(frames, group_frames(twists, frames.label, cfg), cfg)


# --- mask -------------------------------------------------------------------------------


def merge_small_segments(segment, size, min_px):
    """Segments smaller than `min_px` join their largest (size, id) neighbour that ranks
    above them; merges are followed to the end."""
    count = len(size) - 1
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
    """4-connected components of equal non-zero `key` (small non-negative ints), small
    ones merged. Returns the segment image, each segment's key and its size before the
    merge (index 0: background)."""
    segment = np.zeros(key.shape, dtype=np.int64)
    keys = [0]
    for k, box in enumerate(ndimage.find_objects(key), start=1):
        if box is None:
            continue
        component, n = ndimage.label(key[box] == k)
        inside = component > 0
        segment[box][inside] = component[inside] + (len(keys) - 1)
        keys.extend([k] * n)
    size = np.bincount(segment.ravel(), minlength=len(keys))
    size[0] = 0
    return merge_small_segments(segment, size, min_px), np.array(keys), size


def dense(labels):
    """Labels renumbered 0, 1, 2, ... in order (0 stays 0), and the labels of each."""
    present = np.flatnonzero(np.bincount(labels.ravel()))
    lut = np.zeros(present[-1] + 1, dtype=np.int64)
    lut[present] = np.arange(len(present)) + (present[0] != 0)
    return lut[labels], np.r_[0, present[present != 0]]


def intersect(carried, static, min_px):
    """Step 2: segments of equal (carried, static) over the static foreground, small ones
    merged; a component that is no object (label 0, or less than a third of its label's
    carried pixels) joins the largest component of its static segment. Returns the
    segment image and the number of segments."""
    c, _ = dense(carried)
    s, _ = dense(static)
    key = np.where(s != 0, c * (s.max() + 1) + s, 0)
    segment, seg_key, size = label_segments(key, min_px)
    count = len(seg_key) - 1
    seg_carried, seg_static = np.divmod(seg_key, s.max() + 1)
    total = np.bincount(seg_carried, weights=size)
    obj = (seg_carried != 0) & (OBJECT_SHARE * size >= total[seg_carried])
    # The largest (then first) component of min_px or more of each static segment.
    big = np.flatnonzero(size >= min_px)
    big = big[np.lexsort((big, -size[big], seg_static[big]))]
    big = big[first_per_run(seg_static[big])]
    dominant = np.full(seg_static.max() + 1, -1)
    dominant[seg_static[big]] = big
    into = np.where(~obj & (dominant[seg_static] >= 0), dominant[seg_static], np.arange(count + 1))
    into[0] = 0
    return into[segment], count


def fit_motion(p_t, p_t1):
    """A moving group's camera-frame motion: Kabsch on all its points, refitted once
    without those it misses by more than max(1 mm, 2.5 x the mean miss)."""
    first = kabsch(p_t, p_t1)
    if first is None:
        return None
    miss = np.linalg.norm(apply(first, p_t) - p_t1, axis=1)
    keep = miss <= max(FIT_OUTLIER_FACTOR * miss.mean(), FIT_OUTLIER_FLOOR_M)
    return kabsch(p_t[keep], p_t1[keep]) or first


def group_motions(frames, grouping):
    """Rotation (g, 3, 3) and translation (g, 3) of each group in the camera frame: the
    fitted motion of a moving group (its twist if the fit fails), identity otherwise."""
    count = len(grouping.twist)
    r = np.broadcast_to(np.eye(3), (count, 3, 3)).copy()
    t = np.zeros((count, 3))
    origin = frames.space_origin
    for g in np.flatnonzero(grouping.moving):
        members = grouping.frame_group == g
        motion = fit_motion(frames.p_t[members].reshape(-1, 3), frames.p_t1[members].reshape(-1, 3))
        if motion is None:
            rg, tg = se3_exp(grouping.twist[g : g + 1])
            motion = rg[0], origin + tg[0] - rg[0] @ origin
        r[g], t[g] = motion
    return r, t


def grow_decisions(step, source, candidates, motions, tol_px):
    """For each pixel (its `source` pixel at t, -1 for none), the candidate group (index
    into `motions`) whose rigid motion best predicts the observed flow there, within
    `tol_px`; NO_GROUP if none, HOLE if the pixel has no source. `candidates` is
    (pixels, groups) bool."""
    w = step.labels_t.shape[1]
    has_source = source >= 0
    src = source[has_source]
    sy, sx = np.divmod(src, w)
    p = step.back_project(sx, sy, step.depth_t.ravel()[src])
    observed = np.stack((sx, sy), axis=-1) + step.flow.reshape(-1, 2)[src]
    best = np.full(len(src), tol_px**2)
    choice = np.full(len(src), NO_GROUP)
    # Groups in id order; the later group wins a tie, as in riseg.
    for g in np.flatnonzero(candidates.any(axis=0)):
        q = p @ motions[0][g].T + motions[1][g]
        ex = step.fx * q[:, 0] / q[:, 2] + step.cx - observed[:, 0]
        ey = step.fy * q[:, 1] / q[:, 2] + step.cy - observed[:, 1]
        r2 = ex * ex + ey * ey
        take = candidates[has_source, g] & (q[:, 2] > 1e-6) & (r2 <= best)
        best[take] = r2[take]
        choice[take] = g
    decision = np.full(len(source), HOLE)
    decision[has_source] = choice
    return decision


def grow(segment, claim, decision, width, frontier):
    """Breadth-first growth of the claimed pixels (flat `claim`, group + 1, 0 = free) from
    the seed pixels `frontier` (queue order) to 4-neighbours of their segment whose
    decision is their group or HOLE. One wave at a time, in riseg's queue order: a pixel
    goes to the first of the wave's pixels (left, right, up, down) that reaches it."""
    n = segment.size
    while frontier.size:
        x = frontier % width
        to = np.stack((frontier - 1, frontier + 1, frontier - width, frontier + width), axis=1)
        on_image = np.stack((x > 0, x + 1 < width, frontier >= width, frontier + width < n), axis=1)
        # A step off the image stays on its (claimed) pixel, which the claim test drops.
        to = np.where(on_image, to, frontier[:, None]).ravel()
        src = np.repeat(frontier, 4)
        group = claim[src]
        ok = (claim[to] == 0) & (segment[to] == segment[src])
        ok &= (decision[to] == HOLE) | (decision[to] == group - 1)
        to, group = to[ok], group[ok]
        _, first = np.unique(to, return_index=True)
        first.sort()
        frontier = to[first]
        claim[frontier] = group[first]


def merge_same_motion(out, segment, static, pair, label_of, grouping, cfg):
    """Step 6: labels of moving groups of different segments at t and different static
    segments at t+1 whose twists are closer than merge_twist_m unite."""
    static_of = np.zeros(segment.max() + 1, dtype=np.int64)
    static_of[segment] = static
    seg, grp = np.divmod(pair, len(grouping.twist))
    labels = UnionFind(out.max() + 1)
    merges = 0
    entries = [e for e in range(len(pair)) if grouping.moving[grp[e]]]
    for at, a in enumerate(entries):
        for b in entries[at + 1 :]:
            ga, gb = grp[a], grp[b]
            if grouping.label[ga] == grouping.label[gb] or static_of[seg[a]] == static_of[seg[b]]:
                continue
            d2 = twist_norm2(grouping.twist[ga] - grouping.twist[gb], cfg.length_scale_m)
            if np.sqrt(d2) < cfg.merge_twist_m:
                merges += labels.union(label_of[a], label_of[b])
    if not merges:
        return out
    return np.array([labels.find(i) for i in range(len(labels.parent))])[out]


def correct_mask(step, frames, grouping, cfg):
    h, w = step.labels_t.shape
    labels = step.labels_t.ravel()
    depth = step.depth_t.ravel()
    # Everything outside the static foreground's bounding box is background at t+1
    # whatever was carried there, so the per-pixel work is done in that window.
    rows = np.flatnonzero(step.static_t1.any(axis=1))
    cols = np.flatnonzero(step.static_t1.any(axis=0))
    out = np.zeros((h, w), dtype=np.uint16)
    if rows.size == 0:
        return out
    (y0, y1), (x0, x1) = (rows[0], rows[-1] + 1), (cols[0], cols[-1] + 1)
    wh, ww = y1 - y0, x1 - x0

    # 1. Carry: splat every labelled pixel to its rounded flow target; nearer depth wins.
    src = np.flatnonzero((labels != 0) & valid_depth(depth))
    sy, sx = np.divmod(src, w)
    flow = step.flow.reshape(-1, 2)[src]
    u = round_half_away(sx + flow[:, 0]) - x0
    v = round_half_away(sy + flow[:, 1]) - y0
    inside = (u >= 0) & (v >= 0) & (u < ww) & (v < wh)
    src = src[inside]
    target = v[inside].astype(np.intp) * ww + u[inside].astype(np.intp)
    order = np.lexsort((depth[src], target))  # stable: equal depths keep scan order
    target, src = target[order], src[order]
    first = first_per_run(target)
    source = np.full(wh * ww, -1)  # image pixel at t of each window pixel
    source[target[first]] = src[first]
    carried = np.zeros(wh * ww, dtype=np.int64)
    carried[target[first]] = labels[src[first]]

    # 2. Intersect with the static mask.
    static = step.static_t1[y0:y1, x0:x1].astype(np.int64)
    segment, count = intersect(carried.reshape(wh, ww), static, cfg.min_segment_px)
    segment = segment.ravel()

    # 3. Seed: (segment, group) pairs with the seeds of a group's worth of frames; every
    # still group seeds as the first one, with the identity motion.
    groups = len(grouping.twist)
    seed_as = np.arange(groups)
    if not grouping.moving.all():
        seed_as[~grouping.moving] = np.argmin(grouping.moving)
    grouped = grouping.frame_group != NO_GROUP
    px = (round_half_away(frames.px_t1[grouped]) - (x0, y0)).reshape(-1, 2)
    seed_group = np.repeat(seed_as[grouping.frame_group[grouped]], 3)
    in_window = (px[:, 0] >= 0) & (px[:, 1] >= 0) & (px[:, 0] < ww) & (px[:, 1] < wh)
    seed_px = px[in_window, 1].astype(np.intp) * ww + px[in_window, 0].astype(np.intp)
    seed_group = seed_group[in_window]
    seed_seg = segment[seed_px]
    pair, seeds = np.unique(seed_seg * groups + seed_group, return_counts=True)
    real = (pair // groups != 0) & (seeds >= 3 * max(cfg.min_group_frames, 1))
    pair, seeds = pair[real], seeds[real]
    in_segment = np.zeros((count + 1, groups), dtype=bool)
    in_segment[pair // groups, pair % groups] = True
    split = in_segment.sum(axis=1) >= 2

    # 4. Grow in split segments from the seed pixels (the first frame to mark a pixel wins).
    claim = np.zeros(wh * ww, dtype=np.int64)
    if split.any():
        ok = split[seed_seg] & in_segment[seed_seg, seed_group]
        _, first = np.unique(seed_px[ok], return_index=True)
        first = np.sort(first)
        claim[seed_px[ok][first]] = seed_group[ok][first] + 1
        pixels = np.flatnonzero(split[segment])
        decision = np.full(wh * ww, NO_GROUP)
        decision[pixels] = grow_decisions(
            step,
            source[pixels],
            in_segment[segment[pixels]],
            group_motions(frames, grouping),
            cfg.grow_tol_px,
        )
        grow(segment, claim, decision, ww, seed_px[ok][first])

    # 5. Label: in a split segment the group with most seeds keeps the segment's label,
    # the others get new ones.
    relabel = np.repeat(np.arange(count + 1)[:, None], groups, axis=1)
    label_of = pair // groups  # each entry's output label
    next_label = count + 1
    for seg in np.flatnonzero(split):
        mine = np.flatnonzero(pair // groups == seg)
        largest = mine[np.argmax(seeds[mine])]  # ties: the smaller group id
        for e in mine[mine != largest]:
            relabel[seg, pair[e] % groups] = label_of[e] = next_label
            next_label += 1
    labelled = segment.copy()
    claimed = claim != 0
    labelled[claimed] = relabel[segment[claimed], claim[claimed] - 1]

    # 6. Merge labels of one motion that the static mask cut apart (off when 0).
    if cfg.merge_twist_m > 0:
        fg = segment != 0
        labelled = merge_same_motion(
            labelled, segment[fg], static.ravel()[fg], pair, label_of, grouping, cfg
        )

    # 7. Components of the labels, small ones merged.
    final, _, _ = label_segments(labelled.reshape(wh, ww), cfg.min_segment_px)
    out[y0:y1, x0:x1] = final
    return out


# --- driver -----------------------------------------------------------------------------


def update_mask(step, cfg):
    frames = create_frames(step, cfg)
    twists = compute_twists(frames)
    grouping = group_bfifs(frames, twists, cfg)
    return correct_mask(step, frames, grouping, cfg)


def load(directory):
    d = Path(directory)
    k = json.loads((d / "intrinsics.json").read_text())
    raw = json.loads((d / "config.json").read_text())
    cfg = Config(**{f.name: f.type(raw[f.name]) for f in fields(Config)})
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
    grouping = group_bfifs(frames, twists, cfg)
    labels_t1 = correct_mask(step, frames, grouping, cfg)

    stages = {
        "frames": lambda: create_frames(step, cfg),
        "twists": lambda: compute_twists(frames),
        "grouping": lambda: group_bfifs(frames, twists, cfg),
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
