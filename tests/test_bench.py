"""`make bench` at a reduced size: the sweep, the tables and the figures from its caches."""

import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_bench_sweep_tables_and_figures(tmp_path):
    """Runs on generated houses only: no shared data needed."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    res = tmp_path / "results"
    run = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "experiment=bench", "run.limit=2",
                          f"run.results_dir={res}", "run.progress=false", "env.resolution=0.1"],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    csvs = sorted((res / "runs" / "bench").rglob("metrics.csv"))
    # 2 classifiers x 3 aggregators x 2 post-processing, then the sanity grid's 3 segmenters
    assert len(csvs) == 15
    assert sorted(c.parent.name.rsplit("segmenter=", 1)[1] for c in csvs if "segmenter=" in c.parent.name) == [
        "grid", "gt_geometry", "one_room"]
    df = pd.concat(pd.read_csv(c) for c in csvs)
    assert len(df) == 30 and (df["status"] == "ok").all()
    out = tmp_path / "tables"
    t = subprocess.run([sys.executable, "-m", "benchmark.commands.tables", str(res / "runs" / "bench"), "--out", str(out),
                        "--table", "table3", "--table", "table4"], cwd=ROOT, env=env, capture_output=True, text=True)
    assert t.returncode == 0, t.stderr
    assert "Table IV" in t.stdout and (out / "table4.tex").exists()
    t4 = pd.read_csv(out / "table4.csv")
    assert len(t4) == 9 and (t4["n"] == 2).all()  # 6 configurations and the 3 sanity rows
    drawn = {}
    for workers in ("1", "2"):  # in this process, and on two forked workers: the same files
        f = subprocess.run([sys.executable, "-m", "benchmark.commands.figures", "from-run", str(res / "runs" / "bench"),
                            "--out", str(tmp_path / f"figs{workers}"), "--jobs", workers], cwd=ROOT, env=env,
                           capture_output=True, text=True, timeout=300)
        assert f.returncode == 0, f.stderr[-2000:]
        assert len(list((tmp_path / f"figs{workers}").glob("fig3_*.png"))) == 6
        assert len(list((tmp_path / f"figs{workers}").glob("fig4_*.png"))) == 4
        drawn[workers] = {p.name: p.read_bytes() for p in (tmp_path / f"figs{workers}").glob("*.png")}
        assert f.stdout.split() == sorted(f.stdout.split(), key=f.stdout.split().index)  # printed in order
    assert drawn["1"] == drawn["2"]
