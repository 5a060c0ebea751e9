"""Sanity rows for every comparison table (docs/metrics.md): segmentations that know nothing
(one room, a fixed grid) or everything (the ground truth's own rooms). A metric worth reading
ranks one room below every real method and gives the ground-truth geometry 100.

* :class:`OneRoom` — the whole walkable map as one segment.
* :class:`Grid` — squares of ``size`` metres from the map's top-left corner, cut to the
  walkable cells; each square is one segment (its pieces, if walls cut it, stay one id).
* :class:`GroundTruthGeometry` — the scene's room instances, unchanged. It needs the ground
  truth, so it declares ``uses_scene = True`` and the runner calls it as
  ``seg(grid, scene=scene)``; a plain ``seg(grid)`` is an error.

All return (H, W) int32 instance ids on walkable cells, -1 elsewhere, like the geometric
segmenters.
"""

from __future__ import annotations

import numpy as np

from benchmark.interfaces import Segmenter
from envs.maps.gridmap import GridMap
from envs.maps.ids import dense_ids


class OneRoom(Segmenter):
    """Every walkable cell in segment 0."""

    def __call__(self, grid: GridMap) -> np.ndarray:
        """Returns: (H, W) int32, 0 on walkable cells, -1 elsewhere."""
        return np.where(np.asarray(grid.walkable, bool), 0, -1).astype(np.int32)


class Grid(Segmenter):
    """Squares of ``size`` metres (pixel rows/columns ``floor(i * resolution / size)``).

    Args:
        size: side of a square, metres (> 0).
    """

    def __init__(self, size: float = 3.0):
        if not size > 0:
            raise ValueError(f"grid segmenter: size must be > 0 metres, got {size!r}")
        self.size = float(size)

    def __call__(self, grid: GridMap) -> np.ndarray:
        """Returns: (H, W) int32 square ids 0..K-1 (numbered in raster order of the squares
        that hold a walkable cell) on walkable cells, -1 elsewhere."""
        walk = np.asarray(grid.walkable, bool)
        h, w = walk.shape
        rows = np.floor(np.arange(h) * grid.resolution / self.size).astype(np.int64)
        cols = np.floor(np.arange(w) * grid.resolution / self.size).astype(np.int64)
        cell = rows[:, None] * (int(cols.max()) + 1) + cols[None, :]
        out = np.full(walk.shape, -1, dtype=np.int32)
        if walk.any():
            out[walk] = dense_ids(cell[walk])[0]
        return out


class GroundTruthGeometry(Segmenter):
    """The ground truth's own rooms as the segmentation (perfect segments, no classes)."""

    uses_scene = True

    def __call__(self, grid: GridMap, scene=None) -> np.ndarray:
        """Returns: ``scene.instances`` as (H, W) int32."""
        if scene is None:
            raise ValueError("segmenter gt_geometry needs the scene's ground truth: call it as seg(grid, scene=scene)")
        inst = np.asarray(scene.instances)
        if inst.shape != np.asarray(grid.walkable).shape:
            raise ValueError(f"gt_geometry: ground truth shape {inst.shape} differs from map shape "
                             f"{np.asarray(grid.walkable).shape}")
        return inst.astype(np.int32)
