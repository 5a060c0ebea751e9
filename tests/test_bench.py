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
    assert len(csvs) == 12  # 2 classifiers x 3 aggregators x 2 post-processing
    df = pd.concat(pd.read_csv(c) for c in csvs)
    assert len(df) == 24 and (df["status"] == "ok").all()
    out = tmp_path / "tables"
    t = subprocess.run([sys.executable, "-m", "benchmark.commands.tables", str(res / "runs" / "bench"), "--out", str(out),
                        "--table", "table3", "--table", "table4"], cwd=ROOT, env=env, capture_output=True, text=True)
    assert t.returncode == 0, t.stderr
    assert "Table IV" in t.stdout and (out / "table4.tex").exists()
    t4 = pd.read_csv(out / "table4.csv")
    assert len(t4) == 6 and (t4["n"] == 2).all()
    f = subprocess.run([sys.executable, "-m", "benchmark.commands.figures", "from-run", str(res / "runs" / "bench"),
                        "--out", str(tmp_path / "figs")], cwd=ROOT, env=env, capture_output=True, text=True,
                       timeout=300)
    assert f.returncode == 0, f.stderr[-2000:]
    assert len(list((tmp_path / "figs").glob("fig3_*.png"))) == 6
    assert len(list((tmp_path / "figs").glob("fig4_*.png"))) == 4
