"""Sweep job folder names (issue 29): ordinary overrides keep Hydra's readable names byte for
byte; overrides holding paths (or quotes, braces, spaces) give one flat folder per job with a
readable part and a hash, never folders nested after the path."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from benchmark.config import MAX_JOB_DIRNAME, job_dirname

ROOT = Path(__file__).resolve().parents[1]


def test_ordinary_names_are_kept_and_others_shortened_with_a_hash():
    plain = "aggregator=graph_knn,classifier=objects,env=synthetic,postprocess=default"
    assert job_dirname(plain) == plain
    a = job_dirname("classifier.path=/data/robot/run1/labels/{house_id}.csv,viewpoints=file")
    b = job_dirname("classifier.path=/data/robot/run2/labels/{house_id}.csv,viewpoints=file")
    assert a.startswith("classifier.path=labels__house_id_.csv,viewpoints=file~") and a != b
    assert "/" not in a and "{" not in a and len(a) <= 80 + 11
    assert job_dirname("x" * (MAX_JOB_DIRNAME + 1)) != "x" * (MAX_JOB_DIRNAME + 1)
    assert "~" in job_dirname("run.label='my run'")


@pytest.mark.slow
def test_a_sweep_over_path_values_makes_flat_distinct_folders(tmp_path):
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "-m", "env=synthetic", "env.n_houses=1",
                        "env.resolution=0.1", "classifier=oracle", "run.label=runs/a/b,runs/c/d",
                        f"run.results_dir={tmp_path}", "run.progress=false"], cwd=ROOT,
                       env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    sweep = tmp_path / "runs" / "default"
    jobs = sorted(p.name for p in sweep.iterdir() if p.is_dir())
    assert len(jobs) == 2 and all("~" in j and j.startswith("classifier=oracle") for j in jobs), jobs
    assert all((sweep / j / "metrics.csv").is_file() for j in jobs)  # one level: no folder named after a path
