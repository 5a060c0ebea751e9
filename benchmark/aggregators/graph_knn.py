"""Graph KNN with geodesic distance (PAPER.md step 3).

The graph: walkable cells, edges to the 4 (or 8) neighbours, every step costs 1 (so with
8-connectivity a diagonal step counts as one hop). A cell's K nearest viewpoints are the
first K in the order (geodesic distance, viewpoint index): ties in distance go to the lower
viewpoint index. Cells that fewer than K viewpoints reach use those they have; cells no
viewpoint reaches stay unlabelled. The label is the majority top class of those viewpoints
(ties: the tied class of the nearest viewpoint) or, with ``weighting="probability"``, the
class with the largest summed probability (ties: lower class index).

The paper runs one BFS per viewpoint. Here one multi-source BFS, level by level, carries
every viewpoint's wavefront and lets a cell accept at most K viewpoints, lowest index first
within a level (the frontier stays ordered by viewpoint index, so no sorting is needed). This is exact: if a cell on a shortest path from viewpoint s already holds
K viewpoints ranked before s, every cell behind it does too, so s is not among their K
nearest. Memory: (H*W, K) int32 slots plus the frontier of one BFS level (at most K
entries per cell of that level), linear in the map size.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np

from benchmark.aggregators.common import kept_neighbours, view_cells, vote_neighbours
from benchmark.interfaces import Aggregator
from envs.kernel_cache import njit
from envs.maps.gridmap import GridMap
from envs.ranges import Integer, OneOf

_D4 = np.array([[-1, 0], [1, 0], [0, -1], [0, 1]], dtype=np.int64)
_D8 = np.array([[-1, 0], [1, 0], [0, -1], [0, 1], [-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=np.int64)


def neighbour_offsets(connectivity: int) -> np.ndarray:
    if connectivity not in (4, 8):
        raise ValueError(f"connectivity must be 4 or 8, got {connectivity}")
    return _D4 if connectivity == 4 else _D8


@njit(cache=True)
def _knn_bfs(walk, src_r, src_c, k, offs, slots, cnt):
    h, w = walk.shape
    n = src_r.shape[0]
    fr_cell = np.empty(n, np.int64)
    fr_src = np.empty(n, np.int64)
    m = 0
    for s in range(n):
        cell = src_r[s] * w + src_c[s]
        if cnt[cell] < k:
            slots[cell, cnt[cell]] = s
            cnt[cell] += 1
            fr_cell[m] = cell
            fr_src[m] = s
            m += 1
    nb = offs.shape[0]
    # The frontier is kept in increasing viewpoint order (true for level 0; candidates are
    # generated and accepted in frontier order, so it stays true), hence a cell accepts the
    # lowest-index viewpoints of a level first without sorting.
    while m > 0:
        nxt_cell = np.empty(m * nb, np.int64)
        nxt_src = np.empty(m * nb, np.int64)
        q = 0
        for i in range(m):
            cell = fr_cell[i]
            s = fr_src[i]
            r = cell // w
            c = cell % w
            for d in range(nb):
                rr = r + offs[d, 0]
                cc = c + offs[d, 1]
                if rr < 0 or rr >= h or cc < 0 or cc >= w or not walk[rr, cc]:
                    continue
                v = rr * w + cc
                if cnt[v] >= k:
                    continue
                dup = False
                for j in range(cnt[v]):
                    if slots[v, j] == s:
                        dup = True
                        break
                if dup:
                    continue
                slots[v, cnt[v]] = s
                cnt[v] += 1
                nxt_cell[q] = v
                nxt_src[q] = s
                q += 1
        fr_cell = nxt_cell[:q]
        fr_src = nxt_src[:q]
        m = q
    return slots


def knn_neighbours(walkable: np.ndarray, rows: np.ndarray, cols: np.ndarray, k: int, connectivity: int = 4) -> np.ndarray:
    """(H*W, K) int32 viewpoint indices per cell, nearest first by (geodesic hops, index); -1 = none."""
    offs = neighbour_offsets(connectivity)
    h, w = walkable.shape
    # the map-sized work arrays are allocated here, in NumPy, and filled by the kernel
    slots = np.full((h * w, int(k)), -1, np.int32)
    cnt = np.zeros(h * w, np.int32)
    return _knn_bfs(np.ascontiguousarray(walkable, dtype=np.bool_), np.asarray(rows, np.int64),
                    np.asarray(cols, np.int64), int(k), offs, slots, cnt)


class GraphKNN(Aggregator):
    """Graph KNN aggregator.

    Args:
        k: number of nearest viewpoints per cell.
        connectivity: 4 or 8 (unit cost per step either way).
        weighting: "majority" (top class of each view) or "probability" (summed probabilities).
    """

    def __init__(self, k: Annotated[int, Integer(1)] = 5, connectivity: Annotated[int, OneOf(4, 8)] = 4,
                 weighting: Annotated[str, OneOf("majority", "probability")] = "majority"):
        neighbour_offsets(connectivity)
        if weighting not in ("majority", "probability"):
            raise ValueError(f"weighting must be 'majority' or 'probability', got {weighting!r}")
        self.k, self.connectivity, self.weighting = int(k), int(connectivity), weighting

    def __call__(self, grid: GridMap, poses: np.ndarray, proba: np.ndarray) -> np.ndarray:
        r, c, _, p, _ = view_cells(grid, poses, proba, self.k)
        cells = np.flatnonzero(grid.walkable.ravel())
        # the walkable cells' neighbours depend on the map and the views alone: kept per process
        # for the next aggregation of the same views (another classifier's), kept_neighbours
        nbr = kept_neighbours("graph_knn", grid.walkable, r, c, (self.k, self.connectivity),
                              lambda: knn_neighbours(grid.walkable, r, c, self.k, self.connectivity)[cells])
        lab = np.full(grid.shape[0] * grid.shape[1], -1, np.int32)
        lab[cells] = vote_neighbours(nbr, p, self.weighting)
        return lab.reshape(grid.shape)
