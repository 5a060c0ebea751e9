"""Euclidean KNN: the naive baseline the paper argues against (straight-line distance,
ignores walls). Each walkable cell takes the vote of its K nearest viewpoints by Euclidean
distance between cell centres in pixels, voted as in :mod:`benchmark.aggregators.graph_knn`.

"Nearest" is the order (squared pixel distance, viewpoint index), exactly as graph KNN. The
views are grouped by the cell they stand on (views turning in place share one:
:func:`view_places`). A numba kernel takes the cells in square tiles of :data:`TILE` x
:data:`TILE`. For a tile's centre it finds the distance ``d`` of its K-th nearest view; no cell
of the tile is more than ``h`` (half the tile's diagonal) from the centre, so every view among a
cell's K nearest, ties at the K-th included, lies within ``d + 2 h`` of the centre (the
triangle inequality twice): those places are the tile's candidates. Each cell then keeps the K
smallest keys ``d2 * N + index`` of its candidates' views by insertion (K is small): exact by
construction, no tie handling needed. A place's views share a distance, so their keys rise with
their index: the first that does not enter ends the place. Time about (cells x candidates),
memory (cells, K).
"""

from __future__ import annotations

from typing import Annotated

import numpy as np

from benchmark.aggregators.common import kept_neighbours, view_cells, vote_neighbours
from benchmark.interfaces import Aggregator
from envs.kernel_cache import njit
from envs.maps.gridmap import GridMap
from envs.ranges import Integer, OneOf

#: the side of the square tiles of cells that share their candidate views, in cells (even)
TILE = 8


@njit(cache=True, nogil=True, inline="always")
def _k_best(prow, pcol, starts, members, n, r, c, k, cand, nc, best, bidx):
    """Into ``best``/``bidx``: the K smallest keys ``d2 * N + index`` of the views on places
    ``cand[:nc]`` from cell (r, c), sorted, and their view indices."""
    filled = 0
    for x in range(nc):
        p = cand[x]
        dr, dc = prow[p] - r, pcol[p] - c
        d2n = (dr * dr + dc * dc) * n
        if filled == k and d2n > best[k - 1]:
            continue
        for v in range(starts[p], starts[p + 1]):  # the place's views, by index: keys rise
            key = d2n + members[v]
            if filled < k:
                pos = filled
                filled += 1
            elif key < best[k - 1]:
                pos = k - 1
            else:
                break  # nor do the place's later views enter
            while pos > 0 and best[pos - 1] > key:  # insertion into the sorted K best
                best[pos] = best[pos - 1]
                bidx[pos] = bidx[pos - 1]
                pos -= 1
            best[pos] = key
            bidx[pos] = members[v]


@njit(cache=True, nogil=True)
def _k_nearest(prow, pcol, starts, members, n, cells, k, tile):
    m = cells.shape[0]
    places = prow.shape[0]
    out = np.empty((m, k), np.int64)
    if m == 0:
        return out
    # the cells by tile (a counting sort; each tile's cells in their order)
    rmin, rmax, cmin, cmax = cells[0, 0], cells[0, 0], cells[0, 1], cells[0, 1]
    for j in range(m):
        rmin, rmax = min(rmin, cells[j, 0]), max(rmax, cells[j, 0])
        cmin, cmax = min(cmin, cells[j, 1]), max(cmax, cells[j, 1])
    across = (cmax - cmin) // tile + 1
    tiles = ((rmax - rmin) // tile + 1) * across
    first = np.zeros(tiles + 1, np.int64)
    which = np.empty(m, np.int64)
    for j in range(m):
        t = ((cells[j, 0] - rmin) // tile) * across + (cells[j, 1] - cmin) // tile
        which[j] = t
        first[t + 1] += 1
    for t in range(tiles):
        first[t + 1] += first[t]
    order = np.empty(m, np.int64)
    at = first[:tiles].copy()
    for j in range(m):
        order[at[which[j]]] = j
        at[which[j]] += 1
    half = tile // 2
    reach = 2.0 * np.sqrt(2.0 * half * half)  # twice the farthest a tile's cell is from its centre
    every = np.arange(places)
    d2c = np.empty(places, np.int64)
    cand = np.empty(places, np.int64)
    best = np.empty(k, np.int64)
    bidx = np.empty(k, np.int64)
    for t in range(tiles):
        if first[t] == first[t + 1]:
            continue
        cr = rmin + (t // across) * tile + half
        cc = cmin + (t % across) * tile + half
        _k_best(prow, pcol, starts, members, n, cr, cc, k, every, places, best, bidx)  # the centre's K nearest
        r = np.sqrt(best[k - 1] // n) + reach + 1e-6
        limit = np.int64(r * r) + 1  # (rounded up: more candidates, never fewer)
        nc = 0
        for p in range(places):  # the candidates, nearest the centre first
            dr, dc = prow[p] - cr, pcol[p] - cc
            d2c[p] = dr * dr + dc * dc
            if d2c[p] <= limit:
                x = nc
                while x > 0 and d2c[cand[x - 1]] > d2c[p]:
                    cand[x] = cand[x - 1]
                    x -= 1
                cand[x] = p
                nc += 1
        for q in range(first[t], first[t + 1]):
            j = order[q]
            _k_best(prow, pcol, starts, members, n, cells[j, 0], cells[j, 1], k, cand, nc, best, bidx)
            for v in range(k):
                out[j, v] = bidx[v]
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
    return _k_nearest(prow, pcol, starts, members, len(rows), np.ascontiguousarray(cells, np.int64), int(k), TILE)


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
        # the map and the views alone decide them: kept for another classifier's views (kept_neighbours)
        nbr = kept_neighbours("euclidean_knn", grid.walkable, r, c, (self.k,),
                              lambda: euclidean_neighbours(r, c, cells, self.k))
        out = np.full(grid.shape, -1, np.int32)
        out[cells[:, 0], cells[:, 1]] = vote_neighbours(nbr, p, self.weighting)
        return out
