"""A 2D pose graph and its least-squares solve (graph SLAM's back end, Grisetti et al. 2010).

Nodes are SE(2) states (x, z metres, phi radians counter-clockwise from +x; see
:mod:`benchmark.conditions.odometry`). An edge ``(i, j, z, sqrt_info)`` says "node j seen from node i is at
``z``" (dx, dz in i's frame, metres; dphi, radians), with ``sqrt_info`` (3, 3) the upper
Cholesky factor of its information matrix (inverse covariance), so that the whitened residual

    r_ij = sqrt_info @ [R(phi_i)^T (t_j - t_i) - z[:2],  wrap(phi_j - phi_i - z[2])]

has unit covariance. :func:`solve` minimises the sum of squared whitened residuals over every
node but the first (the map's frame: the robot's start) by Levenberg-Marquardt with the sparse
analytic Jacobian, each step's normal equations solved by a sparse Cholesky factorisation
(:mod:`benchmark.conditions.sparse_cholesky`; SciPy's sparse LU for a graph whose factor would
exceed :data:`CHOLESKY_MAX_ENTRIES`, or where a damped system is not positive definite to
rounding). With noisy constraints it leaves a residual: the corrected
poses are not the true ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csc_matrix
from scipy.sparse.linalg import spsolve

from benchmark.conditions import sparse_cholesky
from benchmark.conditions.odometry import wrap
from envs.kernel_cache import njit

#: the most entries the Cholesky factor of a solve's system may hold; a larger graph's solve
#: keeps SciPy's sparse LU (SuperLU), faster there. A house's route (about 470 nodes, 1,400
#: unknowns, 15,000 entries) factors in about a tenth of the LU's time; a robot covering a
#: 70 x 70 lattice of nodes with closures to the row beside (14,700 unknowns, about a million
#: entries by this order) in about 1.8 times the LU's.
CHOLESKY_MAX_ENTRIES = 200_000


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


def _blocks(states: np.ndarray, graph: PoseGraph) -> tuple[np.ndarray, np.ndarray]:
    """The whitened residuals' Jacobian blocks: ((E, 3, 3) with respect to node j's state,
    (E, 3, 3) with respect to node i's)."""
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
    return np.einsum("eab,ebc->eac", graph.sqrt_info, rt), np.einsum("eab,ebc->eac", graph.sqrt_info, ji)


def _block_pattern(graph: PoseGraph) -> tuple[np.ndarray, np.ndarray]:
    """Every entry the normal equations over nodes 1..n-1 may have, in CSC (both triangles):
    the 3 x 3 blocks of each node with itself and with every node an edge joins it to."""
    n = graph.n
    own = np.arange(1, n)
    a = np.concatenate([np.asarray(graph.i, np.int64), np.asarray(graph.j, np.int64), own])
    b = np.concatenate([np.asarray(graph.j, np.int64), np.asarray(graph.i, np.int64), own])
    keep = (a > 0) & (b > 0)
    a, b = a[keep] - 1, b[keep] - 1
    rows = 3 * a[:, None, None] + np.arange(3)[None, :, None]
    cols = 3 * b[:, None, None] + np.arange(3)[None, None, :]
    rows, cols = np.broadcast_arrays(rows, cols)
    size = 3 * (n - 1)
    m = csc_matrix((np.ones(rows.size, np.int8), (rows.ravel(), cols.ravel())), shape=(size, size))
    m.sum_duplicates()
    return m.indptr, m.indices


def _incidence(graph: PoseGraph) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per node, the edges that touch it in edge order: (n + 1,) offsets, the edges, and each
    one's role (1: the node is the edge's j, 2: its i, 3: both)."""
    i, j = np.asarray(graph.i, np.int64), np.asarray(graph.j, np.int64)
    e = np.arange(len(i))
    node = np.concatenate([j, i])
    edge = np.concatenate([e, e])
    role = np.concatenate([np.full(len(e), 1), np.full(len(e), 2)])
    order = np.lexsort((edge, node))
    node, edge, role = node[order], edge[order], role[order]
    same = np.zeros(len(node), bool)  # an edge from a node to itself: one entry, both roles
    same[1:] = (node[1:] == node[:-1]) & (edge[1:] == edge[:-1])
    role[np.flatnonzero(same) - 1] = 3
    node, edge, role = node[~same], edge[~same], role[~same]
    offsets = np.searchsorted(node, np.arange(graph.n + 1)).astype(np.int64)
    return offsets, edge.astype(np.int64), role.astype(np.int64)


@njit(cache=True, nogil=True)
def _normal_equations(bj, bi, ei, ej, r, offsets, edges, roles, n):
    """The normal equations J^T J, J^T r of the sparse Jacobian over nodes 1..n-1 (column
    3 (k - 1) + c: node k's state c), as SciPy forms them from the COO Jacobian (``J.T @ J`` by
    its row-by-row product, ``J.T @ r``), sum for sum in the same order, so the values are its
    values bit for bit: entry (k, l) adds J[rho, k] J[rho, l] over the rows rho holding both, rho
    ascending, from 0.0; an entry that comes to exactly 0 is left out except on the diagonal
    (kept at 0.0, where SciPy adds the damping to a missing entry).

    Returns:
        (indptr, indices, data, g, diag, at_diag): J^T J in CSC (indices ascending in each
        column), J^T r, J^T J's diagonal and the index in ``data`` of each column's diagonal entry.
    """
    m = 3 * (n - 1)
    cap = 0  # per column: at most 6 columns per edge touching the node (its two nodes), and the diagonal
    for k in range(1, n):
        cap += 3 * (6 * (offsets[k + 1] - offsets[k]) + 1)
    indptr = np.zeros(m + 1, np.int32)
    indices = np.empty(cap, np.int32)
    data = np.empty(cap, np.float64)
    g = np.zeros(m, np.float64)
    diag = np.zeros(m, np.float64)
    at_diag = np.empty(m, np.int64)
    sums = np.zeros(m, np.float64)
    mark = np.full(m, -1, np.int64)
    touched = np.empty(m, np.int64)
    w = np.empty(6, np.float64)
    wc = np.empty(6, np.int64)
    nnz = 0
    for k in range(1, n):
        for c in range(3):
            col = 3 * (k - 1) + c
            nt = 0
            gsum = 0.0
            for t in range(offsets[k], offsets[k + 1]):
                e = edges[t]
                role = roles[t]
                a_node = ei[e]
                b_node = ej[e]
                for a in range(3):
                    if role == 1:
                        v = bj[e, a, c]
                    elif role == 2:
                        v = bi[e, a, c]
                    else:
                        v = bj[e, a, c] + bi[e, a, c]
                    gsum += v * r[3 * e + a]
                    # row 3 e + a of J: node i's and node j's columns, ascending
                    nw = 0
                    if a_node == b_node:
                        if a_node > 0:
                            for d in range(3):
                                wc[nw] = 3 * (a_node - 1) + d
                                w[nw] = bj[e, a, d] + bi[e, a, d]
                                nw += 1
                    else:
                        first, second = (a_node, b_node) if a_node < b_node else (b_node, a_node)
                        for node in (first, second):
                            if node > 0:
                                for d in range(3):
                                    wc[nw] = 3 * (node - 1) + d
                                    w[nw] = bi[e, a, d] if node == a_node else bj[e, a, d]
                                    nw += 1
                    for q in range(nw):
                        lc = wc[q]
                        if mark[lc] != col:
                            mark[lc] = col
                            sums[lc] = 0.0
                            touched[nt] = lc
                            nt += 1
                        sums[lc] += v * w[q]
            g[col] = gsum
            # this column's entries, rows ascending (J^T J is symmetric, value for value)
            for x in range(1, nt):
                y = touched[x]
                z = x - 1
                while z >= 0 and touched[z] > y:
                    touched[z + 1] = touched[z]
                    z -= 1
                touched[z + 1] = y
            has_diag = False
            for x in range(nt):
                lc = touched[x]
                if lc == col:
                    has_diag = True
                    diag[col] = sums[lc]
                if sums[lc] != 0.0 or lc == col:
                    if lc > col and not has_diag:
                        at_diag[col] = nnz
                        indices[nnz] = col
                        data[nnz] = 0.0
                        nnz += 1
                        has_diag = True
                    if lc == col:
                        at_diag[col] = nnz
                    indices[nnz] = lc
                    data[nnz] = sums[lc]
                    nnz += 1
            if not has_diag:
                at_diag[col] = nnz
                indices[nnz] = col
                data[nnz] = 0.0
                nnz += 1
            indptr[col + 1] = nnz
    return indptr, indices[:nnz].copy(), data[:nnz].copy(), g, diag, at_diag


def solve(graph: PoseGraph, initial: np.ndarray, max_iterations: int = 100) -> tuple[np.ndarray, dict]:
    """Least-squares node states, node 0 held at ``initial[0]``: Levenberg-Marquardt on the
    sparse normal equations (a sparse Cholesky factorisation of each damped system, the order
    and pattern worked out once per solve), as g2o and GTSAM solve pose graphs.

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
    incidence = _incidence(graph)
    ei, ej = np.asarray(graph.i, np.int64), np.asarray(graph.j, np.int64)
    size = 3 * (graph.n - 1)
    analysis = sparse_cholesky.analyse(*_block_pattern(graph), size)
    if analysis.lp[-1] > CHOLESKY_MAX_ENTRIES:
        analysis = None
    while it < max_iterations:
        it += 1
        if system is None:
            r = r.ravel()
            system = _normal_equations(*_blocks(x, graph), ei, ej, r, *incidence, graph.n)
        indptr, indices, data, g, diag, at_diag = system
        damped = data.copy()
        damped[at_diag] += lam * np.maximum(diag, 1e-12)  # (the damping is > 0: no entry becomes 0)
        lx = None if analysis is None else sparse_cholesky.factor(analysis, indptr, indices, damped)
        if lx is not None:
            step = sparse_cholesky.solve(analysis, lx, -g)
        else:  # a large graph, or not positive definite to rounding: the LU with pivoting copes
            step = spsolve(csc_matrix((damped, indices, indptr), shape=(size, size)), -g)
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
