#!/usr/bin/env python3
"""OpenCV DIS optical flow on the pairs that `host/examples/flow_pairs.rs` wrote.

    pip install opencv-python-headless numpy
    python3 bench/flow_vs_opencv.py DIR [--runs 7] [--per-pair]

Runs cv2.DISOpticalFlow presets ULTRAFAST, FAST and MEDIUM on one thread
(cv2.setNumThreads(1)) and prints, per preset, the same tab-separated columns as the
Rust example: name, mean EPE on moving-object pixels, mean EPE on all pixels (pixels,
averaged over pairs), mean over pairs of the median time of --runs runs (ms, after one
warm-up run). The time covers `calc` on 8-bit grayscale images (BGR-to-gray conversion
excluded).
"""

import argparse
import glob
import os
import statistics
import sys
import time

import cv2
import numpy as np

FLO_MAGIC = 202021.25


def read_flo(path):
    with open(path, "rb") as f:
        magic = np.fromfile(f, np.float32, 1)
        if magic.size != 1 or magic[0] != FLO_MAGIC:
            sys.exit(f"{path}: not a .flo file")
        w, h = np.fromfile(f, np.int32, 2)
        data = np.fromfile(f, np.float32, 2 * w * h)
        if data.size != 2 * w * h:
            sys.exit(f"{path}: truncated .flo file")
    return data.reshape(h, w, 2)


def read_image(path, flags):
    img = cv2.imread(path, flags)
    if img is None:
        sys.exit(f"{path}: cannot read image")
    return img


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir")
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--per-pair", action="store_true")
    args = ap.parse_args()

    cv2.setNumThreads(1)
    names = sorted(
        os.path.basename(p)[: -len("_a.png")]
        for p in glob.glob(os.path.join(args.dir, "*_a.png"))
    )
    if not names:
        sys.exit(f"{args.dir}: no *_a.png files (run the flow_pairs example first)")
    pairs = []
    for n in names:
        base = os.path.join(args.dir, n)
        a = cv2.cvtColor(read_image(base + "_a.png", cv2.IMREAD_COLOR), cv2.COLOR_BGR2GRAY)
        b = cv2.cvtColor(read_image(base + "_b.png", cv2.IMREAD_COLOR), cv2.COLOR_BGR2GRAY)
        mask = read_image(base + "_mask.png", cv2.IMREAD_GRAYSCALE) > 127
        pairs.append((n, a, b, read_flo(base + "_gt.flo"), mask))

    presets = [
        ("ULTRAFAST", cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST),
        ("FAST", cv2.DISOPTICAL_FLOW_PRESET_FAST),
        ("MEDIUM", cv2.DISOPTICAL_FLOW_PRESET_MEDIUM),
    ]
    for label, preset in presets:
        dis = cv2.DISOpticalFlow.create(preset)
        obj, all_, ms = [], [], []
        for n, a, b, gt, mask in pairs:
            flow = dis.calc(a, b, None)
            times = []
            for _ in range(max(args.runs, 1)):
                t = time.perf_counter()
                flow = dis.calc(a, b, None)
                times.append((time.perf_counter() - t) * 1e3)
            epe = np.linalg.norm(flow - gt, axis=2)
            known = np.all(np.abs(gt) < 1e9, axis=2)  # Middlebury: >= 1e9 is unknown
            e_obj, e_all = float(epe[mask & known].mean()), float(epe[known].mean())
            med = statistics.median(times)
            if args.per_pair:
                print(f"opencv-dis-{label.lower()}/{n}\t{e_obj:.3f}\t{e_all:.3f}\t{med:.1f}")
            obj.append(e_obj)
            all_.append(e_all)
            ms.append(med)
        print(
            f"opencv-dis-{label.lower()}\t{np.mean(obj):.3f}\t{np.mean(all_):.3f}\t{np.mean(ms):.1f}"
        )


if __name__ == "__main__":
    main()
