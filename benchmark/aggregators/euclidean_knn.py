"""Euclidean KNN: the naive baseline the paper argues against (straight-line distance,
ignores walls). Each walkable cell takes the vote of its K nearest viewpoints by Euclidean
distance between cell centres in pixels, voted as in :mod:`benchmark.aggregators.graph_knn`.

"Nearest" is the order (squared pixel distance, viewpoint index), exactly as graph KNN. A
numba kernel keeps each cell's K smallest keys ``d2 * N + index`` by insertion (K is small):
exact by construction, no tie handling needed. The views are grouped by the cell they stand on
(views turning in place share one: :func:`view_places`) and the places sorted by row once;
each cell visits them outwards from its own row, nearer rows first, and stops in a direction
once the squared row distance alone puts every further view's key above its K-th (a skipped
view could never enter). A place's views share a distance, so their keys rise with their
index: the first that does not enter ends the place. Time O(cells x places) at worst, about
the places within the K-th distance's rows in practice; memory (cells, K).
"""

from __future__ import annotations

from typing import Annotated

import numpy as np

from benchmark.aggregators.common import view_cells, vote_neighbours
from benchmark.interfaces import Aggregator
from envs.kernel_cache import njit
from envs.maps.gridmap import GridMap
from envs.ranges import Integer, OneOf


@njit(cache=True, nogil=True)
def _k_nearest(prow, pcol, starts, members, n, cells, k):
    places = prow.shape[0]
    out = np.empty((cells.shape[0], k), np.int64)
    best = np.empty(k, np.int64)
    for j in range(cells.shape[0]):
        cr, cc = cells[j, 0], cells[j, 1]
        filled = 0
        up = np.searchsorted(prow, cr) - 1  # next place above (row < cr), going up
        down = up + 1  # next place at or below, going down
        while up >= 0 or down < places:
            # the nearer row first; a direction ends when its row distance alone exceeds the K-th key
            if down < places and (up < 0 or prow[down] - cr <= cr - prow[up]):
                p = down
                down += 1
            else:
                p = up
                up -= 1
            dr = prow[p] - cr
            if filled == k and dr * dr * n > best[k - 1]:
                if dr >= 0:
                    down = places
                else:
                    up = -1
                continue
            dc = pcol[p] - cc
            d2n = (dr * dr + dc * dc) * n
            for q in range(starts[p], starts[p + 1]):  # the place's views, by index: keys rise
                key = d2n + members[q]
                if filled < k:
                    pos = filled
                    filled += 1
                elif key < best[k - 1]:
                    pos = k - 1
                else:
                    break  # nor do the place's later views enter
                while pos > 0 and best[pos - 1] > key:  # insertion into the sorted K best
                    best[pos] = best[pos - 1]
                    pos -= 1
                best[pos] = key
        for q in range(k):
            out[j, q] = best[q] % n
    return out


def view_places(rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The cells views stand on, by row: views turning in place share one.

    Args:
        rows, cols: (N,) int64 pixel row and column of each view.

    Returns:
        (P,) row and (P,) column of each place, sorted by (row, column); (P + 1,) ``starts``
        and (N,) ``members``: the views on place p are ``members[starts[p]:starts[p + 1]]``,
        in index order.
    """
    members = np.lexsort((np.arange(len(rows)), cols, rows))
    r, c = rows[members], cols[members]
    first = np.flatnonzero(np.r_[True, (r[1:] != r[:-1]) | (c[1:] != c[:-1])]) if len(r) else np.zeros(0, np.int64)
    return r[first], c[first], np.r_[first, len(r)].astype(np.int64), members.astype(np.int64)


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
    prow, pcol, starts, members = view_places(rows, cols)
    return _k_nearest(prow, pcol, starts, members, len(rows), np.ascontiguousarray(cells, np.int64), int(k))


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
