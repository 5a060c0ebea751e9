"""Geometry-only room segmentation of an occupancy map (the classic baselines, our own
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
* :class:`Voronoi` (simplified) — skeleton of the free space (the medial axis, i.e. the
  Voronoi graph of the obstacles); *critical points* are skeleton pixels whose clearance is
  a local minimum within ``window`` metres and below ``max_door`` / 2 (door-like
  narrowings); the free space is cut with a disc of that clearance around each critical
  point, and the resulting parts of at least ``min_area`` are the seeds. (The classic method
  cuts with the segment to the two nearest obstacle points; the disc is our simplification.)
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from skimage.morphology import skeletonize
from skimage.segmentation import watershed

from envs.gridmap import GridMap

_FOUR = ndimage.generate_binary_structure(2, 1)


def grow_seeds(seeds: np.ndarray, walkable: np.ndarray) -> np.ndarray:
    """Grow labelled seeds (0 = none) over ``walkable`` by a watershed on the distance map;
    walkable components without a seed become extra rooms. Returns ids 0..K-1, -1 elsewhere."""
    dist = ndimage.distance_transform_edt(walkable)
    lab = watershed(-dist, seeds, mask=walkable, connectivity=1)
    orphan, n = ndimage.label(walkable & (lab == 0), _FOUR)
    if n:
        lab[orphan > 0] = orphan[orphan > 0] + lab.max()
    out = np.full(walkable.shape, -1, np.int32)
    ids = np.unique(lab[lab > 0])
    remap = np.zeros(lab.max() + 1, np.int32)
    remap[ids] = np.arange(len(ids))
    out[lab > 0] = remap[lab[lab > 0]]
    return out


def _check(grid: GridMap, min_area: float, max_area: float) -> tuple[float, float]:
    if not grid.walkable.any():
        raise ValueError("geometric segmentation needs a map with walkable cells")
    if min_area < 0 or max_area <= min_area:
        raise ValueError(f"room area limits must satisfy 0 <= min_area < max_area, got {min_area}, {max_area}")
    px = grid.resolution ** 2
    return min_area / px, max_area / px


class Morphological:
    """Erode until rooms break off, then grow back.

    Args: min_area, max_area: room seed area limits, square metres (measured on the eroded map).
    """

    def __init__(self, min_area: float = 0.5, max_area: float = 60.0):
        self.min_area, self.max_area = min_area, max_area

    def __call__(self, grid: GridMap) -> np.ndarray:
        lo, hi = _check(grid, self.min_area, self.max_area)
        work = grid.walkable.copy()
        prev, _ = ndimage.label(work, _FOUR)
        seeds = np.zeros(grid.shape, np.int32)
        k = 0
        while work.any():
            lab, n = ndimage.label(work, _FOUR)
            ids, first = np.unique(lab.ravel(), return_index=True)
            parent = np.zeros(n + 1, np.int64)
            parent[ids] = prev.ravel()[first]
            sizes = np.bincount(lab.ravel(), minlength=n + 1)
            # a real split: at least two parts of room size (>= min_area) from one parent
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
        return grow_seeds(seeds, grid.walkable)


class DistanceTransform:
    """Threshold sweep on the distance map.

    Args: min_area: smallest seed, square metres; max_area: largest room (seeds above it are
    still kept: no smaller split exists at that threshold); step: threshold step, metres.
    """

    def __init__(self, min_area: float = 0.5, max_area: float = 60.0, step: float = 0.05):
        self.min_area, self.max_area, self.step = min_area, max_area, step

    def __call__(self, grid: GridMap) -> np.ndarray:
        lo, _ = _check(grid, self.min_area, self.max_area)
        dist = ndimage.distance_transform_edt(grid.walkable) * grid.resolution
        best, best_seeds = -1, None
        for t in np.arange(0.0, dist.max(), max(self.step, grid.resolution)):
            lab, n = ndimage.label(dist > t, _FOUR)
            sizes = np.bincount(lab.ravel())
            keep = np.nonzero(sizes[1:] >= lo)[0] + 1
            if len(keep) > best:
                best = len(keep)
                seeds = np.zeros(grid.shape, np.int32)
                for j, i in enumerate(keep):
                    seeds[lab == i] = j + 1
                best_seeds = seeds
        return grow_seeds(best_seeds, grid.walkable)


class Voronoi:
    """Cut the free space at critical points of its skeleton (simplified, see module doc).

    Args: min_area: smallest room, square metres; max_door: widest passage treated as a
    door, metres; window: neighbourhood for the clearance minimum, metres.
    """

    def __init__(self, min_area: float = 0.5, max_area: float = 60.0, max_door: float = 1.2, window: float = 0.6):
        self.min_area, self.max_area, self.max_door, self.window = min_area, max_area, max_door, window

    def critical_points(self, grid: GridMap) -> np.ndarray:
        """(M, 3) int rows of (row, col, clearance px) of the chosen critical points."""
        walk = grid.walkable
        dist = ndimage.distance_transform_edt(walk)
        skel = skeletonize(walk) & (dist > 1)
        win = max(int(round(self.window / grid.resolution)), 1) * 2 + 1
        on_skel = np.where(skel, dist, np.inf)
        local_min = ndimage.minimum_filter(on_skel, size=win, mode="constant", cval=np.inf)
        # a narrowing: a local minimum of the clearance with wider space on both sides along the skeleton
        local_max = ndimage.maximum_filter(np.where(skel, dist, 0), size=win * 2 + 1)
        cand = skel & (dist <= local_min) & (dist * grid.resolution <= self.max_door / 2) & (local_max > dist * 1.25)
        lab, n = ndimage.label(cand, np.ones((3, 3), bool))
        pts = []
        for i in range(1, n + 1):
            rr, cc = np.nonzero(lab == i)
            j = np.argmin(dist[rr, cc])
            pts.append((rr[j], cc[j], dist[rr[j], cc[j]]))
        return np.array(pts, dtype=float).reshape(-1, 3)

    def __call__(self, grid: GridMap) -> np.ndarray:
        lo, _ = _check(grid, self.min_area, self.max_area)
        cut = grid.walkable.copy()
        rr, cc = np.mgrid[: grid.shape[0], : grid.shape[1]]
        for r, c, d in self.critical_points(grid):
            rad = d + 1.5
            r0, r1 = int(max(r - rad - 1, 0)), int(min(r + rad + 2, grid.shape[0]))
            c0, c1 = int(max(c - rad - 1, 0)), int(min(c + rad + 2, grid.shape[1]))
            disc = (rr[r0:r1, c0:c1] - r) ** 2 + (cc[r0:r1, c0:c1] - c) ** 2 <= rad ** 2
            cut[r0:r1, c0:c1] &= ~disc
        lab, n = ndimage.label(cut, _FOUR)
        sizes = np.bincount(lab.ravel())
        seeds = np.zeros(grid.shape, np.int32)
        for j, i in enumerate(np.nonzero(sizes[1:] >= lo)[0] + 1):
            seeds[lab == i] = j + 1
        return grow_seeds(seeds, grid.walkable)
