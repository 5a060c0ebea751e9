"""Input checks and voting shared by the aggregators."""

from __future__ import annotations

import logging

import numpy as np

from envs.maps.gridmap import GridMap
from envs.render.observation import poses_array

log = logging.getLogger(__name__)


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
    ``probability``: the largest summed probability; ties go to the lower class index.
    Cells with no neighbour get -1.
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
    if weighting != "majority":
        raise ValueError(f"weighting must be 'majority' or 'probability', got {weighting!r}")
    top = np.argmax(proba, axis=1)
    lab = np.where(nbr >= 0, top[np.maximum(nbr, 0)], -1)
    counts = np.zeros((m, c), dtype=np.int32)
    for j in range(k):
        ok = lab[:, j] >= 0
        counts[ok, lab[ok, j]] += 1
    best = counts.max(axis=1)
    # the nearest neighbour whose class reaches the best count decides
    for j in range(k - 1, -1, -1):
        ok = (lab[:, j] >= 0) & (counts[np.arange(m), np.maximum(lab[:, j], 0)] == best)
        out[ok] = lab[ok, j]
    out[~has] = -1
    return out
