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
from skimage.draw import line as draw_line
from skimage.morphology import skeletonize
from skimage.segmentation import watershed

from benchmark.interfaces import Segmenter
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


class Morphological(Segmenter):
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


class DistanceTransform(Segmenter):
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


class Voronoi(Segmenter):
    """Cut the free space at the critical points of its skeleton (simplified, see module doc).

    Args:
        min_area: smallest room, square metres (smaller parts join their neighbours).
        max_area: largest room, square metres (a larger part is kept whole: the method has
            no finer split; recorded for symmetry with the other baselines).
        max_door: widest passage treated as a door, metres.
        window: neighbourhood in which a critical point's clearance is the smallest, metres.
        widening: a critical point needs skeleton clearance at least ``widening`` times its
            own within ``2 * window`` (ratio), i.e. wider space beyond the narrowing.
    """

    def __init__(self, min_area: float = 0.5, max_area: float = 60.0, max_door: float = 1.2, window: float = 0.6,
                 widening: float = 1.25):
        if max_door <= 0 or window <= 0 or widening < 1:
            raise ValueError(f"Voronoi needs max_door > 0 m, window > 0 m and widening >= 1, got "
                             f"{max_door}, {window}, {widening}")
        self.min_area, self.max_area, self.max_door = min_area, max_area, max_door
        self.window, self.widening = window, widening

    def critical_points(self, grid: GridMap) -> np.ndarray:
        """(M, 3) float rows of (row, col, clearance px) of the critical points."""
        walk = grid.walkable
        dist = ndimage.distance_transform_edt(np.pad(walk, 1))[1:-1, 1:-1]  # the map edge is an obstacle
        skel = skeletonize(walk) & (dist > 1)
        nbrs = ndimage.convolve(skel.astype(np.uint8), np.ones((3, 3), np.uint8), mode="constant") - 1
        win = max(int(round(self.window / grid.resolution)), 1) * 2 + 1
        local_min = ndimage.minimum_filter(np.where(skel, dist, np.inf), size=win, mode="constant", cval=np.inf)
        local_max = ndimage.maximum_filter(np.where(skel, dist, 0), size=win * 2 + 1)
        # a narrowing on a plain stretch of the skeleton (two neighbours: not a junction or a tip)
        cand = (skel & (nbrs == 2) & (dist <= local_min) & (dist * grid.resolution <= self.max_door / 2)
                & (local_max >= dist * self.widening))
        lab, n = ndimage.label(cand, np.ones((3, 3), bool))
        pts = []
        for sl, i in zip(ndimage.find_objects(lab), range(1, n + 1)):
            rr, cc = np.nonzero(lab[sl] == i)
            j = np.argmin(dist[sl][rr, cc])
            r, c = rr[j] + sl[0].start, cc[j] + sl[1].start
            pts.append((r, c, dist[r, c]))
        return np.array(pts, dtype=float).reshape(-1, 3)

    def critical_lines(self, grid: GridMap) -> list[tuple[tuple[int, int], tuple[int, int], tuple[int, int]]]:
        """For each critical point, (basis point 1, critical point, basis point 2) as (row, col):
        the nearest obstacle pixel, and the nearest obstacle pixel on the opposite side
        (more than 105 degrees away from the first, seen from the critical point)."""
        obst = ~np.pad(grid.walkable, 1)  # padded: the map edge is an obstacle
        _, (ir, ic) = ndimage.distance_transform_edt(~obst, return_indices=True)
        lines = []
        for r, c, d in self.critical_points(grid):
            r, c = int(r) + 1, int(c) + 1
            b1 = np.array([ir[r, c], ic[r, c]])
            u = b1 - (r, c)
            rad = int(np.ceil(2 * d)) + 2
            r0, c0 = max(r - rad, 0), max(c - rad, 0)
            qr, qc = np.nonzero(obst[r0:r + rad + 1, c0:c + rad + 1])
            v = np.stack([qr + r0 - r, qc + c0 - c], axis=1).astype(float)
            norm = np.hypot(v[:, 0], v[:, 1])
            opposite = v @ u < np.cos(np.deg2rad(105)) * norm * np.hypot(*u)
            if opposite.any():
                k = np.nonzero(opposite)[0][np.argmin(norm[opposite])]
                b2 = (int(v[k, 0]) + r, int(v[k, 1]) + c)
            else:  # no obstacle found on the other side: mirror the first basis point
                b2 = (r - int(u[0]), c - int(u[1]))
            lines.append(((int(b1[0]) - 1, int(b1[1]) - 1), (r - 1, c - 1), (b2[0] - 1, b2[1] - 1)))
        return lines

    def __call__(self, grid: GridMap) -> np.ndarray:
        lo, _ = _check(grid, self.min_area, self.max_area)
        cut = grid.walkable.copy()
        h, w = grid.shape
        for b1, p, b2 in self.critical_lines(grid):
            for a, b in ((b1, p), (p, b2)):  # 8-connected lines: they separate 4-connected regions
                rr, cc = draw_line(*a, *b)
                ok = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
                cut[rr[ok], cc[ok]] = False
        lab, n = ndimage.label(cut, _FOUR)
        sizes = np.bincount(lab.ravel())
        seeds = np.zeros(grid.shape, np.int32)
        for j, i in enumerate(np.nonzero(sizes[1:] >= lo)[0] + 1):
            seeds[lab == i] = j + 1
        return grow_seeds(seeds, grid.walkable)
