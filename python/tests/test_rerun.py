"""``riseg demo --rerun`` and ``riseg run --rerun`` read back with the rerun-sdk wheel of
the same version (no viewer): every entity of every frame is in the file, as the archetype
host/src/cli/record.rs documents."""

from collections import defaultdict
from pathlib import Path

from rerun.experimental import RrdReader

from conftest import run_cli

STAGES = ("segment", "flow", "frames", "twists", "grouping", "mask")
# Entity under the root -> its archetype.
EVERY_FRAME = {
    "camera/rgb": "Image",
    "camera/depth": "DepthImage",
    "camera/static": "SegmentationImage",
    "camera/riseg": "SegmentationImage",
} | {f"timing/{stage}": "Scalars" for stage in STAGES}
AFTER_A_PUSH = {"camera/flow": "Image", "body_frames": "Arrows3D"}
PUSH = {"camera/push": "Arrows2D", "push": "Arrows3D"}
STATIC = {"": {"ViewCoordinates", "AnnotationContext"}, "camera": {"Pinhole"}}


class Recording:
    """The entities of one .rrd: push indices and archetypes of the temporal data, and the
    archetypes of the static data."""

    def __init__(self, rrd: Path):
        self.pushes = defaultdict(set)
        self.archetypes = defaultdict(set)
        self.static = defaultdict(set)
        for chunk in RrdReader(rrd).stream():
            batch = chunk.to_record_batch()
            # Component columns are named ``Archetype:field``.
            kinds = {name.split(":")[0] for name in batch.schema.names if ":" in name}
            if chunk.is_static:
                self.static[chunk.entity_path] |= kinds
            elif "push" in chunk.timeline_names:
                self.pushes[chunk.entity_path].update(batch.column("push").to_pylist())
                self.archetypes[chunk.entity_path] |= kinds

    def check(self, root: str, frames: int, pushes: set) -> None:
        for entity, kinds in STATIC.items():
            path = f"/{root}/{entity}".rstrip("/")
            assert kinds <= self.static[path], (path, dict(self.static))
        for entities, expected in [
            (EVERY_FRAME, set(range(frames))),
            (AFTER_A_PUSH, set(range(1, frames))),
            (PUSH, pushes),
        ]:
            for entity, kind in entities.items():
                path = f"/{root}/{entity}"
                assert self.pushes[path] == expected, (path, self.pushes[path])
                assert self.archetypes[path] == {kind}, (path, self.archetypes[path])
        known = {f"/{root}/{e}" for e in EVERY_FRAME | AFTER_A_PUSH | PUSH}
        assert set(self.pushes) == known, set(self.pushes) ^ known


def test_demo_recording_has_every_push(tmp_path):
    rrd = tmp_path / "demo.rrd"
    out = run_cli("demo", "--out", str(tmp_path / "demo"), "--rerun", str(rrd)).stdout
    pushes = int(out.split(" pushes;")[0].rsplit(" ", 1)[1])
    assert pushes >= 1, out
    # The demo pushes from every frame but its last, where the loop stops.
    Recording(rrd).check("demo", pushes + 1, set(range(pushes)))


def test_run_recording_has_every_frame(scene_dir, tmp_path):
    rrd = tmp_path / "run.rrd"
    run_cli("run", "--scene", str(scene_dir), "--out", str(tmp_path / "pred"),
            "--rerun", str(rrd))
    # The scene's two recorded pushes were made from frames 0 and 1.
    Recording(rrd).check(scene_dir.name, 3, {0, 1})
