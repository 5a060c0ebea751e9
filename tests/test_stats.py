"""benchmark.stats against known answers: a closed-form normal interval, hand-made
paired tables whose verdict is known, and the textbook sample size of a paired t-test."""

from __future__ import annotations

import numpy as np
import pytest

from benchmark import stats


def test_bootstrap_interval_matches_the_normal_closed_form():
    # normal data: the 95 % interval of the mean is mean +- 1.96 s / sqrt(n)
    x = np.random.default_rng(7).normal(50.0, 8.0, 900)
    half = 1.959963984540054 * x.std(ddof=1) / np.sqrt(x.size)
    lo, hi = stats.bootstrap_ci(x)
    assert lo == pytest.approx(x.mean() - half, abs=0.06 * half)
    assert hi == pytest.approx(x.mean() + half, abs=0.06 * half)
    assert (lo, hi) == stats.bootstrap_ci(x)  # seeded: the same rows give the same interval
    assert stats.bootstrap_ci([3.0]) != stats.bootstrap_ci([3.0])  # (nan, nan): no interval from one house
    assert np.isnan(stats.bootstrap_ci([1.0, np.nan, 2.0])[0])


def test_paired_interval_sees_what_unpaired_intervals_hide():
    # two methods on ten houses: B is A plus 1 point on every house, the houses spread by 30 points
    a = np.linspace(20.0, 80.0, 10)
    b = a + 1.0 + np.array([0.1, -0.1] * 5)
    lo_a, hi_a = stats.bootstrap_ci(a)
    lo_b, hi_b = stats.bootstrap_ci(b)
    assert lo_b < hi_a  # the cells' own intervals overlap ...
    d, lo, hi = stats.paired_ci(b, a)
    assert d == pytest.approx(1.0)
    assert 0.9 <= lo < 1.0 < hi <= 1.1  # ... but the paired one excludes zero
    assert stats.verdict("B", "A", d, lo, hi) == "B ahead of A by 1.0 (95 % CI +0.9 to +1.1 for B - A)"
    d2, lo2, hi2 = stats.paired_ci(a, b)
    assert stats.verdict("A", "B", d2, lo2, hi2).startswith("B ahead of A by 1.0")
    with pytest.raises(ValueError, match="same houses"):
        stats.paired_ci(a, b[:5])


def test_a_difference_inside_the_noise_is_called_a_tie():
    # C minus A alternates +5 / -4: mean +0.5, interval well across zero
    a = np.linspace(20.0, 80.0, 10)
    c = a + np.array([5.0, -4.0] * 5)
    d, lo, hi = stats.paired_ci(c, a)
    assert d == pytest.approx(0.5) and lo < 0 < hi
    words = stats.verdict("C", "A", d, lo, hi)
    assert words.startswith("C and A tied (+0.5, 95 % CI -") and "ahead" not in words


def test_groups_of_methods_that_cannot_be_separated():
    base = np.linspace(20.0, 80.0, 12)
    wiggle = np.array([1.0, -1.0] * 6)
    values = {"a": base + 10, "b": base + 10 + wiggle, "c": base, "d": base - 0.2 + 3 * wiggle}
    grps = stats.groups(values)
    assert grps == [["a", "b"], ["c", "d"]]  # equal means: by name; d is 0.2 below c, noisy
    assert stats.group_words([["a", "b"], ["c"]]) == "{a, b} > {c}"


def test_power_against_the_textbook_paired_t_test():
    # Cohen's d_z = 0.5, alpha 0.05 two-sided, power 0.80: 34 pairs (G*Power; the normal
    # approximation (1.96 + 0.84)^2 / 0.25 = 31.4 is a little low)
    assert stats.houses_needed(sd=1.0, delta=0.5) == 34
    assert stats.power_paired(34, 0.5, 1.0) == pytest.approx(0.808, abs=0.001)
    assert stats.power_paired(33, 0.5, 1.0) < 0.8
    # scale-free: 10 points of spread, 5 points to detect is the same question
    assert stats.houses_needed(sd=10.0, delta=5.0) == 34
    # and back: 34 houses detect d_z just under 0.5
    assert stats.detectable_difference(1.0, 34) == pytest.approx(0.495, abs=0.001)
    # a large effect needs few houses; a tiny one many
    assert stats.houses_needed(1.0, 2.0) < 6 and stats.houses_needed(1.0, 0.1) > 700
    with pytest.raises(ValueError, match="> 0"):
        stats.houses_needed(1.0, 0.0)


def test_tables_rank_rows_in_groups_and_state_a_single_difference_with_its_interval():
    import pandas as pd

    from benchmark.reports.tables import TABLES, summarise

    base = np.linspace(0.2, 0.8, 10)
    rows = []
    for method, v in (("a", base + 0.10), ("b", base + 0.10 + np.array([0.01, -0.01] * 5)), ("c", base)):
        rows += [{"house_id": f"h{i}", "dataset": "synthetic", "method": method, "segmenter_row": True,
                  "status": "ok", "iou": x, "matched_iou": x, "pq": x} for i, x in enumerate(v)]
    summ = summarise(pd.DataFrame(rows), TABLES["table5"])
    lines = [n for n in summ.attrs["notes"] if n.startswith("Ranking on matched IoU")]
    assert lines == ["Ranking on matched IoU (synthetic, paired over 10 houses; braces hold rows no paired "
                     "interval separates, Holm-corrected over the ranking's 3 pairs): {a, b} > {c}."]
    assert summ.set_index("method").loc["a", "matched_iou_lo"] < 0.6 < summ.set_index("method").loc["a", "matched_iou_hi"]
    two = pd.DataFrame([r for r in rows if r["method"] != "b"])
    line = next(n for n in summarise(two, TABLES["table5"]).attrs["notes"] if n.startswith("Ranking on PQ"))
    assert line == ("Ranking on PQ (synthetic, paired over 10 houses): a ahead of c by 10.0 "
                    "(95 % CI +10.0 to +10.0 for a - c).")


def test_table2_ranks_the_viewpoint_strategies_of_each_configuration():
    import pandas as pd

    from benchmark.reports.tables import TABLES, summarise

    base = np.linspace(0.2, 0.8, 8)
    rows = [{"house_id": f"h{i}", "dataset": "synthetic", "classifier": "oracle", "aggregator": agg,
             "viewpoints": vp, "postprocess": "none", "segmenter_row": False, "status": "ok", "iou": x + shift}
            for agg, gap in (("graph_knn", 0.05), ("vision_cone", 0.0))
            for vp, shift in (("autotrace", gap), ("autotrace_sparse", 0.0)) for i, x in enumerate(base)]
    lines = [n for n in summarise(pd.DataFrame(rows), TABLES["table2"]).attrs["notes"] if n.startswith("Ranking")]
    assert lines == [
        "Ranking of oracle + graph KNN on IoU (synthetic, paired over 8 houses): autotrace ahead of autotrace "
        "(sparse) by 5.0 (95 % CI +5.0 to +5.0 for autotrace - autotrace (sparse)).",
        "Ranking of oracle + vision cone on IoU (synthetic, paired over 8 houses): autotrace and autotrace (sparse) "
        "tied (+0.0, 95 % CI +0.0 to +0.0)."]


def test_resamples_are_the_seeded_draws_every_time_and_cannot_be_changed():
    """The resamples a process keeps are the ones the seed draws, for every (n, n_boot, seed),
    the first call and the next ones alike, past the number kept and past the size kept; a
    caller cannot write into them."""
    from benchmark.stats import RESAMPLES_KEPT, resample_indices

    def drawn(n: int, n_boot: int, seed: int) -> np.ndarray:  # written out: the seed's own draw
        return np.random.default_rng(seed).integers(0, n, size=(n_boot, n))

    cases = [(n, b, s) for n in (2, 3, 100) for b in (1, 50, 2000) for s in (0, 7)]
    cases += [(n, 20, 1) for n in range(4, 4 + RESAMPLES_KEPT + 3)]  # more than are kept
    cases.append((40_000, 60, 0))  # 19 MB: over the size kept
    for _ in range(2):
        for n, b, s in cases:
            got = resample_indices(n, b, s)
            assert got.shape == (b, n) and np.array_equal(got, drawn(n, b, s)), (n, b, s)
            with pytest.raises(ValueError):
                got[0, 0] = 1
    assert not np.array_equal(resample_indices(100, 50, 0), resample_indices(100, 50, 7))
