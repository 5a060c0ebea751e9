"""A 2D pose graph and its least-squares solve (graph SLAM's back end, Grisetti et al. 2010).

Nodes are SE(2) states (x, z metres, phi radians counter-clockwise from +x; see
:mod:`benchmark.conditions.odometry`). An edge ``(i, j, z, sqrt_info)`` says "node j seen from node i is at
``z``" (dx, dz in i's frame, metres; dphi, radians), with ``sqrt_info`` (3, 3) the upper
Cholesky factor of its information matrix (inverse covariance), so that the whitened residual

    r_ij = sqrt_info @ [R(phi_i)^T (t_j - t_i) - z[:2],  wrap(phi_j - phi_i - z[2])]

has unit covariance. :func:`solve` minimises the sum of squared whitened residuals over every
node but the first (the map's frame: the robot's start) by Levenberg-Marquardt with the sparse
analytic Jacobian and SciPy's sparse solver. With noisy constraints it leaves a residual: the corrected
poses are not the true ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix, diags
from scipy.sparse.linalg import spsolve

from benchmark.conditions.odometry import wrap


@dataclass
class PoseGraph:
    """Edges of a pose graph over ``n`` nodes.

    Attributes:
        n: number of nodes.
        i, j: (E,) int node indices of each edge (from i to j).
        z: (E, 3) measured relative poses (dx, dz metres in i's frame; dphi radians).
        sqrt_info: (E, 3, 3) square roots of the edges' information matrices.
    """

    n: int
    i: np.ndarray
    j: np.ndarray
    z: np.ndarray
    sqrt_info: np.ndarray


def relative(states: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """(E, 3) pose of node j in node i's frame (dx, dz metres, dphi radians wrapped)."""
    s = np.asarray(states, np.float64)
    d = s[j, :2] - s[i, :2]
    c, sn = np.cos(s[i, 2]), np.sin(s[i, 2])
    return np.column_stack([c * d[:, 0] + sn * d[:, 1], -sn * d[:, 0] + c * d[:, 1], wrap(s[j, 2] - s[i, 2])])


def residuals(states: np.ndarray, graph: PoseGraph) -> np.ndarray:
    """(E, 3) whitened residuals of every edge at ``states`` (module docstring)."""
    e = relative(states, graph.i, graph.j) - graph.z
    e[:, 2] = wrap(e[:, 2])
    return np.einsum("eab,eb->ea", graph.sqrt_info, e)


def _jacobian(states: np.ndarray, graph: PoseGraph) -> coo_matrix:
    """Sparse (3E, 3(n-1)) Jacobian of the whitened residuals over nodes 1..n-1."""
    s = np.asarray(states, np.float64)
    i, j = graph.i, graph.j
    e_n = len(i)
    d = s[j, :2] - s[i, :2]
    c, sn = np.cos(s[i, 2]), np.sin(s[i, 2])
    rt = np.zeros((e_n, 3, 3))  # d r_raw / d state_j ; d / d state_i is -rt plus the heading term
    rt[:, 0, 0], rt[:, 0, 1], rt[:, 1, 0], rt[:, 1, 1], rt[:, 2, 2] = c, sn, -sn, c, 1.0
    ji = -rt.copy()
    ji[:, 0, 2] = -sn * d[:, 0] + c * d[:, 1]
    ji[:, 1, 2] = -c * d[:, 0] - sn * d[:, 1]
    bj = np.einsum("eab,ebc->eac", graph.sqrt_info, rt)
    bi = np.einsum("eab,ebc->eac", graph.sqrt_info, ji)
    rows, cols, vals = [], [], []
    r_idx = 3 * np.arange(e_n)[:, None, None] + np.arange(3)[None, :, None]
    for node, block in ((j, bj), (i, bi)):
        c_idx = 3 * (node - 1)[:, None, None] + np.arange(3)[None, None, :]
        keep = node > 0
        rr, cc = np.broadcast_arrays(r_idx, c_idx)
        rows.append(rr[keep].ravel())
        cols.append(cc[keep].ravel())
        vals.append(block[keep].ravel())
    return coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(3 * e_n, 3 * (graph.n - 1)))


def solve(graph: PoseGraph, initial: np.ndarray, max_iterations: int = 100) -> tuple[np.ndarray, dict]:
    """Least-squares node states, node 0 held at ``initial[0]``: Levenberg-Marquardt on the
    sparse normal equations (SciPy's sparse LU), as g2o and GTSAM solve pose graphs.

    Args:
        graph: the edges.
        initial: (n, 3) starting states (the odometry chain).
        max_iterations: linear solves allowed.

    Returns:
        ((n, 3) states, info): ``chi2`` the final sum of squared whitened residuals, ``dof``
        (3E - 3(n-1)), ``iterations``, ``converged`` (the last step moved no state by more than
        1e-9 or the cost stopped falling).
    """
    x = np.asarray(initial, np.float64).reshape(-1, 3).copy()
    if graph.n != len(x):
        raise ValueError(f"pose graph has {graph.n} nodes, initial states {len(x)}")
    if graph.n < 2 or len(graph.i) == 0:
        r = residuals(x, graph) if len(graph.i) else np.zeros((0, 3))
        return x, {"chi2": float((r ** 2).sum()), "dof": 0, "iterations": 0, "converged": True}
    r = residuals(x, graph)
    cost = float((r ** 2).sum())
    lam, converged, it = 1e-4, False, 0
    system = None  # the normal equations at x: made again only when a step is taken
    while it < max_iterations:
        it += 1
        if system is None:
            r = r.ravel()
            jac = _jacobian(x, graph).tocsc()
            h = (jac.T @ jac).tocsc()
            system = (h, jac.T @ r, h.diagonal())
        h, g, diag = system
        step = spsolve((h + diags(lam * np.maximum(diag, 1e-12))).tocsc(), -g)
        trial = x.copy()
        trial[1:] += step.reshape(-1, 3)
        trial[:, 2] = wrap(trial[:, 2])
        r_trial = residuals(trial, graph)
        new = float((r_trial ** 2).sum())
        if new <= cost:
            done = np.abs(step).max() < 1e-9 or cost - new <= 1e-12 * max(cost, 1.0)
            x, r, cost, lam, system = trial, r_trial, new, max(lam / 10.0, 1e-12), None
            if done:
                converged = True
                break
        else:
            lam *= 10.0
            if lam > 1e12:
                converged = True  # no step lowers the cost: a minimum
                break
    return x, {"chi2": cost, "dof": int(3 * len(graph.i) - 3 * (graph.n - 1)), "iterations": it,
               "converged": converged}


def move_edge(moves: np.ndarray, sigmas: np.ndarray, floor: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    """Odometry edges from (K, 3) reported moves (rot1, trans, rot2) and their (K, 3) sigmas.

    The relative pose is (trans cos rot1, trans sin rot1, rot1 + rot2); its covariance is the
    moves' diagonal covariance through that map's Jacobian, plus ``floor`` squared (metres and
    radians) on the diagonal so that an exact move still has finite information.

    Returns:
        ((K, 3) z, (K, 3, 3) sqrt_info).
    """
    m = np.asarray(moves, np.float64).reshape(-1, 3)
    r1, t = m[:, 0], m[:, 1]
    z = np.column_stack([t * np.cos(r1), t * np.sin(r1), wrap(r1 + m[:, 2])])
    jac = np.zeros((len(m), 3, 3))
    jac[:, 0, 0], jac[:, 0, 1] = -t * np.sin(r1), np.cos(r1)
    jac[:, 1, 0], jac[:, 1, 1] = t * np.cos(r1), np.sin(r1)
    jac[:, 2, 0], jac[:, 2, 2] = 1.0, 1.0
    cov = np.einsum("eab,eb,ecb->eac", jac, np.asarray(sigmas, np.float64) ** 2, jac) + floor ** 2 * np.eye(3)
    return z, sqrt_information(cov)


def sqrt_information(cov: np.ndarray) -> np.ndarray:
    """(E, 3, 3) covariances -> (E, 3, 3) upper factors U with U^T U = inverse covariance."""
    info = np.linalg.inv(np.asarray(cov, np.float64))
    low = np.linalg.cholesky(info)  # info = L L^T -> U = L^T
    return np.transpose(low, (0, 2, 1))


__all__ = ["PoseGraph", "relative", "residuals", "solve", "move_edge", "sqrt_information"]
