"""Slow, obviously-correct references for the aggregators (tests and ``make perf``).

* Graph KNN: one breadth-first search per viewpoint with SciPy's csgraph (the paper's
  method), then each cell ranks viewpoints by (distance, index) and keeps the first K.
* Euclidean KNN: all (cell, view) squared pixel distances, each cell sorted by
  (distance, index).
* Vision cone: a per-ray Python loop walking each digital line (computed from its
  definition, not with the kernel's Bresenham error term), with a set per view so a cell
  gets at most one vote per view.
"""

from __future__ import annotations

import cv2
import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from benchmark.aggregators.common import view_cells
from benchmark.aggregators.graph_knn import neighbour_offsets
from envs.maps.gridmap import GridMap
from envs.maps.rays import cone_thetas


def vote_reference(nbr: np.ndarray, proba: np.ndarray, weighting: str) -> np.ndarray:
    """The neighbours' vote in NumPy, one column of neighbours at a time (the aggregators
    vote with :func:`benchmark.aggregators.common.vote_neighbours`, a numba loop).

    ``majority``: the most common top class; ties go to the tied class whose view is nearest.
    ``probability``: the largest summed probability; ties go to the lower class index.

    Returns:
        (M,) int32 labels, -1 for a cell whose first neighbour is -1.
    """
    m, k = nbr.shape
    c = proba.shape[1]
    out = np.full(m, -1, dtype=np.int32)
    has = nbr[:, 0] >= 0
    if weighting == "probability":
        acc = np.zeros((m, c))
        for j in range(k):
            ok = nbr[:, j] >= 0
            acc[ok] += proba[nbr[ok, j]]
        out[has] = np.argmax(acc[has], axis=1)
        return out
    top = np.argmax(proba, axis=1)
    lab = np.where(nbr >= 0, top[np.maximum(nbr, 0)], -1)
    counts = np.zeros((m, c), dtype=np.int32)
    for j in range(k):
        ok = lab[:, j] >= 0
        counts[ok, lab[ok, j]] += 1
    best = counts.max(axis=1)
    for j in range(k - 1, -1, -1):  # the nearest neighbour whose class reaches the best count decides
        ok = (lab[:, j] >= 0) & (counts[np.arange(m), np.maximum(lab[:, j], 0)] == best)
        out[ok] = lab[ok, j]
    out[~has] = -1
    return out


def grid_graph(walkable: np.ndarray, connectivity: int) -> tuple[sp.csr_matrix, np.ndarray]:
    """Sparse unit-weight graph over walkable cells and the node index of every cell (-1 if none)."""
    h, w = walkable.shape
    node = np.full(h * w, -1, np.int64)
    idx = np.flatnonzero(walkable.ravel())
    node[idx] = np.arange(len(idx))
    rr, cc = np.divmod(idx, w)
    src, dst = [], []
    for dr, dc in neighbour_offsets(connectivity):
        r2, c2 = rr + dr, cc + dc
        ok = (r2 >= 0) & (r2 < h) & (c2 >= 0) & (c2 < w)
        ok[ok] = walkable[r2[ok], c2[ok]]
        src.append(node[idx[ok]])
        dst.append(node[r2[ok] * w + c2[ok]])
    src, dst = np.concatenate(src), np.concatenate(dst)
    g = sp.csr_matrix((np.ones(len(src)), (src, dst)), shape=(len(idx), len(idx)))
    return g, node


def graph_knn_reference(grid: GridMap, poses, proba, k: int, connectivity: int = 4, weighting: str = "majority",
                        chunk: int = 64) -> np.ndarray:
    """Graph KNN by one csgraph BFS per viewpoint."""
    r, c, _, p, _ = view_cells(grid, poses, proba, k)
    g, node = grid_graph(grid.walkable, connectivity)
    w = grid.shape[1]
    m = g.shape[0]
    best_d = np.full((m, k), np.inf)
    best_s = np.full((m, k), -1, np.int64)
    src_nodes = node[r * w + c]
    for start in range(0, len(src_nodes), chunk):
        ids = np.arange(start, min(start + chunk, len(src_nodes)))
        d = csgraph.shortest_path(g, method="D", unweighted=True, indices=src_nodes[ids])  # (chunk, M)
        alld = np.concatenate([best_d, d.T], axis=1)
        alls = np.concatenate([best_s, np.broadcast_to(ids, (m, len(ids)))], axis=1)
        alls = np.where(np.isinf(alld), -1, alls)
        order = np.lexsort((np.where(alls < 0, np.iinfo(np.int64).max, alls), alld), axis=1)[:, :k]
        best_d = np.take_along_axis(alld, order, 1)
        best_s = np.take_along_axis(alls, order, 1)
    nbr = np.full((grid.shape[0] * w, k), -1, np.int64)
    cells = np.flatnonzero(grid.walkable.ravel())
    nbr[cells] = np.where(np.isinf(best_d), -1, best_s)
    lab = vote_reference(nbr, p, weighting).reshape(grid.shape)
    lab[~grid.walkable] = -1
    return lab


def euclidean_knn_reference(grid: GridMap, poses, proba, k: int, weighting: str = "majority") -> np.ndarray:
    """Euclidean KNN by sorting every view for every cell (M x N memory: small maps only)."""
    r, c, _, p, _ = view_cells(grid, poses, proba, k)
    cells = np.argwhere(grid.walkable)
    d2 = (cells[:, None, 0] - r[None, :]) ** 2 + (cells[:, None, 1] - c[None, :]) ** 2
    ids = np.broadcast_to(np.arange(len(r)), d2.shape)
    nbr = np.take_along_axis(ids, np.lexsort((ids, d2), axis=1)[:, :k], 1)
    lab = np.full(grid.shape, -1, np.int32)
    lab[cells[:, 0], cells[:, 1]] = vote_reference(nbr, p, weighting)
    return lab


def digital_line(r0: int, c0: int, r1: int, c1: int) -> list[tuple[int, int]]:
    """The cells of the digital line from (r0, c0) to (r1, c1), in order, from its definition.

    One cell per step along the major axis; on the minor axis the integer nearest the exact
    line, a tie (exactly half-way) going to the cell nearer the start. Computed in closed
    form with integer arithmetic, not with Bresenham's error term: an independent check of
    the ray-casting kernel (``envs.maps.rays.trace_ray``), which must visit these cells.

    Returns:
        list of (row, col) pairs, ``max(|r1 - r0|, |c1 - c0|) + 1`` of them.
    """
    dr, dc = r1 - r0, c1 - c0
    n = max(abs(dr), abs(dc))
    if n == 0:
        return [(r0, c0)]
    i = np.arange(n + 1, dtype=np.int64)

    def nearest(d: int) -> np.ndarray:  # round(d * i / n), ties toward the start
        if d > 0:
            return -((n - 2 * d * i) // (2 * n))  # ceil((2 d i - n) / 2n)
        return (2 * d * i + n) // (2 * n)  # floor((2 d i + n) / 2n)

    if abs(dc) >= abs(dr):
        rows, cols = r0 + nearest(dr), c0 + np.sign(dc) * i
    else:
        rows, cols = r0 + np.sign(dr) * i, c0 + nearest(dc)
    return list(zip(rows.tolist(), cols.tolist()))


def walk_ray(blocked: np.ndarray, r0: int, c0: int, theta: float, max_range: float):
    """Free cells a ray visits before the first blocked cell or the map edge, and the hit."""
    h, w = blocked.shape
    r1 = int(np.floor(r0 + 0.5 - np.cos(theta) * max_range))
    c1 = int(np.floor(c0 + 0.5 + np.sin(theta) * max_range))
    seen = []
    for r, c in digital_line(r0, c0, r1, c1):
        if not (0 <= r < h and 0 <= c < w):
            return seen, None
        if blocked[r, c]:
            return seen, (r, c)
        seen.append((r, c))
    return seen, None


def window_mode_reference(counts: np.ndarray, walkable: np.ndarray, window: int) -> np.ndarray:
    """The window mode as a stack: every class's window sums at once, then the first argmax
    (ties: lower index); -1 on cells with no vote in their window or not walkable."""
    summed = np.stack([cv2.boxFilter(c.astype(np.float32), -1, (window, window), normalize=False,
                                     borderType=cv2.BORDER_CONSTANT) for c in counts])
    lab = np.argmax(summed, axis=0).astype(np.int32)
    lab[(summed.max(axis=0) <= 0) | ~walkable] = -1
    return lab


def vision_cone_reference(grid: GridMap, poses, proba, fov: float = 90.0, max_range_m: float = 10.0,
                          blocked_ray_m: float = 0.3, window: int = 5, vote: str = "label",
                          ray_density: float = 1.0) -> np.ndarray:
    """Vision-cone voting by a per-ray Python loop."""
    counts = vision_cone_votes_reference(grid, poses, proba, fov, max_range_m, blocked_ray_m, vote, ray_density)
    return window_mode_reference(counts, grid.walkable, window)


def vision_cone_votes_reference(grid: GridMap, poses, proba, fov: float = 90.0, max_range_m: float = 10.0,
                                blocked_ray_m: float = 0.3, vote: str = "label",
                                ray_density: float = 1.0) -> np.ndarray:
    """The vision cone's (C, H, W) float64 vote counts (before the window mode) by a per-ray
    Python loop: each view's cells, gathered in a set, get one vote each."""
    r, c, yaw, p, _ = view_cells(grid, poses, proba)
    blocked = ~grid.walkable
    n_cls = p.shape[1]
    counts = np.zeros((n_cls, *grid.shape))
    max_px = max_range_m / grid.resolution
    for i in range(len(r)):
        _, hit = walk_ray(blocked, int(r[i]), int(c[i]), float(np.deg2rad(yaw[i])), blocked_ray_m / grid.resolution)
        if hit is not None:
            continue
        cells = set()
        for th in cone_thetas(yaw[i], fov, max_px, ray_density):
            seen, _ = walk_ray(blocked, int(r[i]), int(c[i]), float(th), max_px)
            cells.update(seen)
        for rr, cc in cells:
            if vote == "label":
                counts[int(np.argmax(p[i])), rr, cc] += 1
            else:
                counts[:, rr, cc] += p[i]
    return counts


__all__ = ["graph_knn_reference", "vision_cone_reference", "vision_cone_votes_reference", "window_mode_reference", "euclidean_knn_reference", "digital_line", "walk_ray", "grid_graph"]
