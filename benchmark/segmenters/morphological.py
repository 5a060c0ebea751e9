"""Morphological segmentation (``segmenter=morphological``): erode the free space until rooms
break off, record them as seeds, grow them back (see :mod:`benchmark.segmenters.common`)."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from scipy import ndimage

from benchmark.interfaces import Segmenter
from benchmark.segmenters.common import FOUR, check_area_limits, check_room_area, finish_rooms
from envs.maps.gridmap import GridMap
from envs.ranges import NonNegative, Positive


class Morphological(Segmenter):
    """Erode until rooms break off, then grow back.

    Args:
        min_seed_area, max_area: room seed area limits, square metres (measured on the
            eroded map).
        min_room_area: rooms smaller than this (square metres) merge into the neighbour
            sharing the longest border (:func:`benchmark.segmenters.common.merge_small_rooms`).
    """

    def __init__(self, min_seed_area: Annotated[float, NonNegative()] = 0.5,
                 max_area: Annotated[float, Positive()] = 60.0,
                 min_room_area: Annotated[float, NonNegative()] = 1.0):
        self.min_seed_area, self.max_area = min_seed_area, max_area
        self.min_room_area = check_room_area(min_room_area)

    def __call__(self, grid: GridMap) -> np.ndarray:
        """Returns: (H, W) int32 room ids on walkable cells, -1 elsewhere."""
        lo, hi = check_area_limits(grid, self.min_seed_area, self.max_area)
        work = grid.walkable.copy()
        prev, _ = ndimage.label(work, FOUR)
        seeds = np.zeros(grid.shape, np.int32)
        k = 0
        while work.any():
            lab, n = ndimage.label(work, FOUR)
            # each part lies inside one part of the step before (the free space only shrinks):
            # any of its cells names that parent (the background's entry is never read)
            parent = np.zeros(n + 1, np.int64)
            parent[lab.ravel()] = prev.ravel()
            sizes = np.bincount(lab.ravel(), minlength=n + 1)
            # a real split: at least two parts of room size (>= min_seed_area) from one parent
            big = np.nonzero(sizes[1:] >= lo)[0] + 1
            siblings = np.bincount(parent[big], minlength=prev.max() + 1)
            nxt = ndimage.binary_erosion(work, np.ones((3, 3), bool))
            alive = np.bincount(lab[nxt], minlength=n + 1) > 0
            for i in range(1, n + 1):
                broke_off = siblings[parent[i]] >= 2 or not alive[i]
                if broke_off and lo <= sizes[i] <= hi:
                    k += 1
                    part = lab == i
                    seeds[part] = k
                    nxt &= ~part
            prev, work = lab, nxt
        return finish_rooms(seeds, grid, self.min_room_area)
