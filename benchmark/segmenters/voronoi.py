"""Voronoi segmentation, simplified (``segmenter=voronoi``): cut the free space with the
critical lines at the narrowings of its skeleton (details: :mod:`benchmark.segmenters.common`).

``rule="original"`` (``segmenter=voronoi_original``) takes ipa_room_segmentation's Voronoi graph,
critical-point rule and merging passes instead (:mod:`benchmark.segmenters.voronoi_original`;
docs/baselines.md, "The ports against the originals", for what that changes)."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from scipy import ndimage
from skimage.draw import line as draw_line
from skimage.morphology import skeletonize

from benchmark.interfaces import Segmenter
from benchmark.segmenters import voronoi_original as original
from benchmark.segmenters.common import check_area_limits, check_room_area, finish_rooms
from envs.kernel_cache import njit
from envs.maps.components import components
from envs.maps.distance import distance_px
from envs.maps.gridmap import GridMap
from envs.ranges import Between, NonNegative, OneOf, Positive


def prune_spurs(skel: np.ndarray, clearance: np.ndarray, room: float) -> np.ndarray:
    """The skeleton without its spurs, as ipa_room_segmentation prunes its Voronoi graph before
    it looks for critical points: the branches into corners and alcoves go back to the junction
    they leave from, so no narrowing on them is taken for a door.

    A tip (a pixel with at most one 8-neighbour on the skeleton, not a junction of the skeleton
    as given: more than two 8-neighbours) goes, again and again until no tip goes, unless its
    clearance is above ``room`` and not smaller than its neighbour's: a branch that ends in a
    room's open middle stays. The thinned skeleton of a bare rectangular room ends there instead
    of forking into the room's corners as the authors' Voronoi graph does, and that branch
    carries the room's door; a branch into a corner, an alcove or a pocket between furniture
    (its tip's clearance under ``room``) goes as the authors' does.

    Args:
        skel: (H, W) bool skeleton.
        clearance: (H, W) float distance to the nearest obstacle, pixels.
        room: the clearance (pixels) above which a tip that is a clearance maximum stays
            (:class:`Voronoi` passes ``max_door / 2``: wider than any door).

    Returns:
        (H, W) bool, the pruned skeleton (tips taken in a fixed order: the same on every run).
    """
    s = np.asarray(skel, bool).copy()
    count = ndimage.convolve(s.astype(np.int32), np.ones((3, 3), np.int32), mode="constant") - s
    node = s & (count > 2)
    tips = np.flatnonzero(s & (count <= 1) & ~node)  # row-major: taken from the last
    _prune(s, count, node, np.ascontiguousarray(clearance, np.float64), float(room), tips, int(s.sum()))
    return s


@njit(cache=True)
def _prune(s, count, node, clearance, room, tips, n):
    """:func:`prune_spurs`' loop, in place on ``s`` and ``count``: a stack of tips (flat indices),
    taken from its end; a tip's 8-neighbours on the skeleton visited row by row. ``n``: the
    skeleton's pixels (each goes at most once, pushing at most 8)."""
    h, w = s.shape
    stack = np.empty(tips.shape[0] + 8 * n, np.int64)
    top = tips.shape[0]
    stack[:top] = tips
    around = np.empty(8, np.int64)
    while top > 0:
        top -= 1
        r, c = divmod(stack[top], w)
        if not s[r, c] or count[r, c] > 1:
            continue
        m = 0
        for rr in range(max(r - 1, 0), min(r + 2, h)):
            for cc in range(max(c - 1, 0), min(c + 2, w)):
                if s[rr, cc] and (rr != r or cc != c):
                    around[m] = rr * w + cc
                    m += 1
        if m and clearance[r, c] >= clearance[around[0] // w, around[0] % w] and clearance[r, c] > room:
            continue
        s[r, c] = False
        for i in range(m):
            rr, cc = divmod(around[i], w)
            count[rr, cc] -= 1
            if count[rr, cc] <= 1 and not node[rr, cc]:
                stack[top] = around[i]
                top += 1


class Voronoi(Segmenter):
    """Cut the free space at the critical points of its skeleton (simplified, see module doc).

    Args:
        min_room_area: smallest room, square metres: smaller parts of the cut free space
            merge into the neighbour sharing the longest border
            (:func:`benchmark.segmenters.common.merge_small_rooms`).
        max_area: largest room, square metres (a larger part is kept whole: the method has
            no finer split; recorded for symmetry with the other baselines).
        max_door: widest passage treated as a door, metres.
        window: neighbourhood in which a critical point's clearance is the smallest, metres.
        widening: a critical point needs skeleton clearance at least ``widening`` times its
            own within ``2 * window`` (ratio), i.e. wider space beyond the narrowing.
        rule: ``narrowing`` (the default): the critical points and merge above; ``original``:
            ipa_room_segmentation's Voronoi graph, critical-point rule and merging passes
            (:mod:`benchmark.segmenters.voronoi_original`), with the settings below (the
            authors' defaults, their pixels at 0.05 m/px in metres); ``max_door``, ``window``
            and ``widening`` are not used.
        reach: ``original``: a critical point's neighbourhood on the graph is ``reach`` /
            its clearance metres long, square metres (the authors' 280 pixels²).
        max_search: ``original``: the longest search for that neighbourhood, metres (150 steps).
        min_critical_distance: ``original``: of two critical points closer than this times the
            first's clearance, the one whose line turns less is dropped (ratio).
        max_merge_area: ``original``: the first merging pass merges cells under this area,
            square metres.
        min_segment_area: ``original``: smaller parts of the cut free space are no cell of
            their own, square metres.
        work_resolution: ``original``: the rule runs on the map resampled (nearest) to this
            many metres per pixel, the authors' 0.05 (their graph's margin from the walls, the
            lines' width and the borders the merging counts are pixels), and its rooms are
            sampled back; null: at the map's own resolution.
    """

    def __init__(self, min_room_area: Annotated[float, NonNegative()] = 1.0,
                 max_area: Annotated[float, Positive()] = 60.0, max_door: Annotated[float, Positive()] = 1.2,
                 window: Annotated[float, Positive()] = 0.6,
                 widening: Annotated[float, Between(1, what="a number >= 1")] = 1.25,
                 rule: Annotated[str, OneOf("narrowing", "original")] = "narrowing",
                 reach: Annotated[float, Positive()] = 0.7, max_search: Annotated[float, Positive()] = 7.5,
                 min_critical_distance: Annotated[float, NonNegative()] = 0.5,
                 max_merge_area: Annotated[float, NonNegative()] = 12.5,
                 min_segment_area: Annotated[float, NonNegative()] = 0.1,
                 work_resolution: Annotated[float | None, Positive()] = 0.05):
        if rule not in ("narrowing", "original"):
            raise ValueError(f"segmenter.rule={rule!r}: expected narrowing or original")
        if max_door <= 0 or window <= 0 or widening < 1:
            raise ValueError(f"Voronoi needs max_door > 0 m, window > 0 m and widening >= 1, got "
                             f"{max_door}, {window}, {widening}")
        if work_resolution is not None and not work_resolution > 0:
            raise ValueError(f"segmenter.work_resolution={work_resolution!r}: expected metres per pixel > 0, or null")
        if not (reach > 0 and max_search > 0 and min_critical_distance >= 0 and max_merge_area >= 0
                and min_segment_area >= 0):
            raise ValueError(f"Voronoi needs reach > 0 m², max_search > 0 m, min_critical_distance >= 0, "
                             f"max_merge_area >= 0 m² and min_segment_area >= 0 m², got {reach}, {max_search}, "
                             f"{min_critical_distance}, {max_merge_area}, {min_segment_area}")
        self.min_room_area, self.max_area, self.max_door = check_room_area(min_room_area), max_area, max_door
        self.window, self.widening, self.rule = window, widening, rule
        self.reach, self.max_search, self.min_critical_distance = reach, max_search, min_critical_distance
        self.max_merge_area, self.min_segment_area = max_merge_area, min_segment_area
        self.work_resolution = None if work_resolution is None else float(work_resolution)

    def critical_points(self, grid: GridMap) -> np.ndarray:
        """(M, 3) float rows of (row, col, clearance px) of the critical points (``narrowing``)."""
        walk = grid.walkable
        dist = distance_px(np.pad(walk, 1))[1:-1, 1:-1]  # the map edge is an obstacle
        skel = prune_spurs(skeletonize(walk) & (dist > 1), dist, self.max_door / 2 / grid.resolution)
        nbrs = ndimage.convolve(skel.astype(np.uint8), np.ones((3, 3), np.uint8), mode="constant") - 1
        win = max(int(round(self.window / grid.resolution)), 1) * 2 + 1
        local_min = ndimage.minimum_filter(np.where(skel, dist, np.inf), size=win, mode="constant", cval=np.inf)
        local_max = ndimage.maximum_filter(np.where(skel, dist, 0), size=win * 2 + 1)
        # a narrowing on a plain stretch of the skeleton (two neighbours: not a junction or a tip)
        cand = (skel & (nbrs == 2) & (dist <= local_min) & (dist * grid.resolution <= self.max_door / 2)
                & (local_max >= dist * self.widening))
        lab, n = components(cand, 8)
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
        ir, ic = ndimage.distance_transform_edt(~obst, return_distances=False, return_indices=True)
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

    def original_rooms(self, grid: GridMap) -> np.ndarray:
        """``rule="original"``: the cells of the authors' critical lines after their merging
        passes ((H, W) int64, ids >= 1 on the cells, 0 on obstacles and on free space no cell
        reached)."""
        res = self.work_resolution or grid.resolution
        walk = grid.walkable if res == grid.resolution else original.resample(grid.walkable, grid.resolution, res)
        if not walk.any():
            raise ValueError(f"segmenter.work_resolution={res}: the map has no walkable cell at that resolution "
                             f"(expected one at most the rooms' size)")
        # the authors' graph, pruned as they prune it: every tip goes back to the junction it leaves from
        graph = prune_spurs(original.voronoi_graph(walk), np.zeros(walk.shape), np.inf)
        clear = original.rounded_clearance(walk)
        # the authors count in whole pixels: 0.7 m² at 0.05 m/px is their 280 (0.7 / 0.05 ** 2 is 279.99...)
        reach_px2, steps = round(self.reach / res ** 2), max(int(round(self.max_search / res)), 1)
        pts = original.critical_points(graph, clear, reach_px2, steps)
        ok, b1, b2, angle, length = original.critical_lines(pts, clear, original.border_pixels(walk))
        pts, b1, b2, angle, length = pts[ok], b1[ok], b2[ok], angle[ok], length[ok]
        keep = original.keep_lines(pts, clear[pts[:, 0], pts[:, 1]], angle, length, self.min_critical_distance)
        lines = [(tuple(p), tuple(q)) for i in np.nonzero(keep)[0] for p, q in ((pts[i], b1[i]), (pts[i], b2[i]))]
        lab = original.merge_cells(original.cells(walk, lines, res, self.min_segment_area), res, self.max_merge_area)
        lab = np.where(lab > 0, lab, 0)
        if res != grid.resolution:
            lab = np.where(grid.walkable, original.sample_back(lab, grid.shape, grid.resolution, res), 0)
        return lab

    def __call__(self, grid: GridMap) -> np.ndarray:
        """Returns: (H, W) int32 room ids on walkable cells, -1 elsewhere."""
        check_area_limits(grid, self.min_room_area, self.max_area, "min_room_area < max_area")
        if self.rule == "original":
            return finish_rooms(self.original_rooms(grid).astype(np.int32), grid, self.min_room_area)
        cut = grid.walkable.copy()
        h, w = grid.shape
        for b1, p, b2 in self.critical_lines(grid):
            for a, b in ((b1, p), (p, b2)):  # 8-connected lines: they separate 4-connected regions
                rr, cc = draw_line(*a, *b)
                ok = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
                cut[rr[ok], cc[ok]] = False
        seeds, _ = components(cut)  # every part of the cut free space is a seed
        return finish_rooms(seeds.astype(np.int32), grid, self.min_room_area)
