"""Trust in rows and cache entries (issue 61, items 4, 8 and part of 11): every reader of
``metrics.csv`` rows goes through one loader with the checks ``tables`` applies (a file holding
a house twice for one configuration is refused by ``report`` and ``figures`` too, not averaged);
a cache entry belongs to its full key (``make bench`` and ``make robustness`` into one results
folder never evict each other's score entries); a robustness summary whose sweep records are
gone does not average a family over the severities left as if they were all."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pandas as pd
import pytest

from benchmark.config import compose_job
from benchmark.harness.runner import run

ROOT = Path(__file__).resolve().parents[1]
FAST = ["env.resolution=0.1", "classifier=oracle", "run.limit=1", "viewpoints.spacing=1.0", "run.progress=false",
        "aggregator=graph_knn", "postprocess=default"]
ROW = ["house_id", "status", "iou", "precision", "recall", "accuracy", "matched_iou", "n_views"]


# ------------------------------------------------------------------ item 8: a cache entry belongs to its full key
def _score_entries(results: Path) -> dict[Path, int]:
    return {p: p.stat().st_mtime_ns for p in (results / "cache" / "scores").rglob("*.json")}


@pytest.mark.slow
def test_bench_and_robustness_settings_into_one_results_folder_keep_their_own_score_entries(tmp_path, caplog):
    """The issue's pair: ``make bench`` (env=synthetic, maps kept) and ``make robustness``
    (env=synthetic_robust: the same houses; run.save_maps=false; its clean condition has the
    bench's stages) into one results_dir, and a third with the bench's env but no maps; and the
    sanity segmenter both sweeps run. Each evicted the other's score entry ("env is 'synthetic',
    expected 'synthetic_robust'", "the entry has no maps file"); now each has its own, and a
    second round reads them all back with no warning, computing nothing."""
    results = tmp_path / "R"
    robust = ["env=synthetic_robust", "corruption=clean", "run.save_maps=false"]
    settings = {"bench": ["env=synthetic"], "robustness": robust, "no maps": ["env=synthetic", "run.save_maps=false"],
                "bench grid": ["env=synthetic", "segmenter=grid"], "robustness grid": [*robust, "segmenter=grid"]}
    first, keys = {}, {}
    with caplog.at_level(logging.WARNING, logger="roomseg-bench"):
        for name, over in settings.items():
            cfg, ch = compose_job([*FAST, f"run.results_dir={results}", *over])
            first[name] = run(cfg, tmp_path / name, ch)
            keys[name] = first[name]["score_key"].iloc[0]
        assert not [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
        entries = _score_entries(results)
        assert len(set(keys.values())) == 5 and len(entries) == 5  # one entry per full key
        for name, over in settings.items():  # the second round: everything from the cache
            cfg, ch = compose_job([*FAST, f"run.results_dir={results}", *over])
            again = run(cfg, tmp_path / name, ch)
            cols = [c for c in ROW if c in first[name]]
            pd.testing.assert_frame_equal(again[cols], first[name][cols])
            assert again["env"].iloc[0] == first[name]["env"].iloc[0] and again["score_key"].iloc[0] == keys[name]
    warned = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert warned == []  # no "bad cache entry" for a normal second run
    assert _score_entries(results) == entries  # none rewritten
    assert first["bench"]["env"].iloc[0] == "synthetic" and first["robustness"]["env"].iloc[0] == "synthetic_robust"
    # the maps the bench keeps are vouched for by its own entry; the others keep none
    maps = sorted((results / "cache" / "maps").rglob("*.npz"))
    assert sorted(p.parent.name for p in maps) == sorted([keys["bench"], keys["bench grid"]])


# ------------------------------------------------------------------ item 4: one loader for rows
def _duplicated_job(tmp_path: Path) -> tuple[Path, Path]:
    """A real 2-house job whose metrics.csv then holds house 0 twice (house 1's row replaced by a
    copy of house 0's, so that the row count still matches the summary's): (run folder, file)."""
    results = tmp_path / "R"
    cfg, ch = compose_job([*FAST, "run.limit=2", f"run.results_dir={results}", "run.name=dup"])
    df = run(cfg, results / "runs" / "dup", ch)
    assert len(df) == 2 and (df["status"] == "ok").all()
    f = Path(df.attrs["job_dir"]) / "metrics.csv"
    lines = f.read_text().splitlines(keepends=True)
    f.write_text("".join([lines[0], lines[1], lines[1]]))
    return results / "runs" / "dup", f


@pytest.mark.slow
def test_report_figures_and_tables_refuse_a_house_twice_in_one_file_alike(tmp_path, capsys):
    """Issue 61 item 4: ``report`` showed a mean over "2 / 2" houses of a file holding one house
    twice, which ``tables`` refuses; ``figures from-run`` drew from it. All three now read rows
    through one loader and refuse the file with the same line, exit 2."""
    from benchmark.commands.figures import main as figures
    from benchmark.commands.report import main as report
    from benchmark.commands.tables import main as tables

    run_dir, f = _duplicated_job(tmp_path)
    want = (f"error: {f}: house synthetic-s000000 is on lines 2 and 3 with the same configuration; "
            f"expected one row per house and configuration")
    for name, main, args in (
            ("tables", tables, [str(run_dir), "--table", "table4", "--out", str(tmp_path / "t")]),
            ("report", report, [str(run_dir), "--out", str(tmp_path / "r.html")]),
            ("figures", figures, ["from-run", str(run_dir), "--out", str(tmp_path / "f"), "--jobs", "1"])):
        assert main(args) == 2, name
        err = capsys.readouterr().err.strip().splitlines()
        assert err[-1] == want, (name, err)
    assert not (tmp_path / "r.html").exists() and not (tmp_path / "f").exists()


def test_every_reader_of_metrics_files_goes_through_the_one_loader():
    """No module but the loader (benchmark/reports/tables.py: read_rows, on the run store's
    read_metrics) reads a metrics.csv: the places that read rows call read_rows or load_rows."""
    import re

    readers = []
    for p in sorted((ROOT / "benchmark").rglob("*.py")):
        text = p.read_text(encoding="utf-8")
        rel = p.relative_to(ROOT).as_posix()
        if rel in ("benchmark/reports/tables.py", "benchmark/harness/store.py"):
            continue
        # a CSV read of a job's metrics file, or the store's reader called directly
        if re.search(r"read_csv\([^)]*metrics", text) or re.search(r"\bread_metrics\(", text):
            readers.append(rel)
    assert readers == []


# ------------------------------------------------------------------ item 11 (part): a summary whose sweep records are gone
METHODS = ("graph_knn", "vision_cone")


def _robustness_rows(folder: Path, scan: tuple[int, ...] = (1, 2, 3), houses: int = 3) -> Path:
    """A robustness run's rows without its sweep records (no multirun.yaml, no job folders: a
    copy of the rows): clean, scan at ``scan`` (the sweep's severities 4 and 5 gone) and pose
    1..5, two methods, each severity 5 points of matched IoU lower than the one before."""
    rows = []
    conditions = [("clean", 0), *(("scan", s) for s in scan), *(("pose", s) for s in range(1, 6))]
    for agg_i, agg in enumerate(METHODS):
        for corruption, sev in conditions:
            for h in range(houses):
                v = 0.8 - 0.05 * sev - 0.1 * agg_i + 0.01 * h
                rows.append({"house_id": f"h{h}", "dataset": "synthetic", "env": "synthetic", "classifier": "oracle",
                             "aggregator": agg, "postprocess": "default", "segmenter": "", "corruption": corruption,
                             "severity": sev, "status": "ok", "error": "", "iou": v, "precision": v, "recall": v,
                             "matched_iou": v, "pq": v})
    folder.mkdir(parents=True)
    pd.DataFrame(rows).to_csv(folder / "metrics.csv", index=False)
    return folder / "metrics.csv"


GONE_LINE = ("scan map left out of the summary: severity 4 has no rows for any method; severity 5 has no rows for "
             "any method (no sweep record (multirun.yaml) says which severities were run, so every one "
             "conf/corruption defines (1-5) is expected; a mean over the other severities would not compare)")


@pytest.mark.slow
def test_a_summary_whose_sweep_records_are_gone_leaves_out_a_family_missing_its_top_severities(tmp_path, capsys):
    """Issue 61 item 11 (part): with multirun.yaml gone, scan's severities 4 and 5 missing for
    every method were invisible, and 'scan' was the mean over 1..3 as if complete. The summary
    now expects every severity conf/corruption defines, says so in one line, and shows no scan
    mean; pose (all five there) is kept, and its mean is over 1..5."""
    from benchmark.commands.robustness import main as robustness

    run_dir = _robustness_rows(tmp_path / "run").parent
    out = tmp_path / "out"
    assert robustness([str(run_dir), "--metric", "matched_iou", "--out", str(out)]) == 0
    md = (out / "robustness.md").read_text()
    assert f"- {GONE_LINE}" in md and md.count("scan map left out") == 1
    t = pd.read_csv(out / "robustness_synthetic_matched_iou.csv", index_col="method")
    assert "scan" not in t.columns and "drop scan" not in t.columns
    for i, agg in enumerate(METHODS):
        m = f"oracle+{agg} +post"
        assert t.loc[m, "pose"] == pytest.approx(100 * (0.8 - 0.15 - 0.1 * i + 0.01))  # severities 1..5: mean 3
    capsys.readouterr()


@pytest.mark.slow
def test_the_report_and_the_published_blocks_expect_the_same_severities(tmp_path):
    """The report's robustness section and the README's block summarise with the same expected
    severities as the command: a sweep's record where there is one, else what conf/corruption
    defines."""
    from benchmark.reports import robustness as rb
    from benchmark.reports.html_report import _robustness_section
    from benchmark.reports.tables import load_rows

    f = _robustness_rows(tmp_path / "run")
    expected, unrecorded = rb.expected_severities([f])
    assert expected == rb.defined_severities() and unrecorded == sorted(expected)
    assert expected["scan"] == [1, 2, 3, 4, 5] and expected["explore"] == [0, 1, 2, 3, 4, 5]
    section = _robustness_section([f], [(None, None, load_rows([f]))])
    assert GONE_LINE.replace("(", "").replace(")", "") in section.replace("(", "").replace(")", "")
    assert ">scan map</th>" not in section and ">views-only pose noise, perfect map (ablation)</th>" in section
    # a sweep record that asked for scan 1..3 only: then 1..3 is the whole family
    (tmp_path / "run" / "multirun.yaml").write_text(json.dumps(
        {"hydra": {"overrides": {"task": []}, "sweeper": {"params": {
            "corruption": "clean,scan_1,scan_2,scan_3,pose_1,pose_2,pose_3,pose_4,pose_5",
            "aggregator": ",".join(METHODS)}}}}))
    expected, unrecorded = rb.expected_severities([tmp_path / "run"])
    assert expected["scan"] == [1, 2, 3] and expected["pose"] == [1, 2, 3, 4, 5]
    assert "scan" not in unrecorded and "slam" in unrecorded
    assert rb.expected_severities([f])[0]["scan"] == [1, 2, 3]  # found from a metrics file too
    section = _robustness_section([f], [(None, None, load_rows([f]))])
    assert "scan map left out" not in section and ">scan map</th>" in section
