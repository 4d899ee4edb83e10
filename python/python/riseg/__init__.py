"""RISeg: interactive object segmentation by pushing, in Rust, over numpy arrays.

One loop step is yours to assemble from any segmenter and flow (see the README):
``segment`` / ``flow`` (built in) or your own models, then ``update_mask`` and
``find_action``; ``metrics`` scores a mask, ``read_scene`` reads a scene folder.
"""

from ._riseg import (
    Config,
    Intrinsics,
    Push,
    RisegError,
    Scene,
    find_action,
    flow,
    metrics,
    read_scene,
    segment,
    update_mask,
)

__all__ = [
    "Config",
    "Intrinsics",
    "Push",
    "RisegError",
    "Scene",
    "find_action",
    "flow",
    "metrics",
    "read_scene",
    "segment",
    "update_mask",
]
