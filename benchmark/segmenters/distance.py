"""Distance-transform segmentation (``segmenter=distance``): sweep a threshold over the
distance-to-obstacle map, keep the one with the most room-sized parts as seeds."""

from __future__ import annotations

from typing import Annotated

import numpy as np

from benchmark.interfaces import Segmenter
from benchmark.segmenters.common import check_area_limits, check_room_area, finish_rooms
from envs.kernel_cache import njit
from envs.maps.components import components
from envs.maps.distance import distance_px
from envs.maps.gridmap import GridMap
from envs.maps.union_find import find_root
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
        edt = distance_px(grid.walkable)  # pixels (SciPy's exact transform, by OpenCV): the watershed's too
        dist = edt * grid.resolution
        thresholds = np.arange(0.0, dist.max(), max(self.step, grid.resolution))
        # the lowest threshold with the most parts of seed size, then its parts
        t = thresholds[int(np.argmax(parts_per_threshold(dist, thresholds, lo)))]
        lab, n = components(dist > t)
        keep = np.nonzero(np.bincount(lab.ravel())[1:] >= lo)[0] + 1
        number = np.zeros(n + 1, np.int32)  # the kept parts numbered 1.. in label order
        number[keep] = np.arange(1, len(keep) + 1)
        return finish_rooms(number[lab], grid, self.min_room_area, edt)


def parts_per_threshold(dist: np.ndarray, thresholds: np.ndarray, min_pixels: float) -> np.ndarray:
    """For each threshold t, how many 4-connected parts of ``dist > t`` have at least
    ``min_pixels`` cells: one sweep from the highest threshold down, adding each cell as the
    threshold passes below its distance and joining it to its neighbours (union-find), instead
    of labelling the map once per threshold.

    Args:
        dist: (H, W) float distance to the nearest obstacle (any unit; 0 off the free space).
        thresholds: (T,) ascending, in ``dist``'s unit.
        min_pixels: the smallest part counted, cells.

    Returns:
        (T,) int64 counts.
    """
    thresholds = np.asarray(thresholds, np.float64)
    # a cell is in the part map of threshold k exactly when k < level (thresholds below its distance)
    index = np.int32 if dist.size < 2**31 else np.int64  # cell indices (and sizes) in 4 bytes where they fit
    level = np.searchsorted(thresholds, np.asarray(dist, np.float64).ravel(), side="left").astype(index)
    # the cells by level, highest first, ties in index order (a stable sort; on 16-bit keys NumPy's
    # is a radix sort, the same order in a fraction of the time)
    keys = -level.astype(np.int16) if len(thresholds) < 2**15 else -level
    order = np.argsort(keys, kind="stable").astype(index)
    return _parts_sweep(level, order, np.arange(dist.size, dtype=index), np.zeros(dist.size, index),
                        dist.shape[1], len(thresholds), float(min_pixels))


@njit(cache=True, nogil=True)
def _parts_sweep(level, order, parent, size, w, n_t, min_pixels):
    """:func:`parts_per_threshold`'s sweep: ``parent`` (the cells 0..H W - 1) and ``size``
    (zeros) are the union-find's, of the cell index type."""
    h = parent.shape[0] // w
    inside = np.zeros(parent.shape[0], np.bool_)
    counts = np.zeros(n_t, np.int64)
    big = 0
    q = 0
    for k in range(n_t - 1, -1, -1):
        while q < order.shape[0] and level[order[q]] > k:  # the cells above threshold k join
            p = order[q]
            q += 1
            inside[p] = True
            size[p] = 1
            if 1 >= min_pixels:
                big += 1
            r = p // w
            c = p % w
            for d in range(4):
                if d == 0:
                    if r == 0:
                        continue
                    o = p - w
                elif d == 1:
                    if r == h - 1:
                        continue
                    o = p + w
                elif d == 2:
                    if c == 0:
                        continue
                    o = p - 1
                else:
                    if c == w - 1:
                        continue
                    o = p + 1
                if not inside[o]:
                    continue
                a = find_root(parent, p)
                b = find_root(parent, o)
                if a == b:
                    continue
                if size[a] >= min_pixels:
                    big -= 1
                if size[b] >= min_pixels:
                    big -= 1
                if size[a] < size[b]:
                    a, b = b, a
                parent[b] = a
                size[a] += size[b]
                if size[a] >= min_pixels:
                    big += 1
        counts[k] = big
    return counts
