"""Euclidean KNN: the naive baseline the paper argues against (straight-line distance,
ignores walls). Each walkable cell takes the vote of its K nearest viewpoints by Euclidean
distance in pixels (SciPy cKDTree; equal distances in the tree's order), voted as in
:mod:`benchmark.aggregators.graph_knn`."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from benchmark.aggregators.common import view_cells, vote_neighbours
from envs.gridmap import GridMap


class EuclideanKNN:
    """Args: k: neighbours; weighting: "majority" or "probability"."""

    def __init__(self, k: int = 5, weighting: str = "majority"):
        if weighting not in ("majority", "probability"):
            raise ValueError(f"weighting must be 'majority' or 'probability', got {weighting!r}")
        self.k, self.weighting = int(k), weighting

    def __call__(self, grid: GridMap, poses: np.ndarray, proba: np.ndarray) -> np.ndarray:
        r, c, _, p, _ = view_cells(grid, poses, proba, self.k)
        cells = np.argwhere(grid.walkable)
        _, idx = cKDTree(np.column_stack([r, c]).astype(float)).query(cells.astype(float), k=self.k)
        idx = np.asarray(idx, np.int64).reshape(len(cells), self.k)
        out = np.full(grid.shape, -1, np.int32)
        out[cells[:, 0], cells[:, 1]] = vote_neighbours(idx, p, self.weighting)
        return out
