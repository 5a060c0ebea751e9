"""Input checks, voting and the neighbour memo shared by the aggregators."""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np

from envs.digest import arrays_key
from envs.kernel_cache import njit
from envs.maps.gridmap import GridMap
from envs.memo import ByteLRU
from envs.render.observation import poses_array

log = logging.getLogger(__name__)

#: bytes of neighbour tables a process keeps (:func:`kept_neighbours`): a shared ProcTHOR house's
#: walkable cells x 5 neighbours take about 0.5 MB (int16), so the tables of a job's 100 houses
#: stay while the next job (the same map and views, another classifier) reads them back
NEIGHBOURS_MEMO_BYTES = 96 * 2**20
#: kept per process, read-only: digest of the map, views, kind and settings -> (M, K)
#: neighbour table (:func:`kept_neighbours`)
_NEIGHBOURS = ByteLRU()


def kept_neighbours(kind: str, walkable: np.ndarray, rows: np.ndarray, cols: np.ndarray,
                    settings: tuple, make: Callable[[], np.ndarray]) -> np.ndarray:
    """The (M, K) neighbour table ``make()`` gives for a map and views, kept per process by the
    content of what it depends on, so that aggregating the same views on the same map again (the
    next classifier of a sweep: the neighbours do not depend on the classes) finds it.

    The key is :func:`envs.digest.arrays_key` of ``walkable`` ((H, W) bool), the views' cells
    ``rows`` and ``cols`` ((N,) ints), ``kind`` and ``settings`` (the aggregator's K,
    connectivity); a table is kept in the smallest of int16 and int32 that
    holds its view indices (-1: none), read-only, at most :data:`NEIGHBOURS_MEMO_BYTES` of them
    (one larger than that is not kept). The values are ``make()``'s, whatever the dtype.

    Returns:
        (M, K) ints, view indices (a read-only array kept here, or ``make()``'s own).
    """
    key = arrays_key((np.asarray(walkable, np.bool_), np.asarray(rows, np.int64), np.asarray(cols, np.int64)),
                     (kind, settings))
    kept = _NEIGHBOURS.get(key)
    if kept is not None:
        return kept
    nbr = make()
    small = nbr.astype(np.int16 if len(rows) < 2**15 else np.int32)
    small.setflags(write=False)
    _NEIGHBOURS.put(key, small, small.nbytes + 256, NEIGHBOURS_MEMO_BYTES)
    return nbr


def view_cells(grid: GridMap, poses, proba, k: int | None = None):
    """Validate inputs; return (rows, cols, yaw, proba, kept) of the views on walkable cells.

    Views off the map or on non-walkable cells are dropped (``kept`` marks the others) and
    their count is logged as a warning; no views, all views dropped, a probability matrix of the wrong shape, or K larger
    than the number of views raise ``ValueError``.
    """
    poses = poses_array(poses) if len(np.asarray(poses)) else np.zeros((0, 3))
    proba = np.asarray(proba, dtype=np.float64)
    if len(poses) == 0:
        raise ValueError("no viewpoints: the aggregator needs at least one pose")
    if proba.ndim != 2 or proba.shape[0] != len(poses):
        raise ValueError(f"probability matrix must be (N, C) with N = {len(poses)} poses, got shape {proba.shape}")
    r, c = grid.world_to_cell(poses[:, 0], poses[:, 1])
    kept = grid.is_walkable(r, c)
    if not kept.any():
        raise ValueError(f"all {len(poses)} viewpoints are off the walkable map")
    if not kept.all():
        log.warning("%d of %d viewpoints are off the walkable map and were dropped", int((~kept).sum()), len(poses))
    if k is not None and k > int(kept.sum()):
        raise ValueError(f"K = {k} is larger than the number of usable viewpoints ({int(kept.sum())} of {len(poses)})")
    if k is not None and k < 1:
        raise ValueError(f"K must be >= 1, got {k}")
    return r[kept], c[kept], poses[kept, 2], proba[kept], kept


def vote_neighbours(nbr: np.ndarray, proba: np.ndarray, weighting: str) -> np.ndarray:
    """Labels from each cell's neighbour views, ordered nearest first ((M, K) view ids, -1 = none).

    ``majority``: the most common top class; ties go to the tied class whose view is nearest.
    ``probability``: the largest summed probability (summed nearest first); ties go to the
    lower class index. Cells with no neighbour get -1. A numba loop over cells; the
    references vote with NumPy (:func:`benchmark.aggregators.reference.vote_reference`).

    Returns:
        (M,) int32 class indices, -1 where a cell has no neighbour.
    """
    if weighting not in ("majority", "probability"):
        raise ValueError(f"weighting must be 'majority' or 'probability', got {weighting!r}")
    nbr = np.ascontiguousarray(nbr, np.int64)
    proba = np.ascontiguousarray(proba, np.float64)
    if weighting == "probability":
        return _vote_probability(nbr, proba)
    return _vote_majority(nbr, np.argmax(proba, axis=1).astype(np.int64), proba.shape[1])


@njit(cache=True, nogil=True)
def _vote_majority(nbr, top, n_classes):
    m, k = nbr.shape
    out = np.full(m, -1, np.int32)
    counts = np.zeros(n_classes, np.int64)
    for i in range(m):
        if nbr[i, 0] < 0:
            continue
        counts[:] = 0
        for j in range(k):
            if nbr[i, j] >= 0:
                counts[top[nbr[i, j]]] += 1
        best = counts.max()
        for j in range(k):  # the nearest view whose class reaches the best count
            if nbr[i, j] >= 0 and counts[top[nbr[i, j]]] == best:
                out[i] = top[nbr[i, j]]
                break
    return out


@njit(cache=True, nogil=True)
def _vote_probability(nbr, proba):
    m, k = nbr.shape
    c = proba.shape[1]
    out = np.full(m, -1, np.int32)
    acc = np.zeros(c)
    for i in range(m):
        if nbr[i, 0] < 0:
            continue
        acc[:] = 0.0
        for j in range(k):
            if nbr[i, j] >= 0:
                for q in range(c):
                    acc[q] += proba[nbr[i, j], q]
        best = 0
        for q in range(1, c):  # the first maximum: ties go to the lower class
            if acc[q] > acc[best]:
                best = q
        out[i] = best
    return out
