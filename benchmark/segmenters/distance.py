"""Distance-transform segmentation (``segmenter=distance``): sweep a threshold over the
distance-to-obstacle map, keep the one with the most room-sized parts as seeds."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from scipy import ndimage

from benchmark.interfaces import Segmenter
from benchmark.segmenters.common import FOUR, check_area_limits, check_room_area, finish_rooms
from envs.maps.gridmap import GridMap
from envs.ranges import NonNegative, Positive


class DistanceTransform(Segmenter):
    """Threshold sweep on the distance map.

    Args:
        min_seed_area: smallest seed, square metres (a part of the free space above the
            threshold; the threshold with the most such parts wins).
        max_area: largest room, square metres (seeds above it are still kept: no smaller
            split exists at that threshold).
        step: threshold step, metres.
        min_room_area: rooms smaller than this (square metres) merge into the neighbour
            sharing the longest border (:func:`benchmark.segmenters.common.merge_small_rooms`).
    """

    def __init__(self, min_seed_area: Annotated[float, NonNegative()] = 0.5,
                 max_area: Annotated[float, Positive()] = 60.0, step: Annotated[float, Positive()] = 0.05,
                 min_room_area: Annotated[float, NonNegative()] = 1.0):
        self.min_seed_area, self.max_area, self.step = min_seed_area, max_area, step
        self.min_room_area = check_room_area(min_room_area)

    def __call__(self, grid: GridMap) -> np.ndarray:
        """Returns: (H, W) int32 room ids on walkable cells, -1 elsewhere."""
        lo, _ = check_area_limits(grid, self.min_seed_area, self.max_area)
        edt = ndimage.distance_transform_edt(grid.walkable)  # pixels: the watershed's too
        dist = edt * grid.resolution
        best, best_seeds = -1, None
        for t in np.arange(0.0, dist.max(), max(self.step, grid.resolution)):
            lab, n = ndimage.label(dist > t, FOUR)
            sizes = np.bincount(lab.ravel())
            keep = np.nonzero(sizes[1:] >= lo)[0] + 1
            if len(keep) > best:
                best = len(keep)
                number = np.zeros(n + 1, np.int32)  # the kept parts numbered 1.. in label order
                number[keep] = np.arange(1, len(keep) + 1)
                best_seeds = number[lab]
        return finish_rooms(best_seeds, grid, self.min_room_area, edt)
