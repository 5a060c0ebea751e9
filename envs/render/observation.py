"""What a camera sees at a pose: the contract between renderers and classifiers."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Observation:
    """One posed view.

    Attributes:
        pose: (x, z, yaw): world metres and simulator yaw in degrees.
        image: optional (H, W, 3) uint8 RGB frame (simulators).
        objects: visible objects as (object type, amount seen) pairs; the amount is the
            renderer's measure (floorplan: share of rays that hit the object; simulators:
            share of image pixels).
        visible_classes: optional (C,) float, the share of the visible floor that belongs
            to each ground-truth class (floorplan renderer; used by the oracle classifier).
        meta: anything else the renderer records (e.g. ``{"refused": True}``).
    """

    pose: tuple[float, float, float]
    image: np.ndarray | None = None
    objects: list[tuple[str, float]] = field(default_factory=list)
    visible_classes: np.ndarray | None = None
    meta: dict = field(default_factory=dict)


def poses_array(poses) -> np.ndarray:
    """Validate and return poses as an (N, 3) float array of (x, z, yaw_deg)."""
    arr = np.asarray(poses, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"poses must be an (N, 3) array of (x, z, yaw_deg), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("poses contain non-finite values")
    return arr
