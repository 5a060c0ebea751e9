"""The ipa rows of the robustness benchmark (issue 60 item 5): the authors' ipa_room_segmentation
runs on houses and conditions of its own (``experiment=robustness_ipa``, a second multirun into
``runs/robustness/ipa``), so the summary shows its rows in a table of their own beside the ports
on the same houses and keeps them out of every cell, mean, mCE, reference and verdict of the
main tables; `make robustness` says one line when the build is absent."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmark.commands import robustness as robustness_command
from benchmark.commands.robustness import render
from benchmark.reports import robustness as rb

ROOT = Path(__file__).resolve().parents[1]
MAIN = ("objects+graph_knn +post", "distance", "voronoi")
IPA = ("ipa_distance", "ipa_voronoi")
MAIN_HOUSES = tuple(f"h{i}" for i in range(1, 9))
IPA_HOUSES = MAIN_HOUSES[:3]
IPA_CONDITIONS = (("clean", 0), ("scan", 1), ("scan", 3), ("scan", 5), ("slam", 1), ("slam", 3), ("slam", 5))


def _score(method: str, corruption: str, severity: int, house: str) -> float:
    """A matched IoU with known means: each method its own level, falling with severity, houses
    spread around it (h1..h3 score higher than the rest, so a mean over the wrong houses shows)."""
    base = {"objects+graph_knn +post": 0.70, "distance": 0.60, "voronoi": 0.50,
            "ipa_distance": 0.40, "ipa_voronoi": 0.90}[method]
    k = int(house[1:])
    return base - 0.03 * severity * (1 + (corruption == "slam")) + (0.04 if k <= 3 else -0.02) + 0.005 * k


def _rows(ipa: bool = True, failed: tuple[str, str] | None = None) -> pd.DataFrame:
    rows = []
    main_conditions = [("clean", 0), *[(f, s) for f in ("scan", "slam") for s in range(1, 6)]]
    for m in MAIN:
        for c, s in main_conditions:
            for h in MAIN_HOUSES:
                rows.append({"dataset": "synthetic", "method": m, "corruption": c, "severity": s, "house_id": h,
                             "status": "ok", "matched_iou": _score(m, c, s, h)})
    if ipa:
        for m in IPA:
            for c, s in IPA_CONDITIONS:
                for h in IPA_HOUSES:
                    bad = failed == (m, h)
                    rows.append({"dataset": "synthetic", "method": m, "corruption": c, "severity": s, "house_id": h,
                                 "status": "error" if bad else "ok",
                                 "matched_iou": np.nan if bad else _score(m, c, s, h)})
    return pd.DataFrame(rows)


def _summary(rows: pd.DataFrame) -> dict:
    return rb.summarise(rows, ["matched_iou"], "auto", n_boot=200)[("synthetic", "matched_iou")]


def test_ipa_rows_stand_apart_beside_the_ports_on_their_own_houses():
    with_ipa, without = _summary(_rows()), _summary(_rows(ipa=False))
    # the main table, its mCE, reference, rankings and verdicts: as if the ipa rows were not there
    pd.testing.assert_frame_equal(with_ipa["table"], without["table"])
    assert with_ipa["notes"] == without["notes"] and with_ipa["houses"] == without["houses"] == len(MAIN_HOUSES)
    assert not any(m.startswith("ipa_") for m in with_ipa["table"].index)
    assert not any("ipa_" in n for n in with_ipa["notes"]) and with_ipa["reference"] == without["reference"]
    assert without["apart"] is None
    apart = with_ipa["apart"]
    t = apart["table"]
    assert apart["houses"] == list(IPA_HOUSES)
    assert apart["conditions"] == ["clean", "scan_1", "scan_3", "scan_5", "slam_1", "slam_3", "slam_5"]
    # the ipa rows beside the ports (not the view-based methods), sorted by the clean score
    assert list(t.index) == ["ipa_voronoi", "distance", "voronoi", "ipa_distance"]
    # every cell over the ipa houses only: the ports' mean is theirs on h1..h3, not on all eight
    for m in ("distance", "ipa_voronoi"):
        for c, s in IPA_CONDITIONS:
            want = 100 * np.mean([_score(m, c, s, h) for h in IPA_HOUSES])
            assert t.loc[m, rb.condition_name(c, s)] == pytest.approx(want)
    assert t.loc["distance", "clean"] != pytest.approx(100 * np.mean([_score("distance", "clean", 0, h)
                                                                       for h in MAIN_HOUSES]))
    assert {"clean lo", "clean hi", "slam_5 lo"} <= set(t.columns)
    # a ranking per condition over these houses, none of the family means (the severities differ)
    assert not ({"scan", "slam", "mCE"} & set(t.columns))
    assert any(n.startswith("Rankings over these 3 houses only") for n in apart["notes"])
    assert any(n.startswith("slam_5: {ipa_voronoi") for n in apart["notes"])


def test_a_failed_ipa_row_drops_its_house_from_the_ipa_table_only():
    s = _summary(_rows(failed=("ipa_distance", "h2")))
    assert s["houses"] == len(MAIN_HOUSES) and s["dropped"] == []  # the main table keeps h2
    assert s["apart"]["houses"] == ["h1", "h3"] and s["apart"]["dropped"] == ["h2"]
    want = 100 * np.mean([_score("voronoi", "scan", 3, h) for h in ("h1", "h3")])
    assert s["apart"]["table"].loc["voronoi", "scan_3"] == pytest.approx(want)


def test_one_ipa_house_gives_means_without_interval_or_ranking():
    rows = _rows()
    rows = rows[~(rows["method"].str.startswith("ipa_") & (rows["house_id"] != "h2"))]
    apart = _summary(rows)["apart"]
    assert apart["houses"] == ["h2"]
    assert apart["table"].loc["voronoi", "scan_5"] == pytest.approx(100 * _score("voronoi", "scan", 5, "h2"))
    assert np.isnan(apart["table"].loc["voronoi", "scan_5 lo"])
    assert any(n.startswith("one house: no interval and no ranking") for n in apart["notes"])
    assert not any(n.startswith("Rankings") for n in apart["notes"])


def test_an_ipa_condition_a_port_lacks_is_left_out_with_a_line():
    rows = _rows()
    extra = rows[(rows["method"].isin(IPA)) & (rows["corruption"] == "clean")].assign(corruption="explore",
                                                                                      severity=3)
    s = _summary(pd.concat([rows, extra], ignore_index=True))
    assert "explore_3" not in s["apart"]["conditions"]
    assert "explore_3 left out of this table: no rows for distance, voronoi" in s["apart"]["notes"]


def _job(folder: Path, rows: pd.DataFrame) -> None:
    folder.mkdir(parents=True)
    rows.drop(columns=["dataset"]).assign(dataset="synthetic").to_csv(folder / "metrics.csv", index=False)


def _sweep(folder: Path, jobs: list[str], started: str, finished: str) -> None:
    (folder / "last_sweep.json").write_text(json.dumps({"started_at": started, "finished_at": finished,
                                                        "command": [], "jobs": jobs}))


def _run_with_ipa(tmp_path: Path) -> Path:
    """A main sweep of the three ports and an ipa sweep of its own under it, one job folder a method."""
    rows = _rows()
    rows["pq"] = rows["matched_iou"] * 0.9  # the docs block reports PQ beside matched IoU
    run = tmp_path / "runs" / "robustness"
    main, ipa = rows[~rows["method"].str.startswith("ipa_")], rows[rows["method"].str.startswith("ipa_")]
    for m in MAIN:
        _job(run / m.replace(" ", "_").replace("+", "_"), main[main["method"] == m])
    for m in IPA:
        _job(run / "ipa" / m, ipa[ipa["method"] == m])
    return run


def test_the_summary_page_names_the_ipa_houses_and_leaves_an_earlier_runs_out(tmp_path, monkeypatch):
    # the severities' settings table (a config composed per conf/corruption file) is not what this
    # tests, and is most of the page's time
    monkeypatch.setattr(robustness_command, "severity_settings", lambda: {})
    run = _run_with_ipa(tmp_path)
    _sweep(run, [m.replace(" ", "_").replace("+", "_") for m in MAIN], "2026-01-02T10:00:00+00:00",
           "2026-01-02T11:00:00+00:00")
    _sweep(run / "ipa", list(IPA), "2026-01-02T11:00:01+00:00", "2026-01-02T11:05:00+00:00")
    md = render([run], None, ["matched_iou"], "auto", last_sweep=True)
    assert ("ipa_room_segmentation (matched IoU; the authors' C++, `make ipa-env`) beside the ports, on houses of "
            "its own: 3 house(s) (h1, h2, h3) under 7 condition(s) (clean, scan_1, scan_3, scan_5, slam_1, slam_3, "
            "slam_5)") in md
    assert "in no mean, mCE, reference, ranking or verdict above" in md
    assert "| ipa_voronoi |" in md and "8 houses per cell." in md
    # the ipa sweep of an earlier `make robustness` (finished before the main sweep started) is not read
    _sweep(run / "ipa", list(IPA), "2026-01-01T11:00:01+00:00", "2026-01-01T11:05:00+00:00")
    md = render([run], None, ["matched_iou"], "auto", last_sweep=True)
    assert "| ipa_voronoi |" not in md and "**Earlier run left out**" in md
    assert "No ipa_room_segmentation rows in these runs" in md


def _make_n(*args: str) -> str:
    r = subprocess.run(["make", "-n", "--no-print-directory", "robustness", *args], cwd=ROOT, capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    return r.stdout


def test_make_robustness_says_one_line_without_the_build_and_runs_the_ipa_sweep_with_it(tmp_path):
    out = _make_n("IPA_ENV=/nonexistent", "ROBUST_HOUSES=1")
    assert 'echo "no ipa_room_segmentation build in /nonexistent: no ipa rows (make ipa-env)"' in out
    assert "experiment=robustness_ipa" not in out and "benchmark.commands.robustness" in out
    build = tmp_path / "ipa"
    (build / "bin").mkdir(parents=True)
    (build / "bin" / "ipa_segment").write_text("")
    out = _make_n(f"IPA_ENV={build}", "ROBUST_HOUSES=7", "ROBUST_IPA_HOUSES=3")
    line = next(x for x in out.splitlines() if "experiment=robustness_ipa" in x)
    assert f"ROOMSEG_IPA_ENV={build}" in line and "run.limit=$(( 3 < 7 ? 3 : 7 ))" in line
    lines = out.splitlines()  # after the main sweep, before the tables
    assert lines.index(line) > next(i for i, x in enumerate(lines) if "experiment=robustness " in x)
    assert lines.index(line) < next(i for i, x in enumerate(lines) if "benchmark.commands.robustness" in x)
    out = _make_n(f"IPA_ENV={build}", "ROBUST_IPA=0")  # robustness-timing-publish's fresh-clone grid
    assert "experiment=robustness_ipa" not in out and 'echo "ROBUST_IPA=0: no ipa rows' in out


def test_the_timing_grid_is_the_fresh_clone_one():
    text = (ROOT / "Makefile").read_text()
    recipe = text[text.index("robustness-timing-publish: setup"):]
    recipe = recipe[:recipe.index("\n\n")]
    assert "no ipa rows" in recipe.splitlines()[0]  # its help line says so
    assert "$(MAKE) --no-print-directory robustness ROBUST_HOUSES=$(ROBUST_TIMING_HOUSES) ROBUST_IPA=0" in recipe


def test_the_html_report_and_the_docs_block_show_the_ipa_table(tmp_path):
    """Before: the ipa rows' table was only on the summary page (robustness.md); the HTML report's
    robustness section and docs/robustness.md's generated block showed the main tables alone.
    Known means over h1..h3: ipa_voronoi clean 0.90 + 0.04 + 0.005 * 2 = 95.0; the port distance
    there 65.0, and 62.5 over the eight houses of the main table."""
    import re

    from benchmark.reports.html_report import _robustness_section
    from benchmark.reports.readme_tables import _robustness_block
    from benchmark.reports.tables import load_rows

    run = _run_with_ipa(tmp_path)
    html = _robustness_section([run], [(None, None, load_rows([run]))])
    ipa_table = html.split('class="robust-table ipa-table"', 1)[1].split("</table>", 1)[0]
    cell = re.search(r"<tr><td>ipa_voronoi</td><td[^>]*>([0-9.]+)<", ipa_table)
    assert cell and cell.group(1) == "95.0"
    assert re.search(r"<tr><td>distance</td><td[^>]*>65\.0<", ipa_table)
    assert "on houses of its own: 3 house(s) (h1, h2, h3)" in html
    main_table = html.split('class="robust-table"', 1)[1].split("</table>", 1)[0]
    assert "ipa_voronoi" not in main_table and re.search(r"<tr><td>distance</td><td[^>]*>62\.5<", main_table)

    from benchmark.reports.readme_tables import PROVENANCE, PUBLISHED

    prov = tmp_path / PUBLISHED / "robustness" / PROVENANCE
    prov.parent.mkdir(parents=True)
    prov.write_text(json.dumps({"command": "make robustness", "date_utc": "2026-01-02", "commit": "abc1234"}))
    block = _robustness_block(tmp_path, [run], ["robustness"])
    assert "ipa_room_segmentation (matched IoU in percent, mean [95 % interval]; the authors' C++" in block
    ipa_lines = block.split("ipa_room_segmentation (", 1)[1]
    assert re.search(r"\| ipa_voronoi \| 95\.0", ipa_lines)
    assert "ipa_voronoi" not in block.split("ipa_room_segmentation (", 1)[0]  # in no main cell
