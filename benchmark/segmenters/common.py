"""Shared by the geometric segmenters: input checks and growing seeds back over the free space.

Geometry-only room segmentation of an occupancy map (the classic baselines, our own
implementations; simplified where noted). Each is called ``seg(grid) -> (H, W) int32``
instance ids on walkable cells, -1 elsewhere; room-area limits are in square metres.

All three find one *seed* region per room and grow the seeds back over the free space with
a watershed on the distance map (scikit-image), so every walkable cell connected to a seed
gets a room; a walkable component with no seed becomes one room of its own. Then every
room smaller than ``min_room_area`` is merged into a neighbour (:func:`merge_small_rooms`),
as the ipa_room_segmentation implementations merge small rooms: the fragments that clutter
leaves (a strip between a desk and a wall, the free space around a chair) join the room
around them instead of counting as rooms.

* :class:`Morphological` — erode the free space step by step (3 x 3); whenever a connected
  part of room size breaks off from another part of room size (or is about to vanish),
  with an area between ``min_seed_area`` and ``max_area``, record it as a room seed and
  remove it; specks smaller than ``min_seed_area`` do not count as a split; continue until
  nothing is left.
* :class:`DistanceTransform` — sweep a threshold over the distance-to-obstacle map and keep
  the threshold that gives the most parts of at least ``min_seed_area`` (the lowest such
  threshold on a tie); those parts are the seeds.
* :class:`Voronoi` (simplified) — the classic critical-point method: the skeleton of the
  free space (the medial axis, i.e. the Voronoi graph of the obstacles; the map edge counts
  as an obstacle), pruned as the authors prune their Voronoi graph (its spurs into corners,
  alcoves and pockets between furniture removed back to their junctions,
  :func:`benchmark.segmenters.voronoi.prune_spurs`); *critical points* are skeleton pixels on
  a plain stretch of it (two skeleton neighbours: no junction, no tip) whose clearance is the
  smallest within ``window`` metres, at most ``max_door`` / 2, and at least ``widening``
  times smaller than the largest clearance on the skeleton within ``2 * window`` (a narrowing
  with wider space beyond). Each critical point cuts the free space with the *critical line*:
  8-connected segments from the point to its nearest obstacle pixel and to the nearest
  obstacle pixel on the opposite side (more than 105 degrees away). Every part of the cut free
  space is a seed; parts under ``min_room_area`` join their neighbours by the merge rule.
  Simplified: the authors' critical points (the clearance minimum of every stretch of the
  graph, thinned by the angle of their lines) and their merging of rooms (five passes of rules
  on area, wall share and shared border) are replaced by the narrowing rule above and that area
  rule (VRF learns its merges), so it over-segments cluttered maps. ``rule=original``
  (``segmenter=voronoi_original``) takes the authors' graph, critical points and merging
  passes instead (:mod:`benchmark.segmenters.voronoi_original`).

``min_seed_area`` (distance, morphological) and ``min_room_area`` (all three) are different
things: the first is the area of a seed *while* it is found (a part of the thresholded or
eroded free space, much smaller than its room), the second the area of a finished room.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import numpy as np
from skimage.segmentation import watershed

from envs.atomic import pid_alive
from envs.maps.components import components
from envs.maps.distance import distance_px
from envs.maps.gridmap import GridMap
from envs.maps.ids import dense_ids


def grow_seeds(seeds: np.ndarray, walkable: np.ndarray, dist: np.ndarray | None = None) -> np.ndarray:
    """Grow labelled seeds (0 = none) over ``walkable`` by a watershed on the distance map
    (``dist``: :func:`envs.maps.distance.distance_px` of ``walkable``, when the caller has it);
    walkable components without a seed become extra rooms. Returns ids 0..K-1, -1 elsewhere."""
    if dist is None:
        dist = distance_px(walkable)
    lab = watershed(-dist, seeds, mask=walkable, connectivity=1)
    orphan, n = components(walkable & (lab == 0))
    if n:
        lab[orphan > 0] = orphan[orphan > 0] + lab.max()
    out = np.full(walkable.shape, -1, np.int32)
    grown = lab > 0
    out[grown] = dense_ids(lab[grown])[0]
    return out


def check_area_limits(grid: GridMap, min_area: float, max_area: float, names: str = "min_seed_area < max_area"
                      ) -> tuple[float, float]:
    """The area limits in pixels at the grid's resolution (one line when they are bad)."""
    if not grid.walkable.any():
        raise ValueError("geometric segmentation needs a map with walkable cells")
    if min_area < 0 or max_area <= min_area:
        raise ValueError(f"segmenter area limits must satisfy 0 <= {names}, got {min_area}, {max_area} "
                         f"(square metres)")
    px = grid.resolution ** 2
    return min_area / px, max_area / px


def check_room_area(min_room_area) -> float:
    """``min_room_area`` (square metres) as a float >= 0, or one line naming the setting."""
    if isinstance(min_room_area, bool) or not isinstance(min_room_area, (int, float)) or not min_room_area >= 0:
        raise ValueError(f"segmenter.min_room_area is {min_room_area!r}; expected an area >= 0 in square metres")
    return float(min_room_area)


def merge_small_rooms(instances: np.ndarray, walkable: np.ndarray, min_pixels: float) -> np.ndarray:
    """Merge every room smaller than ``min_pixels`` into a neighbour, smallest first.

    The rule, as ipa_room_segmentation's merging of small rooms: a room under the limit
    joins the neighbouring room with which it shares the *longest border* (the most
    4-adjacent pixel pairs, one in each room); a tie goes to the larger neighbour, then to
    the lower id. Rooms are taken smallest first (ties: lower id) and sizes and borders are
    updated after each merge, so a fragment between two small rooms ends where the merged
    rooms do. A room under the limit with no neighbouring room (an island of free space)
    stays as it is.

    Args:
        instances: (H, W) int room ids >= 0 on walkable cells, -1 elsewhere.
        walkable: (H, W) bool; ids off it are ignored (set to -1).
        min_pixels: rooms with fewer pixels than this are merged (0: nothing changes).

    Returns:
        (H, W) int32 ids 0..K-1 (old ids' order kept), -1 off the rooms.
    """
    inst = np.where(np.asarray(walkable, bool), np.asarray(instances), -1).astype(np.int64)
    out = np.full(inst.shape, -1, np.int32)
    m = inst >= 0
    if not m.any():
        return out
    # the ids present, in order, and each cell's rank among them
    lab = np.full(inst.shape, -1, np.int64)
    lab[m], n = dense_ids(inst[m])
    size = np.bincount(lab[m], minlength=n).astype(np.int64)
    # borders: 4-adjacent pixel pairs of two different rooms, counted per unordered pair
    pairs = []
    for a, b in ((lab[:, :-1], lab[:, 1:]), (lab[:-1, :], lab[1:, :])):
        k = (a >= 0) & (b >= 0) & (a != b)
        lo, hi = np.minimum(a[k], b[k]), np.maximum(a[k], b[k])
        pairs.append(lo * n + hi)
    keys, counts = np.unique(np.concatenate(pairs), return_counts=True) if n > 1 else (np.zeros(0, np.int64),) * 2
    border: list[dict[int, int]] = [{} for _ in range(n)]
    for key, cnt in zip(keys.tolist(), counts.tolist()):
        i, j = divmod(key, n)
        border[i][j] = border[j][i] = cnt
    parent = np.arange(n)
    alive = np.ones(n, bool)
    while True:
        small = np.nonzero(alive & (size < min_pixels))[0]
        small = [i for i in small.tolist() if border[i]]
        if not small:
            break
        i = min(small, key=lambda r: (size[r], r))
        j = max(border[i], key=lambda r: (border[i][r], size[r], -r))
        # merge room i into room j
        parent[parent == i] = j
        size[j] += size[i]
        size[i] = 0
        alive[i] = False
        for r, cnt in border[i].items():
            del border[r][i]
            if r != j:
                border[r][j] = border[j][r] = border[j].get(r, 0) + cnt
        border[i] = {}
    kept = np.nonzero(alive)[0]
    new_id = np.full(n, -1, np.int64)
    new_id[kept] = np.arange(len(kept))
    out[m] = new_id[parent[lab[m]]]
    return out


def finish_rooms(seeds: np.ndarray, grid: GridMap, min_room_area: float, dist: np.ndarray | None = None) -> np.ndarray:
    """Seeds -> rooms: :func:`grow_seeds` over the walkable cells, then
    :func:`merge_small_rooms` with ``min_room_area`` (square metres) at the grid's
    resolution. The last step of every geometric segmenter.

    Args:
        dist: the walkable cells' distance transform in pixels, when the segmenter made it.

    Returns:
        (H, W) int32 room ids 0..K-1 on walkable cells, -1 elsewhere.
    """
    rooms = grow_seeds(seeds, grid.walkable, dist)
    return merge_small_rooms(rooms, grid.walkable, check_room_area(min_room_area) / grid.resolution ** 2)


__all__ = ["grow_seeds", "check_area_limits", "check_room_area", "finish_rooms", "merge_small_rooms"]


def clean_dead_tmp(prefix: str) -> list[Path]:
    """Remove the folders ``<tmp>/<prefix><pid>-*`` of processes that are gone (an external
    segmenter's driver folders, killed before they could remove their own); returns those removed."""
    removed = []
    for p in Path(tempfile.gettempdir()).glob(f"{prefix}*-*"):
        pid = p.name[len(prefix):].split("-", 1)[0]
        if pid.isdigit() and not pid_alive(int(pid)):
            shutil.rmtree(p, ignore_errors=True)
            removed.append(p)
    return removed
