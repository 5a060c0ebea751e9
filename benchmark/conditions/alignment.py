"""Rigid alignment of an estimated trajectory to the true one, and the absolute trajectory error.

:func:`align_rigid` is Umeyama's least-squares rigid transform (Umeyama 1991; Horn 1987 for
the closed form), without scale, as trajectory benchmarks compute ATE (Sturm et al. 2012):
the rotation R and translation t minimising ``sum |true_k - (R est_k + t)|^2`` over the
positions. :func:`ate_rmse` is the root mean square of the position error after it.
"""

from __future__ import annotations

import numpy as np


def align_rigid(est: np.ndarray, true: np.ndarray) -> tuple[float, np.ndarray]:
    """The rotation angle and translation taking ``est`` positions onto ``true`` ones.

    Args:
        est: (N, 2) estimated positions (metres).
        true: (N, 2) true positions (metres), same order.

    Returns:
        (theta radians counter-clockwise in the (first, second) coordinate plane, (2,) t metres):
        ``true ~ R(theta) @ est + t``. Fewer than 2 points: the translation of the one point.
    """
    a, b = np.asarray(est, np.float64).reshape(-1, 2), np.asarray(true, np.float64).reshape(-1, 2)
    if a.shape != b.shape or len(a) == 0:
        raise ValueError(f"align_rigid: est {a.shape} and true {b.shape} must be the same (N, 2), N >= 1")
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    if len(a) < 2:
        return 0.0, mb - ma
    cov = (b - mb).T @ (a - ma) / len(a)
    u, _, vt = np.linalg.svd(cov)
    s = np.diag([1.0, np.sign(np.linalg.det(u) * np.linalg.det(vt)) or 1.0])
    rot = u @ s @ vt
    theta = float(np.arctan2(rot[1, 0], rot[0, 0]))
    return theta, mb - rot @ ma


def apply_rigid(theta: float, t: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N, 2) points -> R(theta) @ p + t."""
    p = np.asarray(points, np.float64).reshape(-1, 2)
    c, s = np.cos(theta), np.sin(theta)
    return np.column_stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1]]) + np.asarray(t, np.float64)


def ate_rmse(est: np.ndarray, true: np.ndarray) -> float:
    """Absolute trajectory error (metres, RMS) after :func:`align_rigid`."""
    theta, t = align_rigid(est, true)
    d = apply_rigid(theta, t, est) - np.asarray(true, np.float64).reshape(-1, 2)
    return float(np.sqrt((d ** 2).sum(axis=1).mean()))



def to_map_frame(labels: np.ndarray, grid, theta: float, t: np.ndarray, fill: int = -1) -> np.ndarray:
    """A world-frame label raster brought into a robot map's frame (nearest cell).

    The map's cell (r, c) at map-frame position p (its centre, metres) shows the world point
    ``R(theta) p + t`` (:func:`align_rigid` of the estimated trajectory onto the true one), so it
    takes the label of the world cell containing that point; ``fill`` off the raster.

    Args:
        labels: (H, W) int labels on ``grid`` (world frame).
        grid: the :class:`envs.maps.gridmap.GridMap` both rasters share (cells, metres per cell, origin).
        theta, t: the rigid transform map frame -> world frame (radians, (2,) metres).

    Returns:
        (H, W) labels in the map's frame (same dtype).
    """
    labels = np.asarray(labels)
    h, w = labels.shape
    rows, cols = np.mgrid[0:h, 0:w]
    x, z = grid.pixel_to_world(rows.ravel(), cols.ravel())
    world = apply_rigid(theta, t, np.column_stack([x, z]))
    r, c = grid.world_to_cell(world[:, 0], world[:, 1])
    ok = (r >= 0) & (r < h) & (c >= 0) & (c < w)
    out = np.full(h * w, fill, labels.dtype)
    out[ok] = labels[r[ok], c[ok]]
    return out.reshape(h, w)


__all__ = ["align_rigid", "apply_rigid", "ate_rmse", "to_map_frame"]
