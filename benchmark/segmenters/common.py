"""Shared by the geometric segmenters: input checks and growing seeds back over the free space.

Geometry-only room segmentation of an occupancy map (the classic baselines, our own
implementations; simplified where noted). Each is called ``seg(grid) -> (H, W) int32``
instance ids on walkable cells, -1 elsewhere; room-area limits are in square metres.

All three find one *seed* region per room and grow the seeds back over the free space with
a watershed on the distance map (scikit-image), so every walkable cell connected to a seed
gets a room; a walkable component with no seed becomes one room of its own.

* :class:`Morphological` — erode the free space step by step (3 x 3); whenever a connected
  part of room size breaks off from another part of room size (or is about to vanish),
  with an area between ``min_area`` and ``max_area``, record it as a room seed and remove
  it; specks smaller than ``min_area`` do not count as a split; continue until nothing is
  left.
* :class:`DistanceTransform` — sweep a threshold over the distance-to-obstacle map and keep
  the threshold that gives the most parts of at least ``min_area`` (the lowest such
  threshold on a tie); those parts are the seeds.
* :class:`Voronoi` (simplified) — the classic critical-point method: the skeleton of the
  free space (the medial axis, i.e. the Voronoi graph of the obstacles; the map edge counts
  as an obstacle); *critical points* are skeleton pixels on a plain stretch of it (two
  skeleton neighbours: no junction, no tip) whose clearance is the smallest within
  ``window`` metres, at most ``max_door`` / 2, and at least ``widening`` times smaller than
  the largest clearance on the skeleton within ``2 * window`` (a narrowing with wider space
  beyond). Each critical point cuts the free space with the *critical line*: 8-connected
  segments from the point to its nearest obstacle pixel and to the nearest obstacle pixel
  on the opposite side (more than 105 degrees away). The parts of at least ``min_area`` are
  the seeds; smaller parts join their neighbours through the growing step. Simplified:
  no skeleton pruning and no merging of rooms beyond that area rule (the full method and
  VRF learn or hand-tune merges), so it over-segments cluttered maps.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from skimage.segmentation import watershed

from envs.maps.gridmap import GridMap

FOUR = ndimage.generate_binary_structure(2, 1)


def grow_seeds(seeds: np.ndarray, walkable: np.ndarray) -> np.ndarray:
    """Grow labelled seeds (0 = none) over ``walkable`` by a watershed on the distance map;
    walkable components without a seed become extra rooms. Returns ids 0..K-1, -1 elsewhere."""
    dist = ndimage.distance_transform_edt(walkable)
    lab = watershed(-dist, seeds, mask=walkable, connectivity=1)
    orphan, n = ndimage.label(walkable & (lab == 0), FOUR)
    if n:
        lab[orphan > 0] = orphan[orphan > 0] + lab.max()
    out = np.full(walkable.shape, -1, np.int32)
    ids = np.unique(lab[lab > 0])
    remap = np.zeros(lab.max() + 1, np.int32)
    remap[ids] = np.arange(len(ids))
    out[lab > 0] = remap[lab[lab > 0]]
    return out


def check_area_limits(grid: GridMap, min_area: float, max_area: float) -> tuple[float, float]:
    if not grid.walkable.any():
        raise ValueError("geometric segmentation needs a map with walkable cells")
    if min_area < 0 or max_area <= min_area:
        raise ValueError(f"room area limits must satisfy 0 <= min_area < max_area, got {min_area}, {max_area}")
    px = grid.resolution ** 2
    return min_area / px, max_area / px

__all__ = ["grow_seeds", "check_area_limits", "FOUR"]
