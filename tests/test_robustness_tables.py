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
    rank_notes,
    summary_table,
    to_latex,
    to_markdown,
)

# per method: clean, scan severities 1..5, pose severities 1..5 (IoU as fractions)
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
            for fam, vals in (("scan", scan), ("pose", pose)):
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
    assert a["CE pose"] == pytest.approx(100) and b["CE pose"] == pytest.approx(100 * 200 / 75)
    assert b["mCE"] == pytest.approx((50 + 100 * 200 / 75) / 2) and a["mCE"] == pytest.approx(100)
    assert a["drop scan"] == pytest.approx(30) and b["drop scan"] == pytest.approx(15)
    assert b["drop pose"] == pytest.approx(35) and b["mean drop"] == pytest.approx(25)
    assert list(t.index) == ["A", "B"]  # sorted by mCE: the reference (100) before B (158.3)
    assert list(t.columns) == ["clean", "scan", "pose", "CE scan", "CE pose", "mCE", "drop scan", "drop pose",
                               "mean drop"]
    md = to_markdown(t)
    assert "| B | 95.0 | 80.0 | 60.0 | 50.0 | 266.7 | 158.3 | 15.0 | 35.0 | 25.0 |" in md
    assert r"\toprule" in to_latex(t, "caption", "tab:x") and "266.7" in to_latex(t, "c", "l")


def test_rank_notes_say_who_leads_and_whether_geometry_overtakes():
    t = summary_table(cell_means(_rows(), "iou"), reference="A")
    cells = cell_means(_rows(), "iou")
    notes = rank_notes(t, geometric=["A"], cells=cells)
    assert notes[0] == "clean: B first (95.0); best view-based 95.0, best geometric 90.0 (view-based ahead)"
    # pose: B (60) below A (85) at every severity, but above it clean: the ranking flips at severity 1
    assert notes[2] == ("pose error: A first (85.0); best view-based 60.0, best geometric 85.0 (view-based ahead "
                        "at severity 0, geometric ahead at severities 1-5)")
    assert notes[1] == ("scan map: B first (80.0); best view-based 80.0, best geometric 60.0 "
                        "(view-based ahead)")  # ahead at every severity: no flip to report


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
    partial = rows[~((rows["method"] == "A") & (rows["corruption"] == "pose") & (rows["severity"] == 5))]
    with pytest.raises(RobustnessError, match="A: family pose has severities"):
        summary_table(cell_means(partial[partial["method"] == "A"], "iou").pipe(
            lambda c: pd.concat([c, cell_means(rows[rows["method"] == "B"], "iou")])), reference="A")


def test_a_reference_without_error_gives_no_corruption_error():
    perfect = {"A": (1.0, (1.0,) * 5, (1.0,) * 5), "B": VALUES["B"]}
    rows = _rows(perfect, houses=("h1",))
    rows["iou"] = rows["iou"].clip(upper=1.0)
    rows.loc[rows["method"] == "A", "iou"] = 1.0
    t = summary_table(cell_means(rows, "iou"), reference="A")
    assert np.isnan(t.loc["B", "CE scan"]) and np.isnan(t.loc["B", "mCE"])
