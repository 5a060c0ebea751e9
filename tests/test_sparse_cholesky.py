"""The sparse Cholesky of the pose-graph solve against NumPy's dense solver (no code shared):
random symmetric positive definite matrices on sparse patterns, a matrix missing entries of its
analysed pattern, the normal equations of real pose graphs, and matrices that are not positive
definite."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import csc_matrix
from scipy.sparse import random as sparse_random

from benchmark.conditions import sparse_cholesky as sc


def _spd(n: int, density: float, seed: int) -> csc_matrix:
    rng = np.random.default_rng(seed)
    b = sparse_random(n, n, density=density, random_state=rng, format="csc")
    a = (b @ b.T).tocsc()
    a = a + csc_matrix(np.diag(rng.uniform(0.5, 2.0, n)))
    a = csc_matrix(a)
    a.sum_duplicates()
    a.sort_indices()
    return a


@pytest.mark.parametrize("n,density,seed", [(1, 1.0, 0), (2, 0.5, 1), (7, 0.3, 2), (40, 0.05, 3), (200, 0.01, 4),
                                            (300, 0.002, 5)])
def test_solutions_are_numpys(n, density, seed):
    a = _spd(n, density, seed)
    an = sc.analyse(a.indptr, a.indices, n)
    assert sorted(an.perm.tolist()) == list(range(n))
    lx = sc.factor(an, a.indptr, a.indices, a.data)
    assert lx is not None
    rng = np.random.default_rng(seed + 100)
    for _ in range(3):
        b = rng.normal(size=n)
        x = sc.solve(an, lx, b)
        np.testing.assert_allclose(x, np.linalg.solve(a.toarray(), b), rtol=1e-9, atol=1e-12)
    # the factor itself: P A P^T = L L^T
    low = np.zeros((n, n))
    for j in range(n):
        for p in range(an.lp[j], an.lp[j + 1]):
            low[an.li[p], j] = lx[p]
    assert np.allclose(np.triu(low, 1), 0.0)
    dense = a.toarray()[np.ix_(an.perm, an.perm)]
    np.testing.assert_allclose(low @ low.T, dense, atol=1e-10 * np.abs(dense).max())


def test_entries_missing_from_the_analysed_pattern_count_as_zero():
    """One analysis (a denser pattern) serves a matrix with fewer entries, as the solve's
    pattern serves normal equations whose entries come to exactly 0."""
    full = _spd(60, 0.05, 7)
    an = sc.analyse(full.indptr, full.indices, 60)
    sparse = full.toarray()
    rng = np.random.default_rng(8)
    off = [(i, j) for i, j in zip(*np.nonzero(sparse)) if i < j]
    for k in rng.choice(len(off), len(off) // 3, replace=False):  # a third of the pairs off
        i, j = off[k]
        sparse[i, j] = sparse[j, i] = 0.0
    sparse += np.diag(np.abs(sparse).sum(1))  # (kept diagonally dominant: positive definite)
    m = csc_matrix(sparse)
    assert m.nnz < full.nnz
    b = rng.normal(size=60)
    x = sc.solve(an, sc.factor(an, m.indptr, m.indices, m.data), b)
    np.testing.assert_allclose(x, np.linalg.solve(sparse, b), rtol=1e-9, atol=1e-12)


def test_pose_graph_normal_equations():
    """The damped normal equations of a chain with loop closures, on the solve's own pattern."""
    from benchmark.conditions import pose_graph as pg
    from benchmark.conditions.pose_graph import PoseGraph

    rng = np.random.default_rng(3)
    n, extra = 80, 20
    i = np.r_[np.arange(n - 1), rng.integers(0, n, extra)]
    j = np.r_[np.arange(1, n), rng.integers(0, n, extra)]
    graph = PoseGraph(n, i, j, rng.normal(0, 0.5, (len(i), 3)), np.triu(rng.normal(0, 1, (len(i), 3, 3))) + 3 * np.eye(3))
    states = rng.normal(0, 2, (n, 3))
    r = pg.residuals(states, graph).ravel()
    indptr, indices, data, g, diag, at = pg._normal_equations(
        *pg._blocks(states, graph), np.asarray(i, np.int64), np.asarray(j, np.int64), r, *pg._incidence(graph), n)
    size = 3 * (n - 1)
    an = sc.analyse(*pg._block_pattern(graph), size)
    for lam in (1e-8, 1e-4, 10.0):
        damped = data.copy()
        damped[at] += lam * np.maximum(diag, 1e-12)
        a = csc_matrix((damped, indices, indptr), shape=(size, size)).toarray()
        x = sc.solve(an, sc.factor(an, indptr, indices, damped), -g)
        np.testing.assert_allclose(x, np.linalg.solve(a, -g), rtol=1e-7, atol=1e-10)


def test_not_positive_definite_gives_none_and_bad_patterns_one_line():
    a = csc_matrix(np.array([[1.0, 2.0], [2.0, 1.0]]))  # eigenvalues 3 and -1
    an = sc.analyse(a.indptr, a.indices, 2)
    assert sc.factor(an, a.indptr, a.indices, a.data) is None
    assert sc.factor(an, np.array([0, 1, 2]), np.array([0, 1]), np.array([0.0, 1.0])) is None  # a zero pivot
    with pytest.raises(ValueError, match="a pattern of 3 columns needs 4 column starts"):
        sc.analyse(a.indptr, a.indices, 3)
