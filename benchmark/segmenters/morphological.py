"""Morphological segmentation (``segmenter=morphological``): erode the free space until rooms
break off, record them as seeds, grow them back (see :mod:`benchmark.segmenters.common`).

``rule="limits"`` takes seeds as ipa_room_segmentation's original does instead: after every
erosion step, each part of the eroded free space whose area lies between the limits is a seed
at once, whether or not anything broke off (docs/baselines.md, "The ports against the
originals", for what that changes)."""

from __future__ import annotations

from typing import Annotated

import cv2
import numpy as np

from benchmark.interfaces import Segmenter
from benchmark.segmenters.common import check_area_limits, check_room_area, finish_rooms
from envs.maps.components import components
from envs.maps.gridmap import GridMap
from envs.ranges import NonNegative, OneOf, Positive


class Morphological(Segmenter):
    """Erode until rooms break off, then grow back.

    Args:
        min_seed_area, max_area: room seed area limits, square metres (measured on the
            eroded map).
        min_room_area: rooms smaller than this (square metres) merge into the neighbour
            sharing the longest border (:func:`benchmark.segmenters.common.merge_small_rooms`).
        rule: ``split`` (the default): a part is a seed when it breaks off from a part of
            room size or is about to vanish; ``limits``: the original's rule, every part
            (8-connected, as OpenCV's contours) strictly between the area limits after an
            erosion step is a seed at once.
    """

    def __init__(self, min_seed_area: Annotated[float, NonNegative()] = 0.5,
                 max_area: Annotated[float, Positive()] = 60.0,
                 min_room_area: Annotated[float, NonNegative()] = 1.0,
                 rule: Annotated[str, OneOf("split", "limits")] = "split"):
        if rule not in ("split", "limits"):
            raise ValueError(f"segmenter.rule={rule!r}: expected split or limits")
        self.min_seed_area, self.max_area, self.rule = min_seed_area, max_area, rule
        self.min_room_area = check_room_area(min_room_area)

    def __call__(self, grid: GridMap) -> np.ndarray:
        """Returns: (H, W) int32 room ids on walkable cells, -1 elsewhere."""
        lo, hi = check_area_limits(grid, self.min_seed_area, self.max_area)
        if self.rule == "limits":
            return finish_rooms(limit_seeds(grid.walkable, lo, hi), grid, self.min_room_area)
        work = grid.walkable.copy()
        prev, _ = components(work)
        seeds = np.zeros(grid.shape, np.int32)
        square = np.ones((3, 3), np.uint8)
        k = 0
        while work.any():
            lab, n = components(work)
            # each part lies inside one part of the step before (the free space only shrinks):
            # any of its cells names that parent (the background's entry is never read)
            parent = np.zeros(n + 1, np.int64)
            parent[lab.ravel()] = prev.ravel()
            sizes = np.bincount(lab.ravel(), minlength=n + 1)
            # a real split: at least two parts of room size (>= min_seed_area) from one parent
            big = np.nonzero(sizes[1:] >= lo)[0] + 1
            siblings = np.bincount(parent[big], minlength=prev.max() + 1)
            # one 3 x 3 erosion step, cells beyond the map's edge counting as obstacles (OpenCV's
            # erosion of 0/1 cells is scipy's binary_erosion with border_value 0, cell for cell)
            nxt = cv2.erode(work.view(np.uint8), square, borderType=cv2.BORDER_CONSTANT, borderValue=0).view(bool)
            alive = np.bincount(lab[nxt], minlength=n + 1) > 0
            # parts that broke off (or are about to vanish) with a seed's size, numbered in order
            keep = (siblings[parent] >= 2) | ~alive
            keep &= (lo <= sizes) & (sizes <= hi)
            keep[0] = False
            if keep.any():
                k, part = _take_seeds(seeds, lab, keep, k)
                nxt &= ~part
            prev, work = lab, nxt
        return finish_rooms(seeds, grid, self.min_room_area)


def limit_seeds(walkable: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """ipa_room_segmentation's morphological seeds: erode the free space one 3 x 3 step at a
    time; after each step every part of it (8-connected) with more than ``lo`` and fewer than
    ``hi`` cells is a seed (numbered in order) and leaves the map; until nothing is left.
    Areas are cell counts (the original measures OpenCV's contour polygons, a little smaller,
    and stops after 73 steps, 3.65 m at its 0.05 m/px).

    Returns:
        (H, W) int32 seed numbers 1.., 0 elsewhere.
    """
    work = np.asarray(walkable, bool).copy()
    seeds = np.zeros(work.shape, np.int32)
    square = np.ones((3, 3), np.uint8)
    k = 0
    while work.any():
        work = cv2.erode(work.view(np.uint8), square, borderType=cv2.BORDER_CONSTANT, borderValue=0).view(bool)
        lab, n = components(work, 8)
        sizes = np.bincount(lab.ravel(), minlength=n + 1)
        keep = (lo < sizes) & (sizes < hi)
        keep[0] = False
        if keep.any():
            k, part = _take_seeds(seeds, lab, keep, k)
            work &= ~part
    return seeds


def _take_seeds(seeds: np.ndarray, lab: np.ndarray, keep: np.ndarray, k: int) -> tuple[int, np.ndarray]:
    """Write the parts of ``lab`` (H, W labels) that ``keep`` (n + 1,) bool marks into ``seeds``
    as seeds ``k + 1..``, numbered in label order; (the last seed number, (H, W) bool their cells)."""
    number = np.where(keep, np.cumsum(keep) + k, 0).astype(np.int32)
    mark = number[lab]
    part = mark > 0
    seeds[part] = mark[part]
    return k + int(keep.sum()), part
