"""Type stubs of the compiled module ``riseg._riseg`` (re-exported by ``riseg``).

Array conventions: colour ``uint8 (H, W, 3)``; depth ``float32 (H, W)`` in metres
(``<= 0`` or NaN: no reading); labels ``uint16 (H, W)`` (0 = background); heatmap
``uint8 (H, W)`` (0-255); flow ``float32 (H, W, 2)``, ``(dx, dy)`` pixels from the first
image to the second (NaN: unknown). A wrong dtype or shape raises ``ValueError`` naming
the argument; C-contiguous inputs are read without a copy.
"""

from os import PathLike
from typing import Any, Optional, Union

import numpy as np
import numpy.typing as npt

class RisegError(RuntimeError):
    """An error riseg reports; the message says what failed and where."""

class Config:
    """riseg-core's settings; ``Config()`` is the paper's defaults with seed 0.

    Fields are read as attributes and set by keyword: ``Config(seed=7)``,
    ``cfg.replace(max_pushes=2)``. An unknown field or an out-of-range value raises
    ``ValueError``. Names and meanings are those of ``riseg config --print``'s ``[core]``.
    """

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
    certain_from: int
    uncertain_from: int
    max_clusters: int
    kmeans_samples: int
    kmeans_iters: int
    region_min_area_m2: float
    region_max_len_m: float
    region_cell_m: float
    pair_max_m: float
    uncertain_max_m: float
    push_len_m: float
    max_pushes: int
    seed: int

    def __init__(self, **overrides: Union[int, float]) -> None: ...
    def replace(self, **overrides: Union[int, float]) -> "Config":
        """A copy with the keyword fields replaced."""
    def to_dict(self) -> dict[str, Union[int, float]]:
        """Every field by name."""

class Intrinsics:
    """Pinhole intrinsics, pixels (OpenCV axes; ``(cx, cy)`` from the top-left pixel's centre)."""

    def __init__(self, fx: float, fy: float, cx: float, cy: float) -> None: ...
    @property
    def fx(self) -> float: ...
    @property
    def fy(self) -> float: ...
    @property
    def cx(self) -> float: ...
    @property
    def cy(self) -> float: ...

class Push:
    """FindAction's push."""

    @property
    def start_px(self) -> tuple[float, float]:
        """Start, pixels ``(u, v)``."""
    @property
    def target_px(self) -> tuple[float, float]:
        """End, pixels ``(u, v)``."""
    @property
    def start_cam_m(self) -> tuple[float, float, float]:
        """Start, camera frame, metres."""
    @property
    def direction_cam(self) -> tuple[float, float, float]:
        """Unit direction, camera frame."""
    @property
    def length_m(self) -> float:
        """Length, metres."""

class Scene:
    """A scene folder in memory; frame ``t`` is the scene after ``t`` pushes."""

    @property
    def frames(self) -> int: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def intrinsics(self) -> Intrinsics: ...
    @property
    def has_truth(self) -> bool: ...
    def rgb(self, t: int) -> npt.NDArray[np.uint8]:
        """Colour of frame ``t``, ``(H, W, 3)``."""
    def depth_m(self, t: int) -> npt.NDArray[np.float32]:
        """Depth of frame ``t``, metres, ``(H, W)``."""
    def labels(self, t: int) -> Optional[npt.NDArray[np.uint16]]:
        """Ground truth of frame ``t``, or ``None`` without ``label/``."""
    def motion_hint(self, t: int) -> Optional[tuple[float, float]]:
        """The flow's motion hint for frame ``t`` (``(dx, dy)`` px): the recorded push's
        image motion, as ``riseg run`` gives it; ``None`` for frame 0."""
    def actions(self) -> list[dict[str, Any]]:
        """The recorded pushes of ``actions.json``."""

def segment(
    rgb: npt.NDArray[np.uint8],
    depth_m: npt.NDArray[np.float32],
    intrinsics: Intrinsics,
) -> tuple[npt.NDArray[np.uint16], npt.NDArray[np.uint8]]:
    """The built-in classical static segmenter: ``(labels, heatmap)``."""

def flow(
    rgb0: npt.NDArray[np.uint8],
    rgb1: npt.NDArray[np.uint8],
    hint: Optional[tuple[float, float]] = None,
) -> npt.NDArray[np.float32]:
    """The built-in DIS optical flow from ``rgb0`` to ``rgb1``, ``(H, W, 2)``."""

def update_mask(
    labels_t: npt.NDArray[np.uint16],
    depth_t: npt.NDArray[np.float32],
    depth_t1: npt.NDArray[np.float32],
    flow: npt.NDArray[np.float32],
    static_t1: npt.NDArray[np.uint16],
    intrinsics: Intrinsics,
    config: Optional[Config] = None,
) -> npt.NDArray[np.uint16]:
    """UpdateMask (Algorithm 3): the accumulated mask at t+1."""

def find_action(
    heatmap: npt.NDArray[np.uint8],
    labels: npt.NDArray[np.uint16],
    depth_m: npt.NDArray[np.float32],
    intrinsics: Intrinsics,
    config: Optional[Config] = None,
) -> Optional[Push]:
    """FindAction (Algorithm 2): the next push, or ``None`` when the loop should stop."""

def metrics(pred: npt.NDArray[np.uint16], gt: npt.NDArray[np.uint16]) -> dict[str, float]:
    """UOIS overlap/boundary P/R/F and the share of objects with overlap F > 0.75."""

def read_scene(path: Union[str, "PathLike[str]"]) -> Scene:
    """Reads a scene folder with riseg's reader (``riseg run``'s rules and messages)."""
