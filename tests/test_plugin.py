"""A plug-in from outside the repository: a user's own aggregator in their own package and
config folder, picked up with Hydra's search path, runs through ``roomseg-bench``
(docs/plugins.md; the page's own examples: tests/test_plugin_examples.py)."""

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]

PLUGIN = '''
"""A user's aggregator: every walkable cell gets the class of the first view."""
import numpy as np


class FirstView:
    def __init__(self, tag: str = "x"):
        self.tag = tag

    def __call__(self, grid, poses, proba):
        out = np.full(grid.shape, -1, np.int32)
        out[grid.walkable] = int(np.argmax(proba[0]))
        return out
'''


@pytest.mark.slow
@pytest.mark.parametrize("how", ["searchpath", "config-dir"])
def test_own_aggregator_from_outside_the_repo(tmp_path, how):
    pkg = tmp_path / "userpkg" / "my_stages"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "first_view.py").write_text(textwrap.dedent(PLUGIN))
    conf = tmp_path / "userconf"
    (conf / "aggregator").mkdir(parents=True)
    (conf / "aggregator" / "first_view.yaml").write_text("_target_: my_stages.first_view.FirstView\ntag: mine\n")
    results = tmp_path / "results"
    args = ["aggregator=first_view", "env.n_houses=1", "classifier=oracle", "postprocess=none",
            "env.resolution=0.1", f"run.results_dir={results}", "run.progress=false", "run.name=plug"]
    if how == "searchpath":
        args.append(f"hydra.searchpath=[file://{conf}]")
        cmd = [sys.executable, "-m", "benchmark.commands.bench", *args]
    else:  # a config folder of the user's own, added to the search path by --config-dir
        cmd = [sys.executable, "-m", "benchmark.commands.bench", "--config-dir", str(conf), *args]
    env = {"PYTHONPATH": str(tmp_path / "userpkg"), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    r = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]

    from benchmark.harness.cache import load_npz
    from benchmark.harness.store import find_jobs

    (job,) = find_jobs([results / "runs" / "plug"])
    df = pd.read_csv(job.metrics_path)
    assert df["aggregator"].tolist() == ["first_view"] and df["status"].tolist() == ["ok"]
    assert job.config().aggregator.tag == "mine"
    maps = load_npz(job.maps_path(df["house_id"][0]))
    labels = maps["raw"][maps["raw"] >= 0]
    assert len(labels) > 0 and len(np.unique(labels)) == 1  # one class everywhere: the plug-in ran
    assert labels[0] == int(np.argmax(maps["proba"][0]))
