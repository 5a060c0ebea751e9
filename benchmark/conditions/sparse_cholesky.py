"""Sparse Cholesky factorisation for the pose-graph solve's normal equations.

A Levenberg-Marquardt solve (:func:`benchmark.conditions.pose_graph.solve`) factors one
symmetric positive definite matrix per iteration, always with the same sparsity pattern (the
graph's). :func:`analyse` works out everything that depends on the pattern alone, once: a
fill-reducing order (SciPy's reverse Cuthill-McKee), the elimination tree and the pattern of
the factor ``L``. :func:`factor` then computes ``L`` for one matrix's values, and
:func:`solve` solves with it. The solve's linear algebra this replaces was SciPy's sparse LU
(``spsolve``, SuperLU with partial pivoting), which does the ordering and the symbolic work again
for every matrix; the solve keeps it for a damped system that is not positive definite to
rounding, and for a graph whose factor would be large (its supernodal LU is faster there:
:data:`benchmark.conditions.pose_graph.CHOLESKY_MAX_ENTRIES`).

The algorithm is the up-looking Cholesky of Davis, *Direct Methods for Sparse Linear Systems*
(SIAM 2006, chapter 4): row ``k`` of ``L`` solves a triangular system whose pattern is the
reach of column ``k`` of the matrix in the elimination tree. Here those reaches are found
once, in :func:`analyse`, for a pattern that holds every entry the matrix may have, so that
:func:`factor` only does arithmetic. An entry of the pattern the matrix lacks counts as 0.

``tests/test_sparse_cholesky.py`` checks the solutions against NumPy's dense solver.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import reverse_cuthill_mckee

from envs.kernel_cache import njit


@dataclass(frozen=True)
class Analysis:
    """What :func:`analyse` finds for one pattern of an ``n`` x ``n`` matrix.

    Attributes:
        n: the matrix's size.
        perm: (n,) the order: row and column ``k`` of the factored matrix are the original's
            ``perm[k]``.
        pinv: (n,) its inverse (``pinv[perm[k]] == k``).
        lp: (n + 1,) where each column of ``L`` starts in ``li`` (its diagonal first).
        li: (nnz(L),) the row of each entry of ``L``, column by column.
        rp: (n + 1,) where each row's reach starts in ``reach``.
        reach: the columns ``j < k`` of row ``k`` of ``L``, row by row, in the order the
            factorisation takes them (each before any later column it updates).
    """

    n: int
    perm: np.ndarray
    pinv: np.ndarray
    lp: np.ndarray
    li: np.ndarray
    rp: np.ndarray
    reach: np.ndarray


@njit(cache=True, nogil=True)
def _symbolic(n, ap, ai, perm, pinv):
    # the elimination tree of the reordered matrix's upper triangle (path compression)
    parent = np.full(n, -1, np.int64)
    ancestor = np.full(n, -1, np.int64)
    for k in range(n):
        col = perm[k]
        for p in range(ap[col], ap[col + 1]):
            i = pinv[ai[p]]
            while i != -1 and i < k:
                up = ancestor[i]
                ancestor[i] = k
                if up == -1:
                    parent[i] = k
                i = up
    # each row's reach (the columns its triangular solve touches) and each column's count
    flag = np.full(n, -1, np.int64)
    counts = np.ones(n, np.int64)
    rp = np.zeros(n + 1, np.int64)
    for k in range(n):
        flag[k] = k
        col = perm[k]
        found = 0
        for p in range(ap[col], ap[col + 1]):
            i = pinv[ai[p]]
            if i > k:
                continue
            while flag[i] != k:
                flag[i] = k
                counts[i] += 1
                found += 1
                i = parent[i]
        rp[k + 1] = rp[k] + found
    reach = np.empty(rp[n], np.int64)
    stack = np.empty(n, np.int64)
    flag[:] = -1
    for k in range(n):
        flag[k] = k
        col = perm[k]
        top = rp[k + 1]
        for p in range(ap[col], ap[col + 1]):
            i = pinv[ai[p]]
            if i > k:
                continue
            depth = 0
            while flag[i] != k:  # up the tree to a column already taken: that path, reversed
                stack[depth] = i
                depth += 1
                flag[i] = k
                i = parent[i]
            while depth > 0:
                top -= 1
                depth -= 1
                reach[top] = stack[depth]
    lp = np.zeros(n + 1, np.int64)
    for j in range(n):
        lp[j + 1] = lp[j] + counts[j]
    li = np.empty(lp[n], np.int64)
    nxt = lp[:n].copy()
    for k in range(n):
        for t in range(rp[k], rp[k + 1]):
            j = reach[t]
            li[nxt[j]] = k
            nxt[j] += 1
        li[nxt[k]] = k
        nxt[k] += 1
    return lp, li, rp, reach  # (each column: its diagonal first, then its rows below, increasing)


@njit(cache=True, nogil=True)
def _numeric(n, ap, ai, ax, perm, pinv, lp, li, rp, reach):
    lx = np.empty(lp[n], np.float64)
    nxt = lp[:n] + 1  # each column's next entry below its diagonal
    x = np.zeros(n, np.float64)
    for k in range(n):
        col = perm[k]
        for p in range(ap[col], ap[col + 1]):
            i = pinv[ai[p]]
            if i <= k:
                x[i] = ax[p]
        d = x[k]
        x[k] = 0.0
        for t in range(rp[k], rp[k + 1]):
            j = reach[t]
            lkj = x[j] / lx[lp[j]]
            x[j] = 0.0
            for p in range(lp[j] + 1, nxt[j]):  # column j below its diagonal, rows before k
                x[li[p]] -= lx[p] * lkj
            d -= lkj * lkj
            lx[nxt[j]] = lkj
            nxt[j] += 1
        if not d > 0.0:  # not positive definite (to rounding): no factor
            return lx, False
        lx[lp[k]] = np.sqrt(d)
    return lx, True


@njit(cache=True, nogil=True)
def _triangular_solves(n, lp, li, lx, perm, b):
    y = np.empty(n, np.float64)
    for k in range(n):
        y[k] = b[perm[k]]
    for j in range(n):  # L y = P b
        y[j] /= lx[lp[j]]
        for p in range(lp[j] + 1, lp[j + 1]):
            y[li[p]] -= lx[p] * y[j]
    for j in range(n - 1, -1, -1):  # L^T z = y
        s = y[j]
        for p in range(lp[j] + 1, lp[j + 1]):
            s -= lx[p] * y[li[p]]
        y[j] = s / lx[lp[j]]
    out = np.empty(n, np.float64)
    for k in range(n):
        out[perm[k]] = y[k]
    return out


def analyse(indptr: np.ndarray, indices: np.ndarray, n: int) -> Analysis:
    """The order and the factor's pattern for every symmetric ``n`` x ``n`` matrix whose
    entries lie in the given pattern.

    Args:
        indptr, indices: the pattern in CSC (or CSR: it is symmetric), both triangles, the
            diagonal included: (n + 1,) column starts and the row of each entry.
        n: the matrix's size.
    """
    ap = np.asarray(indptr, np.int64)
    ai = np.asarray(indices, np.int64)
    if ap.shape != (n + 1,) or len(ai) != ap[-1]:
        raise ValueError(f"a pattern of {n} columns needs {n + 1} column starts and as many rows as the last, "
                         f"got {ap.shape[0]} and {len(ai)}")
    pattern = csr_matrix((np.ones(len(ai), np.int8), ai, ap), shape=(n, n))
    perm = np.asarray(reverse_cuthill_mckee(pattern, symmetric_mode=True), np.int64)
    pinv = np.empty(n, np.int64)
    pinv[perm] = np.arange(n)
    lp, li, rp, reach = _symbolic(n, ap, ai, perm, pinv)
    return Analysis(n, perm, pinv, lp, li, rp, reach)


def factor(an: Analysis, indptr: np.ndarray, indices: np.ndarray, data: np.ndarray) -> np.ndarray | None:
    """The values of ``L`` (in :class:`Analysis` ``li``'s layout: ``P A P^T = L L^T``) of the
    symmetric matrix ``A`` in CSC (both triangles; entries outside the analysed pattern are not
    allowed, entries of it that are missing count as 0); None when ``A`` is not positive definite
    (a pivot not above 0)."""
    lx, ok = _numeric(an.n, np.asarray(indptr, np.int64), np.asarray(indices, np.int64),
                      np.asarray(data, np.float64), an.perm, an.pinv, an.lp, an.li, an.rp, an.reach)
    return lx if ok else None


def solve(an: Analysis, lx: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``x`` with ``A x = b``, from :func:`factor`'s ``L`` of ``A``: (n,) float64."""
    return _triangular_solves(an.n, an.lp, an.li, lx, an.perm, np.asarray(b, np.float64))


__all__ = ["Analysis", "analyse", "factor", "solve"]
