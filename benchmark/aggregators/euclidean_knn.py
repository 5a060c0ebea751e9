"""Euclidean KNN: the naive baseline the paper argues against (straight-line distance,
ignores walls). Each walkable cell takes the vote of its K nearest viewpoints by Euclidean
distance between cell centres in pixels, voted as in :mod:`benchmark.aggregators.graph_knn`.

"Nearest" is the order (squared pixel distance, viewpoint index), exactly as graph KNN. A
numba kernel visits every view for every cell and keeps the K smallest keys
``d2 * N + index`` by insertion (K is small): exact by construction, no tie handling needed.
Time O(cells x views); memory (cells, K).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from benchmark.aggregators.common import view_cells, vote_neighbours
from benchmark.interfaces import Aggregator
from envs.maps.gridmap import GridMap


@njit(cache=True, nogil=True)
def _k_nearest(rows, cols, cells, k):
    n = rows.shape[0]
    out = np.empty((cells.shape[0], k), np.int64)
    best = np.empty(k, np.int64)
    for j in range(cells.shape[0]):
        filled = 0
        for i in range(n):
            dr = cells[j, 0] - rows[i]
            dc = cells[j, 1] - cols[i]
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

    def __init__(self, k: int = 5, weighting: str = "majority"):
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
