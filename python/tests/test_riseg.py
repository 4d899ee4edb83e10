"""The Python package against the CLI, and its argument checks."""

import json

import numpy as np
import pytest

import riseg
from conftest import run_cli


def python_loop(scene: riseg.Scene, config: riseg.Config) -> list:
    """``riseg run``'s loop from the package's functions: static segmentation of frame 0,
    then flow, segmentation and UpdateMask for every later frame."""
    k = scene.intrinsics
    static, _heat = riseg.segment(scene.rgb(0), scene.depth_m(0), k)
    masks = [static]
    for t in range(1, scene.frames):
        field = riseg.flow(scene.rgb(t - 1), scene.rgb(t), hint=scene.motion_hint(t))
        static, _heat = riseg.segment(scene.rgb(t), scene.depth_m(t), k)
        masks.append(riseg.update_mask(masks[-1], scene.depth_m(t - 1), scene.depth_m(t),
                                       field, static, k, config))
    return masks


def test_loop_equals_riseg_run(scene_dir, cli_masks):
    scene = riseg.read_scene(scene_dir)
    assert scene.frames == 3 == cli_masks.frames
    masks = python_loop(scene, riseg.Config())
    for t, mask in enumerate(masks):
        assert mask.dtype == np.uint16 and mask.shape == (scene.height, scene.width)
        np.testing.assert_array_equal(mask, cli_masks.labels(t), err_msg=f"frame {t}")
    # The pushes split what the static segmenter merged: the last mask has more objects.
    assert len(np.unique(masks[-1])) > len(np.unique(masks[0]))


def test_metrics_equal_riseg_eval(dataset, cli_pred, cli_masks, tmp_path):
    report = tmp_path / "eval.json"
    run_cli("eval", "--gt", str(dataset), "--pred", str(cli_pred), "--json", str(report))
    rows = json.loads(report.read_text())["pushes"]
    scene = riseg.read_scene(dataset / "scene_000")
    assert [row["push"] for row in rows] == [0, 1, 2]
    for t, row in enumerate(rows):
        m = riseg.metrics(cli_masks.labels(t), scene.labels(t))
        for kind in ("overlap", "boundary"):
            for short, name in (("p", "precision"), ("r", "recall"), ("f", "f")):
                value = m[f"{kind}_{name}"] * 100
                assert value == pytest.approx(row[kind][short], abs=1e-9), (kind, short, row)
        assert m["objects_detected_share"] * 100 == pytest.approx(row["objects_f75_pct"])


def test_strided_inputs_give_the_same_mask(scene_dir):
    scene = riseg.read_scene(scene_dir)
    k, cfg = scene.intrinsics, riseg.Config()
    static0, _ = riseg.segment(scene.rgb(0), scene.depth_m(0), k)
    static1, _ = riseg.segment(scene.rgb(1), scene.depth_m(1), k)
    field = riseg.flow(scene.rgb(0), scene.rgb(1))
    args = [static0, scene.depth_m(0), scene.depth_m(1), field, static1]
    lent = riseg.update_mask(*args, k, cfg)
    # Fortran order: numpy's buffer is not row-major, so riseg copies it first.
    copied = riseg.update_mask(*[np.asfortranarray(a) for a in args], k, cfg)
    np.testing.assert_array_equal(lent, copied)


def test_find_action_pushes_between_merged_objects(scene_dir):
    scene = riseg.read_scene(scene_dir)
    k = scene.intrinsics
    labels, heat = riseg.segment(scene.rgb(0), scene.depth_m(0), k)
    push = riseg.find_action(heat, labels, scene.depth_m(0), k, riseg.Config())
    assert push is not None
    assert push.length_m == pytest.approx(0.02)
    assert np.linalg.norm(push.direction_cam) == pytest.approx(1.0, abs=1e-5)
    u, v = push.start_px
    assert 0 <= u < scene.width and 0 <= v < scene.height
    assert labels[int(v), int(u)] != 0 or heat[int(v), int(u)] > 0
    # Nothing uncertain: no push.
    none = riseg.find_action(np.zeros_like(heat), labels, scene.depth_m(0), k)
    assert none is None


def test_config_defaults_and_fields():
    cfg = riseg.Config()
    assert (cfg.certain_from, cfg.uncertain_from) == (150, 120)
    assert (cfg.pair_max_m, cfg.push_len_m, cfg.seed) == (0.1, 0.02, 0)
    assert cfg.replace(seed=9).seed == 9 and cfg.seed == 0
    assert riseg.Config(max_pushes=2) == cfg.replace(max_pushes=2) != cfg
    assert cfg.to_dict()["frame_samples"] == 1000
    with pytest.raises(ValueError, match='no field "sed"'):
        riseg.Config(sed=1)
    with pytest.raises(ValueError, match="Config"):
        riseg.Config(uncertain_from=200)  # not below certain_from
    with pytest.raises(ValueError, match="Config.seed"):
        riseg.Config(seed="1")
    with pytest.raises(AttributeError):
        cfg.no_such_field


H, W = 6, 8
K = riseg.Intrinsics(500.0, 500.0, 3.5, 2.5)
LABELS = np.ones((H, W), np.uint16)
DEPTH = np.full((H, W), 0.6, np.float32)
FLOW = np.zeros((H, W, 2), np.float32)
RGB = np.zeros((H, W, 3), np.uint8)
HEAT = np.zeros((H, W), np.uint8)


@pytest.mark.parametrize(
    "call, name",
    [
        (lambda: riseg.update_mask(LABELS.astype(np.int32), DEPTH, DEPTH, FLOW, LABELS, K),
         "labels_t"),
        (lambda: riseg.update_mask(LABELS, DEPTH.astype(np.float64), DEPTH, FLOW, LABELS, K),
         "depth_t"),
        (lambda: riseg.update_mask(LABELS, DEPTH, DEPTH[:-1], FLOW, LABELS, K), "depth_t1"),
        (lambda: riseg.update_mask(LABELS, DEPTH, DEPTH, FLOW[..., :1], LABELS, K), "flow"),
        (lambda: riseg.update_mask(LABELS, DEPTH, DEPTH, FLOW, LABELS.tolist(), K),
         "static_t1"),
        (lambda: riseg.find_action(HEAT[None], LABELS, DEPTH, K), "heatmap"),
        (lambda: riseg.find_action(HEAT, LABELS, DEPTH.T, K), "depth_m"),
        (lambda: riseg.segment(RGB[..., :2], DEPTH, K), "rgb"),
        (lambda: riseg.flow(RGB, RGB.astype(np.float32)), "rgb1"),
        (lambda: riseg.metrics(LABELS, LABELS.astype(np.uint8)), "gt"),
    ],
)
def test_wrong_dtype_or_shape_names_the_argument(call, name):
    with pytest.raises(ValueError, match=f"^{name}: "):
        call()


def test_riseg_errors_carry_riseg_message(tmp_path):
    with pytest.raises(riseg.RisegError, match="no_such_scene"):
        riseg.read_scene(tmp_path / "no_such_scene")
    with pytest.raises(ValueError, match="Intrinsics"):
        riseg.Intrinsics(0.0, 500.0, 1.0, 1.0)
    with pytest.raises(riseg.RisegError, match="static segmentation"):
        riseg.segment(RGB[:0], DEPTH[:0], K)  # no pixels
