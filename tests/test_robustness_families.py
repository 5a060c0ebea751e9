"""The robustness summary with the newer robot conditions, on hand-made rows with known answers:
``slam`` is a family like scan and pose (in mCE); ``lost`` (3 severities) and ``kidnap`` (2) are
labelled conditions reported apart (a column per condition, in neither mCE nor the mean drop, and
no say in the choice of the reference); a family's own severity-0 rows (``explore`` 0: the
unlimited frontier run) are its severity 0 for the drop, the relative CE, the curves and the
flips, and the clean rows are where the run has none."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from benchmark.reports.robustness import (
    FAMILIES,
    FAMILY_WORDS,
    RobustnessError,
    cell_means,
    complete_families,
    house_values,
    rank_notes,
    rising_curves,
    summary_table,
)


def _rows(spec: dict[str, dict[tuple[str, int], float]], houses=("h1", "h2")) -> pd.DataFrame:
    """Per method, (corruption, severity) -> the mean over houses (a fraction); the two houses sit
    0.02 above and below it in every cell, so every paired difference is the same on both."""
    rows = []
    for m, cells in spec.items():
        for (c, s), v in cells.items():
            for k, h in enumerate(houses):
                rows.append({"method": m, "corruption": c, "severity": s, "house_id": h,
                             "iou": v + (0.02 if k == 0 else -0.02), "status": "ok"})
    return pd.DataFrame(rows)


def _ladder(family: str, values) -> dict[tuple[str, int], float]:
    return {(family, s): v for s, v in enumerate(values, start=1)}


def test_the_families_and_their_words():
    assert FAMILIES == ("scan", "pose", "slam", "explore", "classifier", "realistic", "lost", "kidnap", "views_final")
    assert FAMILY_WORDS["slam"] == "SLAM (one pose estimate)"
    assert FAMILY_WORDS["pose"] == "views-only pose noise, perfect map (ablation)"
    assert FAMILY_WORDS["lost"] == "lost robot (wrong loop closures)"
    assert FAMILY_WORDS["kidnap"] == "kidnapped robot"


def test_slam_counts_in_mce_like_scan_and_pose():
    spec = {"A": {("clean", 0): 0.90, **_ladder("scan", (0.80, 0.70, 0.60, 0.50, 0.40)), **_ladder("slam", (0.85,) * 5)},
            "B": {("clean", 0): 0.95, **_ladder("scan", (0.90, 0.85, 0.80, 0.75, 0.70)), **_ladder("slam", (0.60,) * 5)}}
    t = summary_table(cell_means(_rows(spec), "iou"), reference="A")
    # errors: scan A 200, B 100; slam A 5 x 15 = 75, B 5 x 40 = 200
    assert t.loc["B", "CE slam"] == pytest.approx(100 * 200 / 75)
    assert t.loc["B", "mCE"] == pytest.approx((50 + 100 * 200 / 75) / 2)
    # relative: slam A 5 x 5 = 25, B 5 x 35 = 175 -> 700; scan 75 / 150 -> 50
    assert t.loc["B", "rel mCE"] == pytest.approx((50 + 700) / 2)
    assert t.loc["B", "mean drop"] == pytest.approx((15 + 35) / 2)
    assert list(t.columns) == ["clean", "scan", "slam", "CE scan", "CE slam", "mCE", "rel CE scan", "rel CE slam",
                               "rel mCE", "drop scan", "drop slam", "mean drop"]


def _labelled_spec():
    """A drops 5 under scan, B 25: B is the reference auto picks unless kidnap (which spares B)
    counted. lost: A 70/60/50, B 50 x 3; kidnap: A 80/70, B 95 x 2 (its clean score)."""
    return {"A": {("clean", 0): 0.90, **_ladder("scan", (0.85,) * 5), **_ladder("lost", (0.70, 0.60, 0.50)),
                  **_ladder("kidnap", (0.80, 0.70))},
            "B": {("clean", 0): 0.95, **_ladder("scan", (0.80, 0.75, 0.70, 0.65, 0.60)), **_ladder("lost", (0.50,) * 3),
                  **_ladder("kidnap", (0.95, 0.95))}}


def test_lost_and_kidnap_are_reported_apart_with_three_and_two_severities():
    rows = _rows(_labelled_spec())
    cells = cell_means(rows, "iou")
    kept, notes = complete_families(cells)
    assert kept == ["scan", "lost", "kidnap"] and notes == []  # fewer than five severities is a whole family
    t = summary_table(cells, reference=None, families=kept, values=house_values(rows, "iou"), n_boot=200)
    assert t.attrs["reference"] == "B"  # kidnap spares B, but a labelled condition has no say in the choice
    a, b = t.loc["A"], t.loc["B"]
    # scan errors A 5 x 15 = 75, B 20+25+30+35+40 = 150; the only family in mCE
    assert a["CE scan"] == pytest.approx(50) and a["mCE"] == pytest.approx(50)
    assert a["rel mCE"] == pytest.approx(100 * 25 / 125) and a["mean drop"] == pytest.approx(5)
    assert b["mean drop"] == pytest.approx(25)
    # lost: errors A 30+40+50 = 120, B 3 x 50 = 150; relative A 20+30+40 = 90, B 3 x 45 = 135
    assert a["CE lost"] == pytest.approx(80) and a["rel CE lost"] == pytest.approx(100 * 90 / 135)
    assert a["lost 1"] == pytest.approx(70) and a["lost 3"] == pytest.approx(50) and a["lost"] == pytest.approx(60)
    assert a["drop lost"] == pytest.approx(30) and b["drop lost"] == pytest.approx(45)
    # kidnap leaves the reference untouched: no CE there, its drop still shown
    assert np.isnan(a["CE kidnap"]) and a["drop kidnap"] == pytest.approx(15) and b["drop kidnap"] == pytest.approx(0)
    assert a["kidnap 2"] == pytest.approx(70) and "kidnap 3" not in t.columns
    cols = [c for c in t.columns if not c.endswith((" lo", " hi"))]
    assert cols == ["clean", "scan", "CE scan", "mCE", "rel CE scan", "rel mCE", "drop scan", "mean drop",
                    "lost 1", "lost 2", "lost 3", "lost", "CE lost", "rel CE lost", "drop lost",
                    "kidnap 1", "kidnap 2", "kidnap", "CE kidnap", "rel CE kidnap", "drop kidnap"]
    assert t.loc["A", "lost 2 lo"] <= 60 <= t.loc["A", "lost 2 hi"]
    assert any(n.startswith("lost robot (wrong loop closures), kidnapped robot: labelled conditions") for n in
               t.attrs["notes"])
    assert any("No CE for kidnapped robot: it does not degrade the reference B" in n for n in t.attrs["notes"])


def test_a_labelled_condition_missing_one_of_its_severities_is_left_out():
    rows = _rows(_labelled_spec())
    gone = rows[~((rows["corruption"] == "lost") & (rows["severity"] == 2))]
    kept, notes = complete_families(cell_means(gone, "iou"))
    assert kept == ["scan", "kidnap"] and notes[0].startswith("lost robot (wrong loop closures) left out of the "
                                                              "summary: severity 2 has no rows for any method")
    top = rows[~((rows["corruption"] == "lost") & (rows["severity"] == 3))]
    kept, notes = complete_families(cell_means(top, "iou"), expected={"scan": range(1, 6), "lost": [1, 2, 3],
                                                                      "kidnap": [1, 2]})
    assert kept == ["scan", "kidnap"] and "severity 3 has no rows for any method" in notes[0]


def _explore_spec(own_zero: bool = True):
    """A (geometric) and B (view-based): clean 90 / 95; explore's own severity 0 80 / 60; explore
    1..5 A 70..30 (mean 50), B 65 x 5; scan A 80..40, B 90..70."""
    spec = {"A": {("clean", 0): 0.90, **_ladder("scan", (0.80, 0.70, 0.60, 0.50, 0.40)),
                  **_ladder("explore", (0.70, 0.60, 0.50, 0.40, 0.30))},
            "B": {("clean", 0): 0.95, **_ladder("scan", (0.90, 0.85, 0.80, 0.75, 0.70)),
                  **_ladder("explore", (0.65,) * 5)}}
    if own_zero:
        spec["A"][("explore", 0)] = 0.80
        spec["B"][("explore", 0)] = 0.60
    return spec


def test_explore_own_severity_zero_is_where_its_drop_and_relative_ce_start():
    rows = _rows(_explore_spec())
    cells = cell_means(rows, "iou")
    kept, notes = complete_families(cells)
    assert kept == ["scan", "explore"] and notes == []
    values = house_values(rows, "iou")
    t = summary_table(cells, reference="A", families=kept, values=values, n_boot=200)
    a, b = t.loc["A"], t.loc["B"]
    assert a["clean"] == pytest.approx(90) and b["clean"] == pytest.approx(95)  # the clean column: the clean rows
    assert a["explore"] == pytest.approx(50) and b["explore"] == pytest.approx(65)  # severity 0 not in the mean
    assert a["drop explore"] == pytest.approx(80 - 50) and b["drop explore"] == pytest.approx(60 - 65)
    # CE sums severities 1..5 only: errors B 5 x 35 = 175, A 30+40+50+60+70 = 250
    assert b["CE explore"] == pytest.approx(70)
    # relative CE from the own severity 0: B 5 x (-5) = -25 over A 5 x 30 = 150
    assert b["rel CE explore"] == pytest.approx(100 * -25 / 150)
    assert b["rel mCE"] == pytest.approx((50 + 100 * -25 / 150) / 2) and b["mCE"] == pytest.approx((50 + 70) / 2)
    assert b["mean drop"] == pytest.approx((15 - 5) / 2)
    assert t.attrs["notes"][0].startswith("explore: severity 0 is the unlimited frontier run (every method on the "
                                          "explorer's own map), not clean")
    # the curve starts at the own severity 0: B rises 60 -> 65 from 0 to 1 (from clean, 95, it would fall)
    curves = rising_curves(values, ["explore"])
    (r,) = curves.itertuples()
    assert (r.method, r.family, r.step, r.significant) == ("B", "explore", "0->1", True)
    assert r.rise == pytest.approx(5)
    # at severity 0 of explore the geometric A leads by 20 (against clean, B would lead by 5)
    notes = rank_notes(t, ["A"], cells, values)
    explore = next(n for n in notes if n.startswith("exploration budget:"))
    assert "0: geometric ahead -20.0 [-20.0, -20.0]" in explore
    # A leads at 0 and 1, B from 2 on: one change of places (from clean, B's lead at 0 would add one at 1)
    assert "1: geometric ahead -5.0" in explore and explore.endswith("they change places at severity 2")


def test_without_its_own_severity_zero_explore_starts_from_clean():
    rows = _rows(_explore_spec(own_zero=False))
    cells = cell_means(rows, "iou")
    values = house_values(rows, "iou")
    t = summary_table(cells, reference="A", families=["scan", "explore"], values=values, n_boot=200)
    a, b = t.loc["A"], t.loc["B"]
    assert a["drop explore"] == pytest.approx(90 - 50) and b["drop explore"] == pytest.approx(95 - 65)
    assert b["rel CE explore"] == pytest.approx(100 * 150 / 200) and b["CE explore"] == pytest.approx(70)
    assert not any("severity 0 is" in n for n in t.attrs["notes"])
    assert len(rising_curves(values, ["explore"])) == 0
    explore = next(n for n in rank_notes(t, ["A"], cells, values) if n.startswith("exploration budget:"))
    assert "0: view-based ahead +5.0 [+5.0, +5.0]" in explore and explore.endswith("change places at severities 1, 2")


def test_an_own_severity_zero_for_some_methods_only_is_a_gap_not_a_mix():
    rows = _rows(_explore_spec())
    some = rows[~((rows["method"] == "B") & (rows["corruption"] == "explore") & (rows["severity"] == 0))]
    cells = cell_means(some, "iou")
    kept, notes = complete_families(cells)
    assert kept == ["scan"]
    assert notes == ["exploration budget left out of the summary: severity 0 has no rows for B (a mean over the "
                     "other severities would not compare)"]
    with pytest.raises(RobustnessError, match=r"B: family explore has severities \[1, 2, 3, 4, 5\], others \[0, 1"):
        summary_table(cells, reference="A")
    # a sweep that asked for explore_0 and got it for no method: the family is left out too
    none = rows[~((rows["corruption"] == "explore") & (rows["severity"] == 0))]
    kept, notes = complete_families(cell_means(none, "iou"), expected={"scan": range(1, 6), "explore": range(0, 6)})
    assert kept == ["scan"] and "severity 0 has no rows for any method" in notes[0]


ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
PUBLISHED = ROOT / "results" / "published" / "robustness" / "metrics.csv"


def _published_with_new_conditions(folder, houses: int = 3) -> pd.DataFrame:
    """The published run's rows on its first ``houses`` houses, plus made-up rows for the new
    conditions: explore's own severity 0 (its severity-1 rows, matched IoU 0.05 higher), lost 1..3
    (copies of pose 1..3) and kidnap 1..2 (copies of scan 1..2); written to ``folder``/metrics.csv."""
    rows = pd.read_csv(PUBLISHED, low_memory=False)
    keep = sorted(rows["house_id"].unique())[:houses]
    rows = rows[rows["house_id"].isin(keep)]
    # the published run has these conditions itself now: their made-up rows replace them
    made_up = rows["corruption"].isin(["lost", "kidnap"]) | ((rows["corruption"] == "explore") & (rows["severity"] == 0))
    rows = rows[~made_up]
    zero = rows[(rows["corruption"] == "explore") & (rows["severity"] == 1)].copy()
    zero["severity"] = 0
    zero["matched_iou"] = (zero["matched_iou"] + 0.05).clip(upper=1.0)
    lost = rows[(rows["corruption"] == "pose") & (rows["severity"] <= 3)].assign(corruption="lost")
    kidnap = rows[(rows["corruption"] == "scan") & (rows["severity"] <= 2)].assign(corruption="kidnap")
    out = pd.concat([rows, zero, lost, kidnap], ignore_index=True)
    out.to_csv(folder / "metrics.csv", index=False)
    return out


@pytest.mark.slow
def test_the_command_reports_the_own_severity_zero_and_the_labelled_conditions(tmp_path):
    from benchmark.commands.robustness import render
    from benchmark.reports.tables import load_rows

    run = tmp_path / "run"
    run.mkdir()
    _published_with_new_conditions(run)
    out = tmp_path / "out"
    (out / "figures").mkdir(parents=True)
    md = render([run], out, ["matched_iou"], "auto")
    t = pd.read_csv(out / "robustness_procthor_matched_iou.csv", index_col="method")
    # the reference computation: plain group means of the rows as the command reads them (methods named alike)
    rows = load_rows([run])
    rows = rows[rows["dataset"] == "procthor"]
    mean = rows.groupby(["method", "corruption", "severity"])["matched_iou"].mean() * 100
    for m in t.index:
        fam = np.mean([mean[(m, "explore", s)] for s in range(1, 6)])
        assert t.loc[m, "drop explore"] == pytest.approx(mean[(m, "explore", 0)] - fam, abs=1e-3)
        assert t.loc[m, "clean"] == pytest.approx(mean[(m, "clean", 0)], abs=1e-3)
        assert t.loc[m, "drop pose"] == pytest.approx(mean[(m, "clean", 0)] - np.mean(
            [mean[(m, "pose", s)] for s in range(1, 6)]), abs=1e-3)
        assert t.loc[m, "lost 3"] == pytest.approx(mean[(m, "pose", 3)], abs=1e-3)
        assert t.loc[m, "drop kidnap"] == pytest.approx(mean[(m, "clean", 0)] - np.mean(
            [mean[(m, "scan", s)] for s in (1, 2)]), abs=1e-3)
        plain = ["scan", "slam", "explore", "classifier"]  # lost, kidnap, realistic and the ablation pose apart
        assert t.loc[m, "mean drop"] == pytest.approx(np.mean([t.loc[m, f"drop {f}"] for f in plain]), abs=1e-3)
    assert "- explore: severity 0 is the unlimited frontier run" in md
    assert ("| method | lost 1 | lost 2 | lost 3 | lost | drop lost | kidnap 1 | kidnap 2 | kidnap | drop kidnap |"
            in md)
    # the published run holds views_final (its rows are kept): a labelled condition too
    assert "The labelled conditions (`lost`, `kidnap`, `views_final`: each severity a situation of its own" in md
    figures = {p.name for p in (out / "figures").iterdir()}
    assert "robustness_procthor_matched_iou_explore.png" in figures
    assert not any("lost" in f or "kidnap" in f for f in figures)  # no ladder to draw
    assert "| lost | 3 |" in md and "| kidnap | 2 |" in md and "| slam | 5 |" in md  # what each severity sets
