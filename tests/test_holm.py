"""Verdicts corrected for their number (issue 58, item 6): Holm's step-down procedure against
textbook examples, the bootstrap p-value it reads, and the sentence writers on hand-made paired
data where the uncorrected and the corrected verdicts differ."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from benchmark import stats
from benchmark.reports.robustness import cell_means, house_values, rank_notes, summary_table


def test_holm_on_the_textbook_example_of_four_hypotheses():
    """The worked example of Holm's method (Wikipedia, "Holm-Bonferroni method"): p = 0.01, 0.04,
    0.03, 0.005 at alpha 0.05. Sorted, 0.005 <= 0.05/4 and 0.01 <= 0.05/3 are rejected; 0.03 >
    0.05/2 stops the procedure, so H1 and H4 are rejected, H2 and H3 kept. Adjusted p-values (as
    R's p.adjust(method = "holm") gives them): 0.03, 0.06, 0.06, 0.02."""
    p = [0.01, 0.04, 0.03, 0.005]
    adj, rejected = stats.holm(p)
    np.testing.assert_allclose(adj, [0.03, 0.06, 0.06, 0.02])
    assert rejected.tolist() == [True, False, False, True]
    # never above Bonferroni's adjusted p-values (min(1, 4 p): 0.04, 0.16, 0.12, 0.02)
    assert np.all(adj <= np.minimum(1.0, 4 * np.asarray(p)))
    # the alpha each is read at: 0.05/3 (2nd smallest), 0.05/2 for the first one kept and every larger one
    np.testing.assert_allclose(stats.holm_levels(p), [0.05 / 3, 0.05 / 2, 0.05 / 2, 0.05 / 4])


def test_holm_on_the_fifteen_p_values_of_benjamini_and_hochberg_1995():
    """Benjamini and Hochberg's (1995) example of 15 p-values: a Bonferroni-type step procedure
    rejects the three smallest only (0.0095 > 0.05/12 stops Holm's); adjusted p-values by hand."""
    p = [0.0001, 0.0004, 0.0019, 0.0095, 0.0201, 0.0278, 0.0298, 0.0344, 0.0459, 0.3240, 0.4262, 0.5719,
         0.6528, 0.7590, 1.0000]
    adj, rejected = stats.holm(p)
    assert rejected.tolist() == [True] * 3 + [False] * 12
    np.testing.assert_allclose(adj[:9], [0.0015, 0.0056, 0.0247, 0.114, 0.2211, 0.278, 0.278, 0.278, 0.3213])
    np.testing.assert_allclose(adj[9:], 1.0)
    # shuffled, the same answer for each hypothesis
    order = np.random.default_rng(1).permutation(len(p))
    adj2, rej2 = stats.holm(np.asarray(p)[order])
    np.testing.assert_allclose(adj2, adj[order])
    assert rej2.tolist() == rejected[order].tolist()


def test_equal_p_values_share_the_strictest_level_and_a_nan_is_no_comparison():
    p = [0.0, 0.0, 0.0, 0.03, float("nan"), 0.03]
    alphas = stats.holm_levels(p)
    # m = 5 (the NaN is no comparison): three zeros at 0.05/5, then 0.03 > 0.05/2 stops it
    np.testing.assert_allclose(alphas, [0.01, 0.01, 0.01, 0.025, 0.01, 0.025])
    adj, rejected = stats.holm(p)
    assert rejected.tolist() == [True, True, True, False, False, False]
    assert np.isnan(adj[4]) and adj[3] == pytest.approx(0.06) and adj[5] == pytest.approx(0.06)
    # Holm's decision is the level's: p <= its alpha while the procedure has not stopped
    q = np.array([0.004, 0.004, 0.02, 0.049])
    assert stats.holm(q)[1].tolist() == [True, True, True, True]
    np.testing.assert_allclose(stats.holm_levels(q), [0.05 / 4, 0.05 / 4, 0.05 / 2, 0.05])
    assert stats.holm([])[1].tolist() == []


def test_bootstrap_p_is_twice_the_share_on_the_far_side_of_zero():
    assert stats.bootstrap_p([1.0, 2.0, 3.0, -1.0]) == pytest.approx(0.5)
    assert stats.bootstrap_p(np.r_[np.ones(990), -np.ones(10)]) == pytest.approx(0.02)
    assert stats.bootstrap_p([1.0, 2.0]) == 0.0 and stats.bootstrap_p([-1.0, 1.0]) == 1.0
    assert np.isnan(stats.bootstrap_p([1.0])) and np.isnan(stats.paired_p([1.0], [0.0]))
    with pytest.raises(ValueError, match="same houses"):
        stats.paired_p([1.0, 2.0], [1.0])
    assert stats.level_words(0.95) == "95 %" and stats.level_words(1 - 0.05 / 37) == "99.86 %"


def _weak(mu: float, n: int = 30) -> np.ndarray:
    """Per-house differences with mean ``mu`` and a fixed spread (about 2.7 points)."""
    z = np.tile([3.0, -3.0], n // 2) * np.linspace(0.5, 1.5, n)
    return mu + z - z.mean()


def test_the_p_value_and_the_interval_agree_and_holm_turns_two_weak_leads_into_ties():
    weak = _weak(1.2)
    p = stats.paired_p(weak, np.zeros(30))
    d, lo, hi = stats.paired_ci(weak, np.zeros(30))
    assert 0.025 < p < 0.05 and lo > 0  # ahead at 95 % on its own
    # a family of 9 clear leads and 2 such weak ones: the weak ones are read at 5 % / 2 and kept
    strong = [(np.full(30, 20.0) + _weak(0.0), np.zeros(30))] * 9
    verdicts = stats.holm_verdicts(strong + [(weak, np.zeros(30)), (np.zeros(30), weak)])
    assert [v["ahead"] for v in verdicts] == [True] * 9 + [False, False]
    assert {v["m"] for v in verdicts} == {11}
    assert verdicts[0]["level"] == pytest.approx(1 - 0.05 / 11) and verdicts[9]["level"] == pytest.approx(0.975)
    assert verdicts[9]["lo"] <= 0 <= verdicts[9]["hi"] and verdicts[10]["diff"] == pytest.approx(-1.2)
    # alone, a weak lead is a family of one: read at 5 %, ahead
    (alone,) = stats.holm_verdicts([(weak, np.zeros(30))])
    assert alone["ahead"] and alone["level"] == pytest.approx(0.95) and alone["lo"] == pytest.approx(lo)


def test_a_ranking_corrected_for_its_pairs_keeps_weakly_separated_methods_together():
    """A and B 1.2 points apart (p about 0.03), C and D likewise, the two pairs 20 points apart:
    at 95 % each pair is separated ({A} > {B} > {C} > {D}); corrected over the 6 pairs, the 4
    clear ones are rejected and the two weak ones read at 5 % / 2 are not."""
    base = np.linspace(30.0, 60.0, 30)
    values = {"A": base + 20 + _weak(1.2), "B": base + 20, "C": base + _weak(1.2), "D": base}
    assert stats.groups(values) == [["A"], ["B"], ["C"], ["D"]]
    assert stats.groups(values, corrected=True) == [["A", "B"], ["C", "D"]]


def _rows(n: int = 30) -> pd.DataFrame:
    """A (geometric) and B (view-based) on n houses: B 20 points ahead clean and at every
    severity of scan and pose but two, where the difference is weak (p about 0.03): scan 5, A
    ahead by 1.2 (at 95 % a change of places), and pose 3, B ahead by 1.2."""
    base = np.linspace(0.3, 0.6, n)
    rows = []

    def add(method: str, corruption: str, severity: int, v: np.ndarray) -> None:
        rows.extend({"method": method, "corruption": corruption, "severity": severity, "house_id": f"h{h:02d}",
                     "iou": float(x), "status": "ok"} for h, x in enumerate(v))

    add("A", "clean", 0, base)
    add("B", "clean", 0, base + 0.2)
    for fam in ("scan", "pose"):
        for s in range(1, 6):
            add("A", fam, s, base)
            weak = (fam, s) in (("scan", 5), ("pose", 3))
            sign = -1.0 if fam == "scan" else 1.0
            add("B", fam, s, base + (sign * _weak(1.2) / 100 if weak else 0.2 + _weak(0.0) / 100))
    return pd.DataFrame(rows)


def test_the_robustness_sentences_use_intervals_corrected_for_their_family():
    rows = _rows()
    cells, values = cell_means(rows, "iou"), house_values(rows, "iou")
    # uncorrected, both weak differences exclude zero at 95 %
    scan5 = stats.paired_ci(values[("B", "scan", 5)], values[("A", "scan", 5)])
    pose3 = stats.paired_ci(values[("B", "pose", 3)], values[("A", "pose", 3)])
    assert scan5[2] < 0 and pose3[1] > 0
    t = summary_table(cells, reference="B", values=values, n_boot=200)
    notes = rank_notes(t, geometric=["A"], cells=cells, values=values)
    assert notes[0].startswith("Verdicts corrected for their number (Holm 1979")
    assert "one family of 11 comparisons" in notes[0] and "family of its 1 method pairs (2 methods)" in notes[0]
    scan = next(n for n in notes if n.startswith("scan map:"))
    pose = next(n for n in notes if n.startswith("views-only pose noise, perfect map (ablation):"))
    # the clear leads: p 0, read at 5 % / 11
    assert "0: view-based ahead +20.0 [" in scan and "at 99.55 %" in scan
    # the weak ones: kept by Holm, read at 5 % / 2, tied; so no change of places at scan 5
    assert "5: tied -1.2 [" in scan and "] at 97.5 %" in scan
    assert scan.endswith("no change of places that the intervals support")
    assert "3: tied +1.2 [" in pose and "4: view-based ahead +20.0" in pose
    tied = [x for x in (scan + pose).split("; ") if ": tied " in x]
    assert len(tied) == 2
    for part in tied:  # each shown interval holds zero
        lo, hi = (float(x) for x in part.split("[")[1].split("]")[0].split(", "))
        assert lo <= 0 <= hi
