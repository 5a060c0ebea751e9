"""Issue 59 items 3, 5, 6: the relative pose error of Kümmerle et al. (2009) and the fits of the
simulated scanner to real scans (benchmark/conditions/relative_error.py, calibration.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmark.conditions.relative_error import consecutive_pairs, distance_pairs, relative_error


def _se2(rows):
    return np.asarray(rows, np.float64)


def test_relative_error_known_answer_translation():
    """A straight path of 1 m moves; the estimate's last pose is 0.1 m off sideways: of the two
    consecutive relations one is off by 0.1 m, none by any angle."""
    truth = _se2([[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    est = _se2([[0, 0, 0], [1, 0, 0], [2, 0.1, 0]])
    e = relative_error(est, truth, consecutive_pairs(3))
    assert e.n == 2
    assert e.trans_mean_m == pytest.approx(0.05)
    assert e.trans_std_m == pytest.approx(0.05)
    assert e.trans_sq_m2 == pytest.approx(0.005)
    assert e.rot_mean_deg == pytest.approx(0.0, abs=1e-12)


def test_relative_error_heading_error_counts_once():
    """A heading error of 0.1 rad at the middle pose, with the rest of the path carried along
    (what a wrong turn does): the relation (0, 1) is off by 0.1 rad and nothing else, the relation
    (1, 2) is exact; the absolute error of pose 2 (0.1 m and 0.1 rad) is not what is measured."""
    truth = _se2([[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    est = _se2([[0, 0, 0], [1, 0, 0.1], [1 + math.cos(0.1), math.sin(0.1), 0.1]])
    e = relative_error(est, truth, consecutive_pairs(3))
    assert e.rot_mean_deg == pytest.approx(math.degrees(0.1) / 2)
    assert e.rot_sq_deg2 == pytest.approx(math.degrees(0.1) ** 2 / 2)
    assert e.trans_mean_m == pytest.approx(0.0, abs=1e-12)
    # the relation (0, 2): the estimate went to (1 + cos .1, sin .1) instead of (2, 0)
    e02 = relative_error(est, truth, np.array([[0, 2]]))
    assert e02.trans_mean_m == pytest.approx(math.hypot(1 - math.cos(0.1), math.sin(0.1)))


def test_relative_error_ignores_a_global_transform():
    """The whole estimate moved and turned: every relation is exact (unlike the ATE)."""
    rng = np.random.default_rng(0)
    truth = np.column_stack([np.cumsum(rng.uniform(0, 1, 30)), np.cumsum(rng.uniform(-1, 1, 30)),
                             rng.uniform(-math.pi, math.pi, 30)])
    a, tx, ty = 0.7, 5.0, -3.0
    est = np.column_stack([math.cos(a) * truth[:, 0] - math.sin(a) * truth[:, 1] + tx,
                           math.sin(a) * truth[:, 0] + math.cos(a) * truth[:, 1] + ty, truth[:, 2] + a])
    e = relative_error(est, truth, distance_pairs(truth, 2.0))
    assert e.n > 10
    assert e.trans_mean_m < 1e-9 and e.rot_mean_deg < 1e-9


def test_distance_pairs_and_bad_relations():
    path = _se2([[0, 0, 0], [0.5, 0, 0], [1.0, 0, 0], [2.5, 0, 0]])
    assert distance_pairs(path, 1.0).tolist() == [[0, 2], [1, 3], [2, 3]]
    with pytest.raises(ValueError, match="relation index 7"):
        relative_error(path, path, np.array([[0, 7]]))
    with pytest.raises(ValueError, match="estimate has 3 poses, reference 4"):
        relative_error(path[:3], path, np.array([[0, 1]]))
    with pytest.raises(ValueError, match="relation distance"):
        distance_pairs(path, 0.0)
