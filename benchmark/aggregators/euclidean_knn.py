"""Euclidean KNN: the naive baseline the paper argues against (straight-line distance,
ignores walls). Each walkable cell takes the vote of its K nearest viewpoints by Euclidean
distance between cell centres in pixels, voted as in :mod:`benchmark.aggregators.graph_knn`.

"Nearest" is the order (squared pixel distance, viewpoint index), exactly as graph KNN. A
numba kernel keeps each cell's K smallest keys ``d2 * N + index`` by insertion (K is small):
exact by construction, no tie handling needed. The views are sorted by row once; each cell
visits them outwards from its own row, nearer rows first, and stops in a direction once the
squared row distance alone puts every further view's key above its K-th (a skipped view
could never enter). Time O(cells x views) at worst, about the views within the K-th
distance's rows in practice; memory (cells, K).
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
from numba import njit

from benchmark.aggregators.common import view_cells, vote_neighbours
from benchmark.interfaces import Aggregator
from envs.maps.gridmap import GridMap
from envs.ranges import Integer, OneOf


@njit(cache=True, nogil=True)
def _k_nearest(rows, cols, cells, k):
    n = rows.shape[0]
    order = np.argsort(rows, kind="mergesort")  # views by row; a cell searches outwards from its row
    srow = rows[order]
    out = np.empty((cells.shape[0], k), np.int64)
    best = np.empty(k, np.int64)
    for j in range(cells.shape[0]):
        cr, cc = cells[j, 0], cells[j, 1]
        filled = 0
        up = np.searchsorted(srow, cr) - 1  # next view above (row < cr), going up
        down = up + 1  # next view at or below, going down
        while up >= 0 or down < n:
            # the nearer row first; a direction ends when its row distance alone exceeds the K-th key
            if down < n and (up < 0 or srow[down] - cr <= cr - srow[up]):
                pos_s = down
                down += 1
            else:
                pos_s = up
                up -= 1
            dr = srow[pos_s] - cr
            if filled == k and dr * dr * n > best[k - 1]:
                if dr >= 0:
                    down = n
                else:
                    up = -1
                continue
            i = order[pos_s]
            dc = cols[i] - cc
            key = (dr * dr + dc * dc) * n + i
            if filled < k:
                pos = filled
                filled += 1
            elif key < best[k - 1]:
                pos = k - 1
            else:
                continue
            while pos > 0 and best[pos - 1] > key:  # insertion into the sorted K best
                best[pos] = best[pos - 1]
                pos -= 1
            best[pos] = key
        for q in range(k):
            out[j, q] = best[q] % n
    return out


def euclidean_neighbours(rows: np.ndarray, cols: np.ndarray, cells: np.ndarray, k: int) -> np.ndarray:
    """The K nearest views of each cell by (squared pixel distance, view index).

    Args:
        rows, cols: (N,) pixel row and column of each view.
        cells: (M, 2) pixel (row, col) of the cells to label.
        k: neighbours, 1 <= K <= N.

    Returns:
        (M, K) int64 view indices, nearest first.
    """
    rows = np.ascontiguousarray(rows, np.int64)
    cols = np.ascontiguousarray(cols, np.int64)
    if not 1 <= k <= len(rows):
        raise ValueError(f"k must be in 1..{len(rows)} (the number of views), got {k}")
    return _k_nearest(rows, cols, np.ascontiguousarray(cells, np.int64), int(k))


class EuclideanKNN(Aggregator):
    """Args: k: neighbours; weighting: "majority" or "probability"."""

    def __init__(self, k: Annotated[int, Integer(1)] = 5,
                 weighting: Annotated[str, OneOf("majority", "probability")] = "majority"):
        if weighting not in ("majority", "probability"):
            raise ValueError(f"weighting must be 'majority' or 'probability', got {weighting!r}")
        self.k, self.weighting = int(k), weighting

    def __call__(self, grid: GridMap, poses: np.ndarray, proba: np.ndarray) -> np.ndarray:
        r, c, _, p, _ = view_cells(grid, poses, proba, self.k)
        cells = np.argwhere(grid.walkable)
        nbr = euclidean_neighbours(r, c, cells, self.k)
        out = np.full(grid.shape, -1, np.int32)
        out[cells[:, 0], cells[:, 1]] = vote_neighbours(nbr, p, self.weighting)
        return out
