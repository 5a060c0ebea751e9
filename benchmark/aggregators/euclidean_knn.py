"""Euclidean KNN: the naive baseline the paper argues against (straight-line distance,
ignores walls). Each walkable cell takes the vote of its K nearest viewpoints by Euclidean
distance between cell centres in pixels, voted as in :mod:`benchmark.aggregators.graph_knn`.

"Nearest" is the order (squared pixel distance, viewpoint index), exactly as graph KNN:
SciPy's cKDTree (over the distinct view pixels) finds the K + 1 nearest positions; where
the K-th view is not strictly nearer than the last candidate position (the tree may have
left out an equally far view with a lower index) the cell asks for twice as many, until it
is or all positions are candidates.
Memory: (H*W, K + 1), linear in the map size (more only for the tied cells).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from benchmark.aggregators.common import view_cells, vote_neighbours
from benchmark.interfaces import Aggregator
from envs.maps.gridmap import GridMap


def euclidean_neighbours(rows: np.ndarray, cols: np.ndarray, cells: np.ndarray, k: int) -> np.ndarray:
    """(M, K) int64 view indices for the (M, 2) pixel ``cells``, nearest first by
    (squared pixel distance, view index). Needs K <= number of views."""
    pts = np.column_stack([rows, cols]).astype(np.int64)
    cells = np.asarray(cells, np.int64)
    n = len(pts)
    # views sharing a pixel (autotrace puts several headings on one point) are one tree node;
    # members[u] lists the views at unique position u, -1 padded
    upos, inv = np.unique(pts, axis=0, return_inverse=True)
    inv = inv.ravel()
    order = np.argsort(inv, kind="stable")
    mult = np.bincount(inv)
    members = np.full((len(upos), int(mult.max())), -1, np.int64)
    members[inv[order], np.arange(n) - np.repeat(np.cumsum(mult) - mult, mult)] = order
    tree = cKDTree(upos.astype(float))
    out = np.empty((len(cells), k), np.int64)
    todo = np.arange(len(cells))
    kq = min(len(upos), k + 1)
    big = np.iinfo(np.int64).max
    while len(todo):
        _, idx = tree.query(cells[todo].astype(float), k=kq)
        idx = np.asarray(idx, np.int64).reshape(len(todo), kq)
        d2 = ((cells[todo, None, :] - upos[idx]) ** 2).sum(axis=2)  # exact integer distances
        views = members[idx].reshape(len(todo), -1)
        key = np.where(views >= 0, np.repeat(d2, members.shape[1], axis=1) * n + views, big)
        key.sort(axis=1)  # order by (distance, view index)
        out[todo] = key[:, :k] % n
        if kq == len(upos):
            break
        # the K-th view must be nearer than the farthest candidate position, else a position
        # the tree left out may hold an equally far view with a lower index: ask for twice
        # as many positions there
        tied = key[:, k - 1] // n >= d2.max(axis=1)
        todo, kq = todo[tied], min(len(upos), 2 * kq)
    return out


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
