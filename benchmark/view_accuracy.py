"""Per-view accuracy of a classification, beside the segmentation metrics (:mod:`benchmark.metrics`).

Two truths for a view: the class of the room it stands in (:func:`view_accuracy`), and the
class it sees most of (:func:`true_labels`: the majority class of its visible floor, the
oracle classifier's truth, known where the renderer reports visible classes). Every metrics row
of the method carries both (``view_accuracy``, ``view_accuracy_seen``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def true_labels(observations: Sequence) -> np.ndarray:
    """The majority visible class of each observation.

    Returns:
        (N,) int64 class index, -1 where nothing was seen.

    Raises:
        ValueError: an observation has no ``visible_classes`` (not the floorplan renderer).
    """
    rows = []
    for i, o in enumerate(observations):
        if o.visible_classes is None:
            raise ValueError(f"observation {i} has no visible_classes: the oracle needs the floorplan renderer")
        rows.append(np.asarray(o.visible_classes))
    if len({r.shape for r in rows}) > 1:  # rows of different lengths: one at a time
        return np.array([int(np.argmax(r)) if r.sum() > 0 else -1 for r in rows], np.int64)
    out = np.full(len(rows), -1, dtype=np.int64)
    if rows:  # all views at once: each row's sum and first largest class, as one row's
        v = np.stack(rows)
        seen = v.sum(axis=-1) > 0
        out[seen] = np.argmax(v, axis=-1)[seen]
    return out


def seen_accuracy(truth: np.ndarray, proba: np.ndarray) -> float:
    """Share of views whose top class is their true (majority visible) class.

    Args:
        truth: (N,) true class per view, -1 for a view that saw no floor (left out).
        proba: (N, C) class probabilities.

    Returns:
        The share in [0, 1]; NaN when no view saw floor.
    """
    truth = np.asarray(truth)
    m = truth >= 0
    if not m.any():
        return float("nan")
    return float(np.mean(np.asarray(proba)[m].argmax(axis=1) == truth[m]))


def view_accuracy(grid, semantic: np.ndarray, poses: np.ndarray, proba: np.ndarray) -> float:
    """Share of views whose top class equals the ground-truth class of the cell they stand on.

    Args:
        grid: the :class:`envs.maps.gridmap.GridMap` the poses are on.
        semantic: (H, W) ground-truth class per cell, -1 outside every room.
        poses: (N, 3) world x, z (metres), yaw (degrees).
        proba: (N, C) class probabilities.

    Returns:
        The share in [0, 1] over views standing on a room; NaN when none does.
    """
    r, c = grid.world_to_cell(poses[:, 0], poses[:, 1])
    ok = grid.in_bounds(r, c)
    truth = np.full(len(poses), -1)
    truth[ok] = semantic[r[ok], c[ok]]
    m = truth >= 0
    if not m.any():
        return float("nan")
    return float(np.mean(np.asarray(proba)[m].argmax(axis=1) == truth[m]))


__all__ = ["true_labels", "seen_accuracy", "view_accuracy"]
