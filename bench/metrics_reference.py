#!/usr/bin/env python3
"""Independent reference implementation of riseg's UOIS segmentation metrics.

Written from the formulas (issue 6 and the UnseenObjectClustering `multilabel_metrics`
definitions), not from riseg's Rust code: it builds one boolean mask per object, its
one-pixel boundary with array shifts, dilates with scipy.ndimage and matches objects with
scipy.optimize.linear_sum_assignment. host/tests/metrics_vs_python.rs runs it on random
label maps and requires agreement to 1e-6.

Definitions (per image; label 0 is background, every other value is one object):
  tp_ij = |g_i & p_j|,  F_ij = 2 tp_ij / (|g_i| + |p_j|)
  boundary(m): pixels where m differs from m at the right, lower or lower-right
               neighbour (only neighbours inside the image are compared)
  D(b): b dilated by the disk dx^2 + dy^2 <= r^2, r = ceil(0.003 * sqrt(W^2 + H^2))
  bp_ij = |boundary(p_j) & D(boundary(g_i))|,  br_ij = |boundary(g_i) & D(boundary(p_j))|
  matching: min(#G, #P) one-to-one pairs, maximising lexicographically
            (sum floor(F_ij * 2^24), sum bp_ij, sum br_ij)
  overlap P = sum tp / pred foreground, R = sum tp / gt foreground, F = 2PR / (P + R)
  boundary P = sum bp / sum_j |boundary(p_j)|, R = sum br / sum_i |boundary(g_i)|
               (a ratio over zero boundary pixels is 1)
  detected = matched pairs with F_ij > 3/4 (exact), share = detected / #G
  empty cases: no pred, some gt: P=1 R=0 F=0, share 0; pred, no gt: P=0 R=1 F=0,
               share 0; neither: all 1.

Input: an index JSON {"cases": [{"name", "width", "height", "gt", "pred"}, ...]} whose
"gt"/"pred" are files (relative to the index) of width*height little-endian uint16.
Output (stdout): {"results": [{"name", "overlap": [P, R, F], "boundary": [P, R, F],
"objects_gt", "objects_pred", "objects_detected", "objects_detected_share"}, ...]}.

Needs numpy and scipy (pip install numpy scipy).
"""

import json
import math
import os
import sys

import numpy as np
from scipy import ndimage
from scipy.optimize import linear_sum_assignment

F_BITS = 24
# linear_sum_assignment works in float64: keep every sum it forms exactly representable.
EXACT_FLOAT_LIMIT = 2**50


def one_pixel_boundary(mask):
    """Boolean map of pixels whose right / lower / lower-right neighbour differs."""
    edge = np.zeros(mask.shape, dtype=bool)
    edge[:, :-1] |= mask[:, :-1] != mask[:, 1:]
    edge[:-1, :] |= mask[:-1, :] != mask[1:, :]
    edge[:-1, :-1] |= mask[:-1, :-1] != mask[1:, 1:]
    return edge


def disk(radius):
    offsets = np.arange(-radius, radius + 1)
    dy, dx = np.meshgrid(offsets, offsets, indexing="ij")
    return dx * dx + dy * dy <= radius * radius


def dilate(edge, footprint):
    if not edge.any():
        return edge.copy()
    return ndimage.binary_dilation(edge, structure=footprint, border_value=0)


def prf(precision, recall):
    total = precision + recall
    return [precision, recall, 2.0 * precision * recall / total if total > 0 else 0.0]


def ratio_or_one(hits, total):
    return hits / total if total > 0 else 1.0


def metrics(gt, pred):
    height, width = gt.shape
    gt_ids = [int(v) for v in np.unique(gt) if v != 0]
    pred_ids = [int(v) for v in np.unique(pred) if v != 0]
    n_gt, n_pred = len(gt_ids), len(pred_ids)
    base = {"objects_gt": n_gt, "objects_pred": n_pred, "objects_detected": 0}
    if n_gt == 0 and n_pred == 0:
        return {**base, "overlap": [1.0] * 3, "boundary": [1.0] * 3,
                "objects_detected_share": 1.0}
    if n_pred == 0:
        return {**base, "overlap": prf(1.0, 0.0), "boundary": prf(1.0, 0.0),
                "objects_detected_share": 0.0}
    if n_gt == 0:
        return {**base, "overlap": prf(0.0, 1.0), "boundary": prf(0.0, 1.0),
                "objects_detected_share": 0.0}

    footprint = disk(math.ceil(0.003 * math.sqrt(width * width + height * height)))
    g_masks = [gt == v for v in gt_ids]
    p_masks = [pred == v for v in pred_ids]
    g_edges = [one_pixel_boundary(m) for m in g_masks]
    p_edges = [one_pixel_boundary(m) for m in p_masks]
    g_near = [dilate(e, footprint) for e in g_edges]
    p_near = [dilate(e, footprint) for e in p_edges]
    g_edge_total = int(sum(int(e.sum()) for e in g_edges))
    p_edge_total = int(sum(int(e.sum()) for e in p_edges))

    tp = [[int(np.count_nonzero(g & p)) for p in p_masks] for g in g_masks]
    bp = [[int(np.count_nonzero(pe & gn)) for pe in p_edges] for gn in g_near]
    br = [[int(np.count_nonzero(ge & pn)) for pn in p_near] for ge in g_edges]
    g_size = [int(m.sum()) for m in g_masks]
    p_size = [int(m.sum()) for m in p_masks]

    keys = [[0] * n_pred for _ in range(n_gt)]
    for i in range(n_gt):
        for j in range(n_pred):
            f_fixed = (2 * tp[i][j] << F_BITS) // (g_size[i] + p_size[j])
            keys[i][j] = ((f_fixed * (p_edge_total + 1) + bp[i][j]) * (g_edge_total + 1)
                          + br[i][j])
    largest = max(max(row) for row in keys)
    if min(n_gt, n_pred) * (largest + 1) >= EXACT_FLOAT_LIMIT:
        raise ValueError(f"keys too large for exact float64 matching: {largest}")
    rows, cols = linear_sum_assignment(np.array(keys, dtype=np.float64), maximize=True)

    tp_sum = sum(tp[i][j] for i, j in zip(rows, cols))
    bp_sum = sum(bp[i][j] for i, j in zip(rows, cols))
    br_sum = sum(br[i][j] for i, j in zip(rows, cols))
    detected = sum(1 for i, j in zip(rows, cols)
                   if 8 * tp[i][j] > 3 * (g_size[i] + p_size[j]))
    return {
        **base,
        "overlap": prf(tp_sum / int(np.count_nonzero(pred)),
                       tp_sum / int(np.count_nonzero(gt))),
        "boundary": prf(ratio_or_one(bp_sum, p_edge_total),
                        ratio_or_one(br_sum, g_edge_total)),
        "objects_detected": detected,
        "objects_detected_share": detected / n_gt,
    }


def load(folder, name, width, height):
    data = np.fromfile(os.path.join(folder, name), dtype="<u2")
    if data.size != width * height:
        raise ValueError(f"{name}: {data.size} labels, expected {width}x{height}")
    return data.reshape(height, width)


def main(argv):
    if len(argv) != 2:
        print(f"usage: {argv[0]} INDEX.json", file=sys.stderr)
        return 2
    folder = os.path.dirname(os.path.abspath(argv[1]))
    with open(argv[1], encoding="utf-8") as f:
        cases = json.load(f)["cases"]
    results = []
    for case in cases:
        w, h = case["width"], case["height"]
        result = metrics(load(folder, case["gt"], w, h), load(folder, case["pred"], w, h))
        results.append({"name": case["name"], **result})
    json.dump({"results": results}, sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
