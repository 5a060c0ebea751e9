"""Rigid alignment of an estimated trajectory to the true one, and the absolute trajectory error.

:func:`align_rigid` is Umeyama's least-squares rigid transform (Umeyama 1991; Horn 1987 for
the closed form), without scale, as trajectory benchmarks compute ATE (Sturm et al. 2012):
the rotation R and translation t minimising ``sum |true_k - (R est_k + t)|^2`` over the
positions. :func:`ate_rmse` is the root mean square of the position error after it.
"""

from __future__ import annotations

import numpy as np

from envs.kernel_cache import njit


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



@njit(cache=True, nogil=True)
def _map_frame_source(h, w, o0, o1, res, cs, sn, t0, t1, out):
    """Per map cell, the flat index of the world cell its centre shows (-1: off the raster):
    the arithmetic of ``GridMap.pixel_to_world``, :func:`apply_rigid` and
    ``GridMap.world_to_cell``, operation for operation."""
    for r in range(h):
        z = o1 - (r + 0.5) * res
        for c in range(w):
            x = o0 + (c + 0.5) * res
            wx = (cs * x - sn * z) + t0
            wz = (sn * x + cs * z) + t1
            rr = np.floor((o1 - wz) / res)
            cc = np.floor((wx - o0) / res)
            if rr >= 0 and rr < h and cc >= 0 and cc < w:
                out[r, c] = int(rr) * w + int(cc)
            else:
                out[r, c] = -1


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
    t = np.asarray(t, np.float64).reshape(2)
    src = np.empty((h, w), np.int64)
    # the same float operations as pixel_to_world -> apply_rigid -> world_to_cell (np.cos and
    # np.sin of theta as apply_rigid takes them), one pass and no (H W, 2) temporaries
    _map_frame_source(h, w, float(grid.origin[0]), float(grid.origin[1]), float(grid.resolution),
                      float(np.cos(theta)), float(np.sin(theta)), float(t[0]), float(t[1]), src)
    out = np.full((h, w), fill, labels.dtype)
    ok = src >= 0
    out[ok] = labels.ravel()[src[ok]]
    return out


__all__ = ["align_rigid", "apply_rigid", "ate_rmse", "to_map_frame"]
