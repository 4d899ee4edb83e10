"""Shared fixtures: a scene made by ``riseg gen`` and the masks ``riseg run`` wrote for it.

The CLI is the one built from this repository: ``RISEG_BIN`` names it (``test.sh`` sets
it). Without it the suite fails at setup; it never skips.
"""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

import riseg


def riseg_cli() -> str:
    path = os.environ.get("RISEG_BIN")
    if not path or not Path(path).is_file():
        raise RuntimeError(
            "RISEG_BIN must name the riseg binary built from this repository "
            "(python/test.sh sets it)"
        )
    return path


def run_cli(*args: str) -> subprocess.CompletedProcess:
    done = subprocess.run([riseg_cli(), *args], capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"riseg {' '.join(args)} failed:\n{done.stderr}")
    return done


@pytest.fixture(scope="session")
def dataset(tmp_path_factory) -> Path:
    """One packed scene (look-alike boxes, the regime RISeg is for), 2 pushes."""
    root = tmp_path_factory.mktemp("data")
    run_cli("gen", "--scenes", "1", "--seed", "1", "--layout", "packed",
            "--pushes", "2", "--out", str(root / "gen"))
    return root / "gen"


@pytest.fixture(scope="session")
def scene_dir(dataset: Path) -> Path:
    return dataset / "scene_000"


@pytest.fixture(scope="session")
def cli_pred(scene_dir: Path, tmp_path_factory) -> Path:
    """``riseg run``'s output folder: ``PRED/scene_000/label/NNNNNN.png``."""
    pred = tmp_path_factory.mktemp("pred")
    run_cli("run", "--scene", str(scene_dir), "--out", str(pred))
    return pred


@pytest.fixture(scope="session")
def cli_masks(scene_dir: Path, cli_pred: Path, tmp_path_factory) -> riseg.Scene:
    """``riseg run``'s masks, read back as the labels of a copy of the scene folder."""
    masks = tmp_path_factory.mktemp("masks") / scene_dir.name
    shutil.copytree(cli_pred / scene_dir.name, masks)
    for name in ("scene_camera.json", "actions.json"):
        shutil.copy(scene_dir / name, masks)
    for sub in ("rgb", "depth"):
        shutil.copytree(scene_dir / sub, masks / sub)
    return riseg.read_scene(masks)
