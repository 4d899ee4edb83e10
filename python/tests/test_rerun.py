"""``riseg demo --rerun`` and ``riseg run --rerun`` read back with the rerun-sdk wheel
(no viewer): every entity of every frame is in the file."""

from collections import defaultdict
from pathlib import Path

from rerun.experimental import RrdReader

from conftest import run_cli

EVERY_FRAME = ["camera/rgb", "camera/depth", "camera/static", "camera/riseg"] + [
    f"timing/{stage}" for stage in ("segment", "flow", "frames", "twists", "grouping", "mask")
]
AFTER_A_PUSH = ["camera/flow", "body_frames"]
PUSH = ["camera/push", "push"]
STATIC = ["", "camera"]  # view coordinates and class colours; the pinhole


def frames_by_entity(rrd: Path) -> tuple[dict, set]:
    """``{entity: {push index, ...}}`` of the temporal data, and the static entities."""
    timed, static = defaultdict(set), set()
    for chunk in RrdReader(rrd).stream():
        if chunk.is_static:
            static.add(chunk.entity_path)
        elif "push" in chunk.timeline_names:
            timed[chunk.entity_path].update(chunk.to_record_batch().column("push").to_pylist())
    return timed, static


def check_recording(rrd: Path, root: str, frames: int, pushes: set) -> None:
    timed, static = frames_by_entity(rrd)
    for entity in STATIC:
        assert f"/{root}/{entity}".rstrip("/") in static, (entity, static)
    for entity in EVERY_FRAME:
        assert timed[f"/{root}/{entity}"] == set(range(frames)), entity
    for entity in AFTER_A_PUSH:
        assert timed[f"/{root}/{entity}"] == set(range(1, frames)), entity
    for entity in PUSH:
        assert timed[f"/{root}/{entity}"] == pushes, entity


def test_demo_recording_has_every_push(tmp_path):
    rrd = tmp_path / "demo.rrd"
    out = run_cli("demo", "--out", str(tmp_path / "demo"), "--rerun", str(rrd)).stdout
    pushes = int(out.split(" pushes;")[0].rsplit(" ", 1)[1])
    assert pushes >= 1, out
    # The demo pushes from every frame but its last, where the loop stops.
    check_recording(rrd, "demo", pushes + 1, set(range(pushes)))


def test_run_recording_has_every_frame(scene_dir, tmp_path):
    rrd = tmp_path / "run.rrd"
    run_cli("run", "--scene", str(scene_dir), "--out", str(tmp_path / "pred"),
            "--rerun", str(rrd))
    # The scene's two recorded pushes were made from frames 0 and 1.
    check_recording(rrd, scene_dir.name, 3, {0, 1})
