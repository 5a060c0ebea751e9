"""Vision-cone voting (PAPER.md step 3): labels land where the robot looks.

A view is dropped when its short forward ray (``blocked_ray_m`` metres along its heading)
meets an obstacle. Every other view casts rays over its ``fov`` cone up to ``max_range_m``
metres (the shared routine of :mod:`envs.maps.rays`; obstacles are the non-walkable cells),
and every walkable cell a ray reaches with clear line of sight gets one vote from that view
(its top class, or with ``vote="probability"`` its probability vector); a cell reached by
several rays of one view still gets one vote. The label of a cell is the class with the
most votes summed over the ``window`` x ``window`` pixels around it (ties: lower class
index); walkable cells with no vote in their window stay unlabelled.
Memory: (C, H + 2, W + 2) vote counts (label votes: uint8 while no cell can get 256 votes, from the
views within the cone's reach of it, uint16 below 65,536, else uint32; probability votes:
float32; bordered as the cell state, so that a cell's count sits at the state's own flat
index), an (H + 2, W + 2) int32 cell state (free, blocked or
off the map, and the last view that voted there) and an (H, W) bool obstacle copy, linear in
the map size, and nothing per ray or view: every cone shares one array of ray offsets around
its view's heading, and every ray of a given range one table of paths (:func:`envs.maps.ray_paths.ray_paths`,
about 6 MB at 200 px, kept per range). Neighbouring rays of a view end on neighbouring cells
and share most of their cells; a ray looks up only the cells where its path differs from the
previous ray's (a precomputed list per pair of neighbouring ends, with the cells where it
goes on beyond the previous path's end) below where that ray stopped, so the lookups number
about the cells seen.
"""

from __future__ import annotations

from typing import Annotated

import cv2
import numpy as np

from benchmark.aggregators.common import view_cells
from benchmark.interfaces import Aggregator
from envs.kernel_cache import njit
from envs.maps.gridmap import GridMap
from envs.maps.ray_paths import (
    PATH_CACHE_BYTES,
    after_neighbour_list,
    end_paths,
    neighbour_list,
    path_index,
    path_steps,
    ray_paths,
)
from envs.maps.rays import (
    FREE,
    cone_ends,
    cone_thetas,
    line_start,
    line_step,
    ray_end,
    ray_state,
    trace_ray,
)
from envs.ranges import Angle, NonNegative, Odd, OneOf, Positive


def reach_px(max_range: float) -> int:
    """How far a cone of ``max_range`` pixels votes from its view's cell, along either axis, at
    most: its rays end at :func:`envs.maps.rays.ray_end`'s cell, ``floor(0.5 + max_range)``
    px away at most, and their lines never pass beyond their ends (one pixel spare)."""
    return int(np.ceil(max_range)) + 2


def max_votes_per_cell(shape: tuple[int, int], rows: np.ndarray, cols: np.ndarray, reach: int) -> int:
    """An upper bound on the whole votes any one cell can get: the views within ``reach`` px of
    it along both axes (a view votes at most once per cell). Counted on square tiles of
    ``reach`` px: such views lie in the cell's tile or one of the 8 around it, so the bound is
    the largest 3 x 3 sum of views per tile (a (H / reach) x (W / reach) array, not per pixel).

    Args:
        shape: (H, W) map size, pixels.
        rows, cols: (N,) the views' cells.
        reach: :func:`reach_px` of the cone, pixels (>= 1).

    Returns:
        The bound (0 without views).
    """
    t = max(int(reach), 1)
    th, tw = shape[0] // t + 3, shape[1] // t + 3  # one empty tile around the map
    flat = (np.asarray(rows, np.int64) // t + 1) * tw + np.asarray(cols, np.int64) // t + 1
    tiles = np.bincount(flat, minlength=th * tw).reshape(th, tw)
    near = sum(tiles[1 + a:th - 1 + a, 1 + b:tw - 1 + b] for a in (-1, 0, 1) for b in (-1, 0, 1))
    return int(near.max()) if len(flat) else 0


@njit(cache=True, nogil=True)
def _cone_votes(blocked, state, rows, cols, yaws, offsets, max_range, short_px, labels, votes, counts,
                 k, slot, pm, geo, plen, dstart, dj):
    """Per view: the short forward ray, then the cone's rays in order of heading, each a path of
    :func:`envs.maps.ray_paths.ray_paths` (the digital line of :func:`envs.maps.rays.trace_ray` from the camera to
    the ray's end cell, moved to the camera; it stops before the first blocked cell or off the
    map). A ray whose end cell neighbours the previous ray's shares that ray's cells except at
    the indices the two paths' difference list names: those are looked up, and the rest of
    the previous ray's reach (its cells were free and are voted) is skipped. After a ray that
    saw its whole path, the list goes on with this path's cells beyond that one's end, looked
    up the same way; after one that stopped, the ray is walked on from there only where that
    cell is one of its differences. Any other ray (no
    previous one, a farther end, or an end without a path) is walked whole. ``state`` stamps
    the view on each cell it votes for (one vote per view and cell). The vote is written out at
    each of the three walks: as an inlined helper it made the kernel a quarter slower.
    ``counts`` is (C, H + 2, W + 2), bordered as ``state``: a cell's count is at the state's own
    flat index, so a vote needs no second index. A view's ray ends are found first, all at once
    (:func:`envs.maps.rays.cone_ends`: a loop without a branch, then :func:`envs.maps.rays.ray_end`
    for the rare end near a cell boundary), then their paths (:func:`envs.maps.ray_paths.end_paths`:
    read without a bounds test), then its rays are walked. A view's whole votes go to its class's
    plane of the counts, taken once per view. The path helpers read their arrays without a branch
    (:func:`envs.maps.ray_paths.after_differences` says why). On the perf houses at 0.05 m/px, the
    bordered counts and the ends found first made the votes about 1.2x faster, and the ends all
    at once, the branch-free helpers and the plane per view about 1.3x again (1.15x at 0.02 m/px).
    ``votes`` is the (N, C) float32 probability votes of the views (``labels`` -1), or None for
    whole votes: one for class ``labels[v]`` (none where it is -1). None is a type of its own
    to numba, so the whole-vote kernel is compiled without the probability loop (about 6 %
    faster on the perf houses at 0.05 m/px)."""
    cap = int(np.ceil(max(max_range, short_px))) + 2
    # flat indices along the paths: cell (r, c) is (r + 1) * w2 + c + 1 in the state and in
    # each class's counts (both have the one-cell border)
    w2 = state.shape[1]
    flat_state = state.reshape(-1)
    flat_counts = counts.reshape(counts.shape[0], counts.shape[1] * w2)
    buf_r = np.empty(cap, np.int32)
    buf_c = np.empty(cap, np.int32)
    used = 0
    n_cls = 0 if votes is None else votes.shape[1]
    cos_off = np.cos(offsets)
    sin_off = np.sin(offsets)
    n_rays = offsets.shape[0]
    ends_r = np.empty(n_rays, np.int64)  # a view's ray ends (offsets from its cell) and their paths
    ends_c = np.empty(n_rays, np.int64)
    ends_s = np.empty(n_rays, np.int64)
    exact = np.empty(n_rays, np.bool_)
    # the counts a view votes into (its class's plane); a view without a label votes into a
    # scratch plane no one reads (only the walk that stamps what the cones reach has those)
    junk = np.zeros(flat_state.shape[0] if votes is None and (labels < 0).any() else 0, counts.dtype)
    for v in range(rows.shape[0]):
        r0 = rows[v]
        c0 = cols[v]
        yaw = yaws[v]
        r1, c1 = ray_end(r0, c0, yaw, short_px)
        n, hr, hc = trace_ray(blocked, r0, c0, r1, c1, buf_r, buf_c)
        if hr >= 0:
            continue
        used += 1
        lab = labels[v]
        crow = flat_counts[lab] if lab >= 0 else junk
        base_s = (r0 + 1) * w2 + c0 + 1
        prev = -1
        pstop = 0
        per = 0
        pec = 0
        cone_ends(r0, c0, yaw, offsets, cos_off, sin_off, max_range, ends_r, ends_c, exact)
        end_paths(ends_r, ends_c, max_range, k, slot, ends_s)
        for t in range(n_rays):
            er = ends_r[t]
            ec = ends_c[t]
            s = ends_s[t]
            if s < 0:  # not a precomputed end: walk the line itself
                r1 = r0 + er
                c1 = c0 + ec
                dr, dc, sr, sc, err = line_start(r0, c0, r1, c1)
                r = r0
                c = c0
                while True:
                    x = state[r + 1, c + 1]
                    if x < FREE:
                        break
                    if x != v:
                        state[r + 1, c + 1] = v
                        if votes is None:
                            crow[(r + 1) * w2 + c + 1] += 1
                        else:
                            for q in range(n_cls):
                                counts[q, r + 1, c + 1] += votes[v, q]
                    if r == r1 and c == c1:
                        break
                    r, c, err = line_step(r, c, err, dr, dc, sr, sc)
                prev = -1
                continue
            if s == prev:
                continue
            # cell j of the path, minor coordinate mn: base + j * step + mn * mstep
            step_s, mstep_s = path_steps(geo, s, w2)
            a = er - per
            b = ec - pec
            walk_from = 0
            stop = -1
            ls = plen[s]  # (read once: numba cannot tell that the votes written below leave it alone)
            if prev >= 0 and -1 <= a <= 1 and -1 <= b <= 1:
                whole, lim, i, e = neighbour_list(s, prev, a, b, plen, pstop, dstart)
                while i < e and dj[np.uint64(2 * i)] < lim:
                    j = np.int64(dj[np.uint64(2 * i)])
                    mn = np.int64(dj[np.uint64(2 * i + 1)])
                    fs = path_index(base_s, step_s, mstep_s, j, mn)
                    x = flat_state[fs]
                    if x < FREE:
                        stop = j
                        break
                    if x != v:
                        flat_state[fs] = v
                        if votes is None:
                            crow[fs] += 1
                        else:
                            for q in range(n_cls):
                                flat_counts[q, fs] += votes[v, q]
                    i += 1
                if stop < 0:
                    walk_from, stop = after_neighbour_list(whole, i, e, dj, pstop, ls)
            if stop < 0:
                stop = ls
                for j in range(walk_from, ls):
                    mn = np.int64(pm[np.uint64(s), np.uint64(j)])
                    fs = path_index(base_s, step_s, mstep_s, j, mn)
                    x = flat_state[fs]
                    if x < FREE:
                        stop = j
                        break
                    if x != v:
                        flat_state[fs] = v
                        if votes is None:
                            crow[fs] += 1
                        else:
                            for q in range(n_cls):
                                flat_counts[q, fs] += votes[v, q]
            prev = s
            pstop = stop
            per = er
            pec = ec
    return used


def cones_reach(blocked: np.ndarray, rows: np.ndarray, cols: np.ndarray, yaws: np.ndarray, offsets: np.ndarray,
                max_range: float, groups: np.ndarray | None = None, n_groups: int = 1) -> np.ndarray:
    """(H, W) bool: the cells some view's cone reaches (the union of the cones), walked as the
    vision cone walks its rays: neighbouring rays share their cells (:func:`envs.maps.ray_paths.ray_paths`), and a
    ray ending on the cell of the ray before is skipped (the same digital line). The cells are
    those of every ray of heading ``yaws[v] + offsets[t]`` walked whole
    (:func:`envs.maps.rays.trace_ray`: the digital line from the view's cell to its end,
    stopping before the first blocked cell), at a fraction of the lookups.

    Args:
        blocked: (H, W) bool cells that stop a ray.
        rows, cols: (N,) int the views' cells (a view off the map, or on a blocked cell, sees
            nothing).
        yaws: (N,) the views' headings, radians (map convention of :func:`envs.maps.rays.ray_end`).
        offsets: (R,) ray headings around a view's heading, radians (:func:`envs.maps.rays.cone_thetas`
            of heading 0).
        max_range: ray length, pixels (>= 0).
        groups: (N,) int in ``[0, n_groups)``, or None: with groups, the cells of each group's
            views apart, in one walk (a view's cells do not depend on the other views walked
            with it).
        n_groups: the number of groups (>= 1).

    Returns:
        (H, W) bool; with ``groups``, (n_groups, H, W) bool.
    """
    if max_range < 0:
        raise ValueError(f"max_range must be >= 0 pixels, got {max_range}")
    blocked = np.ascontiguousarray(blocked, np.bool_)
    rows, cols = np.asarray(rows, np.int64).ravel(), np.asarray(cols, np.int64).ravel()
    h, w = blocked.shape
    ok = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    state = ray_state(~blocked)  # a cell some view reached holds that view's index (>= 0)
    n = int(ok.sum())
    args = (blocked, state, rows[ok], cols[ok], np.asarray(yaws, np.float64).ravel()[ok],
            np.ascontiguousarray(offsets, np.float64), float(max_range), 0.0)
    paths = ray_paths(float(max_range), PATH_CACHE_BYTES)
    if groups is None:
        # no view votes (label -1, no classes): the walk only stamps the cells it reaches
        _cone_votes(*args, np.full(n, -1, np.int64), None, np.zeros((0, h + 2, w + 2), np.uint8), *paths)
        return state[1:-1, 1:-1] >= 0
    groups = np.asarray(groups, np.int64).ravel()
    if len(groups) != len(rows) or (len(groups) and (groups.min() < 0 or groups.max() >= n_groups)):
        raise ValueError(f"groups must be {len(rows)} ints in [0, {n_groups}), got {len(groups)} "
                         f"in [{groups.min() if len(groups) else 0}, {groups.max() if len(groups) else 0}]")
    # each view votes once for its group on each cell it reaches: a cell a group reaches has a count > 0
    most = min(n, max_votes_per_cell((h, w), rows[ok], cols[ok], reach_px(float(max_range))))
    whole = np.uint8 if most < 2**8 else np.uint16 if most < 2**16 else np.uint32
    counts = np.zeros((n_groups, h + 2, w + 2), whole)  # bordered as the cell state
    _cone_votes(*args, groups[ok], None, counts, *paths)
    return counts[:, 1:-1, 1:-1] > 0


#: rows of the map the window mode works on at once (its float work arrays are this many rows)
MODE_BAND_ROWS = 512


def window_mode(counts: np.ndarray, walkable: np.ndarray, window: int, band_rows: int = MODE_BAND_ROWS) -> np.ndarray:
    """Per cell, the class with the most votes in the ``window`` x ``window`` box around it
    (ties: lower index), on walkable cells with any vote; -1 elsewhere.

    One class at a time (a running best sum and its class) and ``band_rows`` rows at a time
    (each band's window sums read ``window // 2`` rows beyond it; outside the map counts as no
    vote, as for the whole map at once), so the work arrays beyond the (H, W) int32 result are
    a band's, whatever the map's size and the number of classes.
    :func:`benchmark.aggregators.reference.window_mode_reference` is the whole-map stacked argmax.

    Args:
        counts: (C, H, W) votes per class (uint8, uint16, float32 or any real type).
        walkable: (H, W) bool.
        window: odd box size, pixels.
        band_rows: rows per band (>= 1).

    Returns:
        (H, W) int32 class indices, -1 where unlabelled.
    """
    if window < 1 or window % 2 == 0:
        raise ValueError(f"window must be an odd number of pixels >= 1, got {window}")
    h = walkable.shape[0]
    lab = np.full(walkable.shape, -1, np.int32)
    if len(counts) == 0:
        return lab
    half = window // 2
    for r0 in range(0, h, max(int(band_rows), 1)):
        r1 = min(r0 + max(int(band_rows), 1), h)
        a, b = max(r0 - half, 0), min(r1 + half, h)  # the band and the rows its windows read
        out = lab[r0:r1]
        out[:] = 0
        best = None
        for k, c in enumerate(counts):
            # float32 window sums straight from the counts (uint8 / uint16 counts need no float
            # copy; sums of whole votes stay exact below 2**24)
            src = c[a:b] if c.dtype in (np.uint8, np.uint16, np.float32) else c[a:b].astype(np.float32)
            summed = cv2.boxFilter(src, cv2.CV_32F, (window, window), normalize=False,
                                   borderType=cv2.BORDER_CONSTANT)[r0 - a:r1 - a]
            if best is None:
                best = summed.copy()
                continue
            better = summed > best  # strictly: a tie keeps the lower class
            out[better] = k
            np.maximum(best, summed, out=best)
        out[(best <= 0) | ~walkable[r0:r1]] = -1
    return lab


class VisionCone(Aggregator):
    """Vision-cone voting aggregator.

    Args:
        fov: cone angle, degrees.
        max_range_m: cone range, metres (the paper's 500 px at 0.02 m/px = 10 m).
        blocked_ray_m: length of the forward ray that must be clear, metres.
        window: mode-filter window, pixels (odd).
        vote: "label" (one vote for the top class) or "probability".
        ray_density: rays per pixel of arc at the maximum range (1.0: neighbouring rays end
            1 px apart; 2.0 doubles the rays: on the shared houses labels agree with 1.0 on
            98-99.5 % of walkable cells and take ~1.5x as long).
    """

    def __init__(self, fov: Annotated[float, Angle()] = 90.0,
                 max_range_m: Annotated[float, Positive()] = 10.0,
                 blocked_ray_m: Annotated[float, NonNegative()] = 0.3, window: Annotated[int, Odd()] = 5,
                 vote: Annotated[str, OneOf("label", "probability")] = "label",
                 ray_density: Annotated[float, Positive()] = 1.0):
        if ray_density <= 0:
            raise ValueError(f"ray_density must be > 0 rays per pixel, got {ray_density}")
        self.ray_density = float(ray_density)
        if vote not in ("label", "probability"):
            raise ValueError(f"vote must be 'label' or 'probability', got {vote!r}")
        if not (0 < fov <= 360) or max_range_m <= 0 or blocked_ray_m < 0:
            raise ValueError("VisionCone needs 0 < fov <= 360, max_range_m > 0, blocked_ray_m >= 0")
        if window < 1 or window % 2 == 0:
            raise ValueError(f"window must be an odd number of pixels >= 1, got {window}")
        self.fov, self.max_range_m, self.blocked_ray_m = fov, max_range_m, blocked_ray_m
        self.window, self.vote = int(window), vote
        self.last_used = 0

    def votes(self, grid: GridMap, poses: np.ndarray, proba: np.ndarray) -> np.ndarray:
        """(C, H, W) vote counts (before the window mode): with ``vote="label"`` whole votes, in
        the smallest of uint8, uint16 and uint32 that holds :func:`max_votes_per_cell` (a cell
        gets at most one vote per view, from views within the cone's reach of it: 16 views per
        10 m room with a 10 m cone need uint8 at any map size, 1 byte a pixel per class), else
        float32 sums of probabilities. The map's cells of the bordered counts the kernel fills:
        a view, not a copy."""
        r, c, yaw, p, _ = view_cells(grid, poses, proba)
        n_cls = p.shape[1]
        labels = np.argmax(p, axis=1).astype(np.int64) if self.vote == "label" else np.full(len(p), -1, np.int64)
        max_px = self.max_range_m / grid.resolution
        # every cone has the same ray offsets around its heading: no (views x rays) array, so
        # memory does not grow with the number of views (a million views fit)
        offsets = cone_thetas(0.0, self.fov, max_px, self.ray_density)
        # (fewer than 256 views: uint8 whatever the bound, which is not computed)
        most = len(p) if len(p) < 2**8 else min(len(p), max_votes_per_cell(grid.shape, r, c, reach_px(max_px)))
        whole = np.uint8 if most < 2**8 else np.uint16 if most < 2**16 else np.uint32
        h, w = grid.shape
        # bordered as the cell state (a cell's count at the state's own flat index); the map's
        # cells are returned, a view
        counts = np.zeros((n_cls, h + 2, w + 2), whole if self.vote == "label" else np.float32)
        votes = None if self.vote == "label" else p.astype(np.float32)  # None: whole votes (labels)
        self.last_used = _cone_votes(np.ascontiguousarray(~grid.walkable), ray_state(grid.walkable),
                                     r.astype(np.int64), c.astype(np.int64), np.deg2rad(yaw), offsets, float(max_px),
                                     float(self.blocked_ray_m / grid.resolution), labels, votes, counts,
                                     *ray_paths(float(max_px), PATH_CACHE_BYTES))
        return counts[:, 1:-1, 1:-1]

    def __call__(self, grid: GridMap, poses: np.ndarray, proba: np.ndarray) -> np.ndarray:
        return window_mode(self.votes(grid, poses, proba), grid.walkable, self.window)
