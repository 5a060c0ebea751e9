"""Vision-cone voting (PAPER.md step 3): labels land where the robot looks.

A view is dropped when its short forward ray (``blocked_ray_m`` metres along its heading)
meets an obstacle. Every other view casts rays over its ``fov`` cone up to ``max_range_m``
metres (the shared routine of :mod:`envs.maps.rays`; obstacles are the non-walkable cells),
and every walkable cell a ray reaches with clear line of sight gets one vote from that view
(its top class, or with ``vote="probability"`` its probability vector); a cell reached by
several rays of one view still gets one vote. The label of a cell is the class with the
most votes summed over the ``window`` x ``window`` pixels around it (ties: lower class
index); walkable cells with no vote in their window stay unlabelled.
Memory: (C, H, W) vote counts (uint16 with label votes from fewer than 65,536 views, else
float32), an (H + 2, W + 2) int32 cell state (free, blocked or
off the map, and the last view that voted there) and an (H, W) bool obstacle copy, linear in
the map size, and nothing per ray: every cone shares one array of ray offsets around its
view's heading. Neighbouring rays of a view share most cells near the camera; a ray walks
them against the cells the view's earlier rays walked (in order along each ray) and looks a
cell up only where it leaves that path, so the lookups number about the cells seen.
"""

from __future__ import annotations

from typing import Annotated

import cv2
import numpy as np
from numba import njit

from benchmark.aggregators.common import view_cells
from benchmark.interfaces import Aggregator
from envs.maps.gridmap import GridMap
from envs.maps.rays import cone_thetas, line_start, line_step, ray_end, trace_ray
from envs.ranges import Angle, NonNegative, Odd, OneOf, Positive

#: values of the per-cell state array besides view ids (>= 0: the last view that voted there)
FREE, BLOCKED, OUTSIDE = -1, -2, -3


def cone_state(walkable: np.ndarray) -> np.ndarray:
    """(H + 2, W + 2) int32: ``FREE`` on walkable cells, ``BLOCKED`` on the others, ``OUTSIDE`` on a
    one-cell border (a ray walks one cell per step, so it meets the border before leaving the
    map: no bounds checks in the walk). Cell (r, c) of the map is (r + 1, c + 1) here."""
    st = np.full((walkable.shape[0] + 2, walkable.shape[1] + 2), OUTSIDE, np.int32)
    st[1:-1, 1:-1] = np.where(walkable, FREE, BLOCKED)
    return st


@njit(cache=True, nogil=True)
def _cone_votes(blocked, state, rows, cols, yaws, offsets, max_range, short_px, labels, votes, counts):
    """Per view: the short forward ray, then the cone's rays in order of heading. A ray's cells
    are those of :func:`envs.maps.rays.trace_ray` (same digital line, stops before the first
    blocked cell or at the map edge), walked here without its buffer: ``path[j]`` holds the j-th
    cell of the latest ray of this view that reached index j, a free cell this view has already
    voted for, so a ray that is at that cell at step j (neighbouring rays share most of their
    cells near the camera) skips the state lookup; any other cell is looked up once in
    ``state``, which also stamps the view (one vote per view and cell)."""
    cap = int(np.ceil(max(max_range, short_px))) + 2
    buf_r = np.empty(cap, np.int32)
    buf_c = np.empty(cap, np.int32)
    path_r = np.empty(cap, np.int64)
    path_c = np.empty(cap, np.int64)
    n_cls = votes.shape[1]
    used = 0
    for v in range(rows.shape[0]):
        r0 = rows[v]
        c0 = cols[v]
        r1, c1 = ray_end(r0, c0, yaws[v], short_px)
        n, hr, hc = trace_ray(blocked, r0, c0, r1, c1, buf_r, buf_c)
        if hr >= 0:
            continue
        used += 1
        lab = labels[v]
        known = 0  # path[:known] holds cells of this view's rays
        for t in range(offsets.shape[0]):  # the cone's rays: the view's heading + fixed offsets
            r1, c1 = ray_end(r0, c0, yaws[v] + offsets[t], max_range)
            dr, dc, sr, sc, err = line_start(r0, c0, r1, c1)
            r = r0
            c = c0
            j = 0
            while True:
                if not (j < known and path_r[j] == r and path_c[j] == c):
                    s = state[r + 1, c + 1]
                    if s < FREE:  # blocked, or off the map
                        break
                    if s != v:
                        state[r + 1, c + 1] = v
                        if lab >= 0:  # one vote for the view's label
                            counts[lab, r, c] += 1
                        else:  # its probability vector
                            for k in range(n_cls):
                                counts[k, r, c] += votes[v, k]
                    path_r[j] = r
                    path_c[j] = c
                j += 1
                if r == r1 and c == c1:
                    break
                r, c, err = line_step(r, c, err, dr, dc, sr, sc)
            if j > known:
                known = j
    return used


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
        counts: (C, H, W) votes per class (uint16, float32 or any real type).
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
            # float32 window sums straight from the counts (uint16 counts need no float copy;
            # sums of whole votes stay exact below 2**24)
            src = c[a:b] if c.dtype in (np.uint16, np.float32) else c[a:b].astype(np.float32)
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
        """(C, H, W) vote counts (before the window mode): with ``vote="label"`` whole votes, uint16
        (a cell gets at most one vote per view, so fewer than 65,536 views cannot overflow it;
        uint32 beyond), else float32 sums of probabilities."""
        r, c, yaw, p, _ = view_cells(grid, poses, proba)
        n_cls = p.shape[1]
        labels = np.argmax(p, axis=1).astype(np.int64) if self.vote == "label" else np.full(len(p), -1, np.int64)
        max_px = self.max_range_m / grid.resolution
        # every cone has the same ray offsets around its heading: no (views x rays) array, so
        # memory does not grow with the number of views (a million views fit)
        offsets = cone_thetas(0.0, self.fov, max_px, self.ray_density)
        whole = np.uint16 if len(p) < 2**16 else np.uint32
        counts = np.zeros((n_cls, *grid.shape), whole if self.vote == "label" else np.float32)
        self.last_used = _cone_votes(np.ascontiguousarray(~grid.walkable), cone_state(grid.walkable),
                                     r.astype(np.int64), c.astype(np.int64), np.deg2rad(yaw), offsets, float(max_px),
                                     float(self.blocked_ray_m / grid.resolution), labels, p.astype(np.float32), counts)
        return counts

    def __call__(self, grid: GridMap, poses: np.ndarray, proba: np.ndarray) -> np.ndarray:
        return window_mode(self.votes(grid, poses, proba), grid.walkable, self.window)
