#!/usr/bin/env python3
"""Writes the tiny ONNX models of host/tests/onnx_models.rs into OUT (argument 1).

Needs the PyPI `onnx` package (CI: onnx==1.23.2). Every model is a few nodes with known
weights, so the Rust tests know the exact outputs:

  flow_const.onnx     image1, image2 -> flow [1,2,H/8,W/8] = (0.25, -0.125) coarse pixels
                      everywhere (a Conv with zero weights, bias only): (2, -1) frame pixels
  flow_affine.onnx    flow [1,2,H,W] = (0.01 * R of image1, -0.02 * G of image2), raw 0-255
  seg_masks.onnx      rgb, depth [1,1,H,W] -> masks [1,2,H,W] logits 1000*(0.55 - d) and
                      1000*(0.58 - d), scores [1,2] = (0.9, 0.8)   (+ seg_masks.json)
  seg_labels.onnx     rgb -> labels [1,H,W] int64 = R/255 > 0.5    (+ seg_labels.json)
  bad_rank.onnx       flow model whose image1 is [1,H,W] (declared, unused)
  bad_dtype.onnx      flow model whose image1 is float64 (declared, unused)
  no_output.onnx      flow model whose output is named `motion`
  nan_flow.onnx       flow model whose output is NaN
  not_onnx.onnx       a text file
"""

import sys
from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

OPSET = 17
IR_VERSION = 8


def image(name, channels=3, dtype=TensorProto.FLOAT, rank4=True):
    shape = [1, channels, "H", "W"] if rank4 else [1, "H", "W"]
    return helper.make_tensor_value_info(name, dtype, shape)


def save(graph, path):
    model = helper.make_model(
        graph, opset_imports=[helper.make_opsetid("", OPSET)], ir_version=IR_VERSION
    )
    onnx.checker.check_model(model)
    onnx.save(model, str(path))


def init(name, array):
    return numpy_helper.from_array(np.asarray(array, dtype=np.float32), name)


def flow_graph(bias, out_name="flow", stride=8, first=None, weights=None):
    """Conv over concat(image1, image2) with kernel and stride `stride`, weights (zero by
    default) and `bias`. With a `first` declaration (a wrong one, for the error tests),
    image1 is declared but not used and the Conv reads image2 alone."""
    channels = 6 if first is None else 3
    w = np.zeros((2, channels, stride, stride), np.float32) if weights is None else weights
    conv_in = "both" if first is None else "image2"
    nodes = [
        helper.make_node(
            "Conv", [conv_in, "w", "b"], [out_name], kernel_shape=[stride, stride],
            strides=[stride, stride],
        ),
    ]
    if first is None:
        nodes.insert(0, helper.make_node("Concat", ["image1", "image2"], ["both"], axis=1))
    out_shape = [1, 2, "h", "w"]
    return helper.make_graph(
        nodes,
        "flow",
        [first or image("image1"), image("image2")],
        [helper.make_tensor_value_info(out_name, TensorProto.FLOAT, out_shape)],
        [init("w", w), init("b", bias)],
    )


def main(out):
    out.mkdir(parents=True, exist_ok=True)
    save(flow_graph([0.25, -0.125]), out / "flow_const.onnx")

    affine = np.zeros((2, 6, 1, 1), np.float32)
    affine[0, 0, 0, 0] = 0.01  # dx from R of image1
    affine[1, 4, 0, 0] = -0.02  # dy from G of image2
    save(flow_graph([0.0, 0.0], stride=1, weights=affine), out / "flow_affine.onnx")

    save(flow_graph([0.0, 0.0], first=image("image1", rank4=False)), out / "bad_rank.onnx")
    save(
        flow_graph([0.0, 0.0], first=image("image1", dtype=TensorProto.DOUBLE)),
        out / "bad_dtype.onnx",
    )
    save(flow_graph([0.0, 0.0], out_name="motion"), out / "no_output.onnx")
    save(flow_graph([np.nan, np.nan]), out / "nan_flow.onnx")

    # Segmenter: masks from depth thresholds (colour weighted 0), constant scores.
    mw = np.zeros((2, 4, 1, 1), np.float32)
    mw[:, 3, 0, 0] = -1000.0
    seg = helper.make_graph(
        [
            helper.make_node("Concat", ["rgb", "depth"], ["rgbd"], axis=1),
            helper.make_node("Conv", ["rgbd", "mw", "mb"], ["masks"], kernel_shape=[1, 1]),
            helper.make_node("Identity", ["s"], ["scores"]),
        ],
        "seg_masks",
        [image("rgb"), image("depth", channels=1)],
        [
            helper.make_tensor_value_info("masks", TensorProto.FLOAT, [1, 2, "H", "W"]),
            helper.make_tensor_value_info("scores", TensorProto.FLOAT, [1, 2]),
        ],
        [init("mw", mw), init("mb", [550.0, 580.0]), init("s", [[0.9, 0.8]])],
    )
    save(seg, out / "seg_masks.onnx")
    (out / "seg_masks.json").write_text('{"depth_input": "depth", "depth_kind": "depth"}\n')

    labels = helper.make_graph(
        [
            helper.make_node("Gather", ["rgb", "zero"], ["red"], axis=1),
            helper.make_node("Greater", ["red", "half"], ["bright"]),
            helper.make_node("Cast", ["bright"], ["labels"], to=TensorProto.INT64),
        ],
        "seg_labels",
        [image("rgb")],
        [helper.make_tensor_value_info("labels", TensorProto.INT64, [1, "H", "W"])],
        [
            numpy_helper.from_array(np.array(0, np.int64), "zero"),
            init("half", 0.5),
        ],
    )
    save(labels, out / "seg_labels.onnx")
    (out / "seg_labels.json").write_text(
        '{"labels_output": "labels", "mean": [0, 0, 0], "std": [1, 1, 1]}\n'
    )

    (out / "not_onnx.onnx").write_text("this is not an ONNX model\n")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: make_models.py OUT_DIR")
    main(Path(sys.argv[1]))
