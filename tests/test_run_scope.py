"""What a command's tables and report describe (issue 39, item 2): a sweep records the job
folders it ran (``last_sweep.json``); ``tables``, ``report`` and ``robustness`` with
``--last-sweep`` (what ``make bench`` and ``make robustness`` use) read that sweep alone, and
without it say, on stderr and under every table or at the top of the page, that they include
the job folders of earlier runs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from benchmark.commands.report import main as report
from benchmark.commands.tables import main as tables
from benchmark.harness.store import LAST_SWEEP, sweep_scope
from benchmark.harness.sweep import JOB_ERROR, SWEEP_ENV, read_error, record_error, write_summary

ROOT = Path(__file__).resolve().parents[1]


def _sweep(results: Path, limit: int, *extra: str) -> None:
    subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "-m", "env=synthetic", "env.resolution=0.1",
                    "classifier=oracle", "aggregator=graph_knn,vision_cone", "postprocess=default", f"run.limit={limit}",
                    "run.name=s", f"run.results_dir={results}", "run.workers=1", *extra],
                   check=True, capture_output=True, cwd=ROOT)


@pytest.mark.slow
def test_a_smaller_sweep_after_a_larger_one(tmp_path, capsys):
    """3 houses, then 2 houses into the same run folder (as make bench BENCH_HOUSES=5 after a
    20-house bench): the tables of the second say 2 houses per cell, its report lists its 2
    configurations; reading the whole folder says it holds earlier runs' jobs."""
    res = tmp_path / "R"
    run = res / "runs" / "s"
    _sweep(res, 3)
    first = json.loads((run / LAST_SWEEP).read_text())
    assert len(first["jobs"]) == 2 and "run.limit=3" in first["command"]
    _sweep(res, 2, "hydra.launcher.n_jobs=2")  # right after, its jobs side by side in forked workers
    doc = json.loads((run / LAST_SWEEP).read_text())
    assert len(doc["jobs"]) == 2 and all("~" in j for j in doc["jobs"])  # the siblings the larger run left free
    assert len(list(run.rglob("metrics.csv"))) == 4

    out = tmp_path / "t"
    assert tables([str(run), "--last-sweep", "--table", "table4", "--out", str(out)]) == 0
    md = (out / "table4.md").read_text()
    assert "2 houses per cell" in md and "Runs read: " in md and "left out 2 job folder(s) of earlier runs" in md
    assert "left out 2 job folder(s)" in capsys.readouterr().err
    assert tables([str(run), "--table", "table4", "--out", str(out)]) == 0  # the whole folder: said so
    md = (out / "table4.md").read_text()
    assert "3 houses per cell" in md and "includes 2 job folder(s) of earlier runs" in md and "--last-sweep" in md
    capsys.readouterr()

    page_path = tmp_path / "r.html"
    assert report([str(run), "--last-sweep", "--out", str(page_path)]) == 0
    page = page_path.read_text()
    configs = page[page.index('id="configs"'):]
    configs = configs[:configs.index("</table>")]
    assert configs.count("<tr>") == 1 + 2 and "2 configurations, 4 (house, configuration) rows" in page
    assert report([str(run), "--out", str(page_path)]) == 0
    page = page_path.read_text()
    assert "4 configurations, 10 (house, configuration) rows" in page
    assert 'id="scope"' in page and "includes 2 job folder(s) of earlier runs" in page

    from benchmark.commands.figures import main as figures

    assert figures(["from-run", str(run), "--last-sweep", "--out", str(tmp_path / "f"), "--jobs", "1"]) == 0
    drawn = sorted(p.name for p in (tmp_path / "f").rglob("*.png"))  # one figure per configuration of the sweep
    assert drawn == ["fig3_synthetic-s000000_synthetic_oracle0.8_graph_knn_default.png",
                     "fig3_synthetic-s000000_synthetic_oracle0.8_vision_cone_default.png",
                     "fig4_synthetic-s000000_synthetic_oracle0.8_default.png"]


def test_the_sweep_record_holds_its_own_jobs_however_recent_the_others(tmp_path):
    """A job an earlier multirun finished a moment ago (its summary.json as new as this
    multirun's start) is not this multirun's: the record and the job errors follow the token
    each job carries, not file times."""
    sweep = tmp_path / "s"
    for name, token in (("old", "a" * 32), ("new", "b" * 32), ("single", None)):
        job = sweep / name
        job.mkdir(parents=True)
        (job / "metrics.csv").write_text("house_id,status,iou\nh0,ok,0.5\n")
        (job / "resolved_config.yaml").write_text("run: {}\n")
        (job / "summary.json").write_text(json.dumps({"n_houses": 1, "n_ok": 1, "n_failed": 0, "sweep_id": token}))
    table = write_summary(sweep, sweep="b" * 32, started=0.0)
    assert list(table["job"]) == ["new"]
    assert json.loads((sweep / LAST_SWEEP).read_text())["jobs"] == ["new"]

    os.environ[SWEEP_ENV] = "c" * 32
    try:
        record_error("job 'x': run.limit=-1: expected a positive integer", sweep / "old")
    finally:
        del os.environ[SWEEP_ENV]
    assert read_error(sweep / "old" / JOB_ERROR) == ("job 'x': run.limit=-1: expected a positive integer", "c" * 32)
    record_error("no token", sweep / "new")  # outside a multirun
    assert read_error(sweep / "new" / JOB_ERROR) == ("no token", None)


def test_scope_of_folders_without_a_sweep_record(tmp_path, capsys):
    """A folder no multirun wrote (a single run, a copied table) is read whole and said nothing
    about; --last-sweep there is one line naming the folder, exit 2."""
    job = tmp_path / "runs" / "one"
    job.mkdir(parents=True)
    (job / "metrics.csv").write_text("house_id,status,iou,precision,recall\nh0,ok,0.5,0.5,0.5\n")
    scope = sweep_scope([tmp_path / "runs"])
    assert scope.files == [job / "metrics.csv"] and scope.note == ""
    assert tables([str(tmp_path / "runs"), "--last-sweep"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{tmp_path / 'runs'}: no {LAST_SWEEP}" in err
    (tmp_path / "runs" / LAST_SWEEP).write_text("{not json")
    assert tables([str(tmp_path / "runs")]) == 2
    assert "unreadable" in capsys.readouterr().err


def test_sweeps_below_the_folder_read_are_scoped_each(tmp_path):
    """``tables results/runs``: each run's sweep folder is scoped by its own record; a single
    run beside them is read as it is."""
    from benchmark.harness.store import Job, write_last_sweep

    def job(path: Path) -> Path:
        path.mkdir(parents=True)
        (path / "metrics.csv").write_text("house_id,status,iou,precision,recall\nh0,ok,0.5,0.5,0.5\n")
        return path / "metrics.csv"

    runs = tmp_path / "runs"
    new, old = job(runs / "a" / "j~new"), job(runs / "a" / "j")
    single = job(runs / "single")
    write_last_sweep(runs / "a", [Job(new.parent)], 0.0, ["-m"])
    scope = sweep_scope([runs])
    assert sorted(scope.files) == sorted([new, old, single]) and scope.n_other == 1
    assert f"{runs / 'a'}: includes 1 job folder(s) of earlier runs" in scope.note
    scope = sweep_scope([runs], last_only=True)
    assert sorted(scope.files) == sorted([new, single]) and "left out 1 job folder(s)" in scope.note
