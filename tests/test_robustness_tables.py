"""The robustness summary's arithmetic on a hand-made table with known answers (issue 26):
error = 100 - metric, CE per family = summed error over severities / the reference's, mCE the
mean over families, drop = clean - mean over severities; cells never mix house sets."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from benchmark.reports.robustness import (
    RobustnessError,
    cell_means,
    complete_families,
    house_values,
    rank_notes,
    rising_curves,
    summary_table,
    to_latex,
    to_markdown,
)

# per method: clean, scan severities 1..5, slam severities 1..5 (IoU as fractions; slam, not the
# views-only ablation pose, which counts in no mean)
VALUES = {
    "A": (0.90, (0.80, 0.70, 0.60, 0.50, 0.40), (0.85,) * 5),
    "B": (0.95, (0.90, 0.85, 0.80, 0.75, 0.70), (0.60,) * 5),
}


def _rows(values=VALUES, houses=("h1", "h2")) -> pd.DataFrame:
    rows = []
    for m, (clean, scan, pose) in values.items():
        for k, h in enumerate(houses):
            d = 0.02 if k == 0 else -0.02  # houses differ; their mean is the value above
            rows.append({"method": m, "corruption": "clean", "severity": 0, "house_id": h, "iou": clean + d,
                         "status": "ok"})
            for fam, vals in (("scan", scan), ("slam", pose)):
                for s, v in enumerate(vals, start=1):
                    rows.append({"method": m, "corruption": fam, "severity": s, "house_id": h, "iou": v + d,
                                 "status": "ok"})
    return pd.DataFrame(rows)


def test_corruption_error_and_drop_by_hand():
    t = summary_table(cell_means(_rows(), "iou"), reference="A")
    a, b = t.loc["A"], t.loc["B"]
    assert a["clean"] == pytest.approx(90) and b["clean"] == pytest.approx(95)
    assert a["scan"] == pytest.approx(60) and b["scan"] == pytest.approx(80)
    # errors: A scan 20+30+40+50+60 = 200, B 10+15+20+25+30 = 100; pose A 5 x 15 = 75, B 5 x 40 = 200
    assert a["CE scan"] == pytest.approx(100) and b["CE scan"] == pytest.approx(50)
    assert a["CE slam"] == pytest.approx(100) and b["CE slam"] == pytest.approx(100 * 200 / 75)
    assert b["mCE"] == pytest.approx((50 + 100 * 200 / 75) / 2) and a["mCE"] == pytest.approx(100)
    # relative CE: errors above each method's clean error; A scan 5 x 30 = 150, B 5 x 15 = 75;
    # pose A 5 x 5 = 25, B 5 x 35 = 175
    assert b["rel CE scan"] == pytest.approx(50) and b["rel CE slam"] == pytest.approx(700)
    assert b["rel mCE"] == pytest.approx(375) and a["rel mCE"] == pytest.approx(100)
    assert a["drop scan"] == pytest.approx(30) and b["drop scan"] == pytest.approx(15)
    assert b["drop slam"] == pytest.approx(35) and b["mean drop"] == pytest.approx(25)
    assert list(t.index) == ["A", "B"]  # sorted by mCE: the reference (100) before B (158.3)
    assert list(t.columns) == ["clean", "scan", "slam", "CE scan", "CE slam", "mCE", "rel CE scan", "rel CE slam",
                               "rel mCE", "drop scan", "drop slam", "mean drop"]
    md = to_markdown(t)
    assert "| B | 95.0 | 80.0 | 60.0 | 50.0 | 266.7 | 158.3 | 50.0 | 700.0 | 375.0 | 15.0 | 35.0 | 25.0 |" in md
    assert r"\toprule" in to_latex(t, "caption", "tab:x") and "266.7" in to_latex(t, "c", "l")


def test_realistic_stands_apart_and_a_family_that_spares_the_reference_gets_no_ce():
    rows = _rows()
    extra = rows[rows["corruption"] == "scan"].copy()
    extra["corruption"] = "realistic"
    rows = pd.concat([rows, extra], ignore_index=True)
    # A is untouched by pose: CE against A there would measure clean accuracy
    rows.loc[(rows["method"] == "A") & (rows["corruption"] == "slam"), "iou"] = \
        rows.loc[(rows["method"] == "A") & (rows["corruption"] == "clean"), "iou"].to_numpy().repeat(5)
    t = summary_table(cell_means(rows, "iou"), reference="A")
    assert np.isnan(t.loc["B", "CE slam"]) and t.loc["B", "mCE"] == pytest.approx(50)  # scan only
    assert t.loc["B", "CE realistic"] == pytest.approx(50)  # reported ...
    assert list(t.columns)[-4:] == ["realistic", "CE realistic", "rel CE realistic", "drop realistic"]  # ... apart
    assert t.loc["B", "mean drop"] == pytest.approx((15 + 35) / 2)  # realistic not in the mean
    assert any("No CE for SLAM (one pose estimate): it does not degrade the reference A" in n for n in t.attrs["notes"])


def _noisy_rows(n=12):
    """A (geometric) and B (view-based) on n houses with per-house spread: B leads clean by
    10 +- 1 (clear); under slam, B - A is +10 at severities 1-2, +0.5 +- 5 at 3 (a tie), -10 at
    4-5 (clear): a change of places at severity 4, not 3."""
    rng = np.random.default_rng(3)
    base = rng.uniform(0.3, 0.6, n)
    rows = []
    for h in range(n):
        wig = 0.05 if h % 2 else -0.05
        for m, clean, pose in (("A", base[h], [base[h]] * 5),
                               ("B", base[h] + 0.10 + wig / 5, [base[h] + 0.10, base[h] + 0.10, base[h] + 0.005 + wig,
                                                              base[h] - 0.10, base[h] - 0.10])):
            rows.append({"method": m, "corruption": "clean", "severity": 0, "house_id": f"h{h:02d}", "iou": clean,
                         "status": "ok"})
            rows += [{"method": m, "corruption": "slam", "severity": s, "house_id": f"h{h:02d}", "iou": v,
                      "status": "ok"} for s, v in enumerate(pose, start=1)]
    return pd.DataFrame(rows)


def test_rank_notes_say_ahead_only_where_the_paired_interval_excludes_zero():
    rows = _noisy_rows()
    cells = cell_means(rows, "iou")
    values = house_values(rows, "iou")
    t = summary_table(cells, reference="B", values=values)
    assert t.loc["B", "clean lo"] < t.loc["B", "clean"] < t.loc["B", "clean hi"]
    notes = rank_notes(t, geometric=["A"], cells=cells, values=values)
    assert notes[0].startswith("Verdicts corrected for their number (Holm 1979")
    assert notes[1].startswith("clean: {B} > {A}; best view-based minus best geometric (paired interval, "
                               "Holm-corrected): view-based ahead +10.0 [")
    pose = notes[2]
    assert pose.startswith("SLAM (one pose estimate): {B, A}")  # over the family's mean (B +0.1) they cannot be separated
    assert "3: tied +0.5 [" in pose and "1: view-based ahead +10.0 [+10.0, +10.0]" in pose
    assert "4: geometric ahead -10.0" in pose and pose.endswith("they change places at severity 4")


def test_rising_curves_are_listed_with_their_intervals():
    rows = _noisy_rows()
    curves = rising_curves(house_values(rows, "iou"), ["slam"])
    b = curves[curves["method"] == "B"].set_index("step")
    assert list(b.index) == []  # B only falls (10 -> 10 is no rise)
    rows.loc[(rows["method"] == "A") & (rows["severity"] == 5), "iou"] += 0.02
    curves = rising_curves(house_values(rows, "iou"), ["slam"])
    (r,) = curves.itertuples()
    assert (r.method, r.step, r.significant) == ("A", "4->5", True) and r.rise == pytest.approx(2.0)


def test_a_severity_missing_for_every_method_leaves_its_family_out():
    """issue 38: scan_3 gone for all methods passed the old check (methods agreed with each other)."""
    rows = _rows()
    gone = rows[~((rows["corruption"] == "scan") & (rows["severity"] == 3))]
    kept, notes = complete_families(cell_means(gone, "iou"))
    assert kept == ["slam"]
    assert notes == ["scan map left out of the summary: severity 3 has no rows for any method (a mean over the "
                     "other severities would not compare)"]
    # the top severity gone for all: found when the sweep says what it asked for
    top = rows[~((rows["corruption"] == "slam") & (rows["severity"] == 5))]
    assert complete_families(cell_means(top, "iou"))[0] == ["scan", "slam"]
    kept, notes = complete_families(cell_means(top, "iou"), expected={"scan": range(1, 6), "slam": range(1, 6)})
    assert kept == ["scan"] and "severity 5 has no rows for any method" in notes[0]
    one = rows[~((rows["corruption"] == "slam") & (rows["severity"] == 2) & (rows["method"] == "B"))]
    kept, notes = complete_families(cell_means(one, "iou"))
    assert kept == ["scan"] and "SLAM (one pose estimate) left out of the summary: severity 2 has no rows for B" in notes[0]


def test_cells_never_mix_house_sets_or_hide_failures():
    rows = _rows()
    odd = rows[~((rows["method"] == "B") & (rows["corruption"] == "scan") & (rows["severity"] == 3)
                 & (rows["house_id"] == "h2"))]
    with pytest.raises(RobustnessError, match="different house sets.*B / scan 3"):
        cell_means(odd, "iou")
    bad = rows.copy()
    bad.loc[bad.index[5], "status"] = "failed"
    with pytest.raises(RobustnessError, match="1 failed row"):
        cell_means(bad, "iou")
    with pytest.raises(RobustnessError, match="reference method 'C'"):
        summary_table(cell_means(rows, "iou"), reference="C")
    partial = rows[~((rows["method"] == "A") & (rows["corruption"] == "slam") & (rows["severity"] == 5))]
    with pytest.raises(RobustnessError, match="A: family slam has severities"):
        summary_table(cell_means(partial[partial["method"] == "A"], "iou").pipe(
            lambda c: pd.concat([c, cell_means(rows[rows["method"] == "B"], "iou")])), reference="A")


def test_a_reference_without_error_gives_no_corruption_error():
    perfect = {"A": (1.0, (1.0,) * 5, (1.0,) * 5), "B": VALUES["B"]}
    rows = _rows(perfect, houses=("h1",))
    rows["iou"] = rows["iou"].clip(upper=1.0)
    rows.loc[rows["method"] == "A", "iou"] = 1.0
    t = summary_table(cell_means(rows, "iou"), reference="A")
    assert np.isnan(t.loc["B", "CE scan"]) and np.isnan(t.loc["B", "mCE"])
