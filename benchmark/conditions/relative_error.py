"""Relative pose error over relations (Kümmerle et al., "On measuring the accuracy of SLAM
algorithms", Autonomous Robots 27(4), 2009).

A *relation* is a pair of poses ``(i, j)`` and the reference motion between them,
``delta*_ij = x*_i^-1 (+) x*_j`` (the motion from pose ``i`` to pose ``j`` seen from pose ``i``).
An estimate's error on the relation is ``delta_ij (-) delta*_ij = delta*_ij^-1 (+) delta_ij``;
its translation part (metres) and its rotation part (radians) are reported apart, never summed,
as the paper's tables do: the mean absolute error with its standard deviation, and the mean
squared error. The metric only looks at motions between related poses, so a global shift or turn
of the whole estimate costs nothing, unlike the absolute trajectory error (ATE), which this
module does not compute and which must not be put beside these numbers.

States are SE(2) ``(x, y, phi)``, ``phi`` radians counter-clockwise from +x
(:func:`benchmark.conditions.odometry.to_se2` turns the project's poses into them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from benchmark.conditions.odometry import wrap


def relative_motions(states: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """(N, 3) SE(2) states and (K, 2) index pairs -> (K, 3) motions ``x_i^-1 (+) x_j``."""
    s = np.asarray(states, np.float64).reshape(-1, 3)
    p = np.asarray(pairs, np.int64).reshape(-1, 2)
    a, b = s[p[:, 0]], s[p[:, 1]]
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    c, sn = np.cos(a[:, 2]), np.sin(a[:, 2])
    return np.column_stack([c * dx + sn * dy, -sn * dx + c * dy, wrap(b[:, 2] - a[:, 2])])


def relation_errors(estimate: np.ndarray, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per relation, the translational (m) and absolute rotational (rad) error of ``estimate``'s
    motions against ``reference``'s, both (K, 3) motions: ``reference^-1 (+) estimate``."""
    e = np.asarray(estimate, np.float64).reshape(-1, 3)
    r = np.asarray(reference, np.float64).reshape(-1, 3)
    d = relative_motions(np.concatenate([r, e]), np.column_stack([np.arange(len(r)), len(r) + np.arange(len(e))]))
    # relative_motions of (r_k, e_k) treats the motions as poses: r_k^-1 (+) e_k
    return np.hypot(d[:, 0], d[:, 1]), np.abs(d[:, 2])


def consecutive_pairs(n: int, step: int = 1) -> np.ndarray:
    """(K, 2) pairs ``(i, i + step)`` over ``n`` poses."""
    if not (isinstance(step, int | np.integer) and step >= 1):
        raise ValueError(f"relation step {step!r}: expected an integer >= 1")
    i = np.arange(max(n - step, 0))
    return np.column_stack([i, i + step])


def distance_pairs(states: np.ndarray, distance: float) -> np.ndarray:
    """(K, 2) pairs ``(i, j)``: for each pose ``i``, the first later pose ``j`` at least
    ``distance`` metres further along the reference path (no pair where the path ends first)."""
    if not (np.isfinite(distance) and distance > 0):
        raise ValueError(f"relation distance {distance!r}: expected metres > 0")
    s = np.asarray(states, np.float64).reshape(-1, 3)
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(s[:, :2], axis=0).T))])
    j = np.searchsorted(along, along + distance - 1e-12, side="left")
    keep = j < len(s)
    return np.column_stack([np.flatnonzero(keep), j[keep]])


@dataclass(frozen=True)
class RelativeError:
    """Kümmerle et al.'s figures over ``n`` relations: translation in metres, rotation in degrees."""

    n: int
    trans_mean_m: float
    trans_std_m: float
    trans_sq_m2: float
    rot_mean_deg: float
    rot_std_deg: float
    rot_sq_deg2: float

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def relative_error(estimate: np.ndarray, reference: np.ndarray, pairs: np.ndarray) -> RelativeError:
    """The relative pose error of an estimated trajectory against the reference one.

    Args:
        estimate: (N, 3) SE(2) states of the estimate.
        reference: (N, 3) SE(2) states of the reference (ground truth), the same poses in order.
        pairs: (K, 2) the related pose indices (:func:`consecutive_pairs`, :func:`distance_pairs`).

    Returns:
        mean and standard deviation of the absolute translational (m) and rotational (deg)
        errors, and their mean squares (m^2, deg^2), over the relations.
    """
    est = np.asarray(estimate, np.float64).reshape(-1, 3)
    ref = np.asarray(reference, np.float64).reshape(-1, 3)
    if est.shape != ref.shape:
        raise ValueError(f"estimate has {len(est)} poses, reference {len(ref)}: expected the same poses")
    p = np.asarray(pairs, np.int64).reshape(-1, 2)
    if len(p) == 0:
        raise ValueError("relations: none given, expected at least one pose pair")
    if p.min() < 0 or p.max() >= len(ref):
        raise ValueError(f"relation index {int(p.max()) if p.max() >= len(ref) else int(p.min())}: "
                         f"expected 0..{len(ref) - 1}")
    t, r = relation_errors(relative_motions(est, p), relative_motions(ref, p))
    rd = np.rad2deg(r)
    return RelativeError(n=len(p), trans_mean_m=float(t.mean()), trans_std_m=float(t.std()),
                         trans_sq_m2=float(np.mean(t ** 2)), rot_mean_deg=float(rd.mean()),
                         rot_std_deg=float(rd.std()), rot_sq_deg2=float(np.mean(rd ** 2)))


__all__ = ["relative_motions", "relation_errors", "consecutive_pairs", "distance_pairs", "RelativeError",
           "relative_error"]
