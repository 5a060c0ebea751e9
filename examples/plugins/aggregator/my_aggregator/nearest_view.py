"""An aggregator of your own: every walkable cell takes the top class of the nearest view
(straight-line distance, through walls), if that view is within ``max_distance_m``.

Simpler than the bundled ones on purpose: no vote, no line of sight, no geodesic distance.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from scipy.spatial import cKDTree

from envs.ranges import Metres


class NearestView:
    """Nearest view within a radius.

    Args:
        max_distance_m: cells farther than this (metres) from every view stay unlabelled (-1).
    """

    # the annotation is the config check's: aggregator.max_distance_m=-1 is refused in one line
    # before any work (docs/plugins.md, "Value ranges"); the check below is for Python callers
    def __init__(self, max_distance_m: Annotated[float, Metres()] = 3.0):
        if isinstance(max_distance_m, bool) or not isinstance(max_distance_m, int | float) or not max_distance_m > 0:
            raise ValueError(f"aggregator.max_distance_m={max_distance_m!r}: expected a distance > 0 in metres")
        self.max_distance_m = float(max_distance_m)

    def __call__(self, grid, poses: np.ndarray, proba: np.ndarray) -> np.ndarray:
        """Label map.

        Args:
            grid: the GridMap (``walkable`` (H, W) bool, ``pixel_to_world``).
            poses: (N, 3) world x, z (metres) and yaw (degrees) of the views.
            proba: (N, C) class probabilities of the views.
        Returns: (H, W) int32 class indices on walkable cells, -1 elsewhere and beyond the radius.
        """
        out = np.full(grid.walkable.shape, -1, dtype=np.int32)
        if len(poses) == 0:
            return out
        rows, cols = np.nonzero(grid.walkable)
        x, z = grid.pixel_to_world(rows, cols)
        dist, nearest = cKDTree(np.asarray(poses)[:, :2]).query(np.column_stack([x, z]),
                                                                distance_upper_bound=self.max_distance_m)
        reached = np.isfinite(dist)
        out[rows[reached], cols[reached]] = np.argmax(proba, axis=1)[nearest[reached]]
        return out
