"""Results you can trust, from a fresh clone (issue 61, items 1, 3, 9): Ray on one machine runs
as the docs give it and leaves no Ray process behind; ``run.name`` is one folder name under
``run.results_dir``; two sweeps into one run folder at once each count their own jobs."""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from procs import NEEDS_PROC

from benchmark.harness.checks import ConfigError, check_config, check_run_overrides

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
FAST = ["env.resolution=0.1", "viewpoints.spacing=1.0"]
NAME_RULE = "expected one folder name (a string or a number; no / or \\, not starting with a dot, at most 120 characters)"


def _bench(*args: str, env: dict | None = None, timeout: int = 600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "benchmark.commands.bench", *args], cwd=ROOT, env=env or ENV,
                          capture_output=True, text=True, timeout=timeout)


# ---------------------------------------------------------------- item 1: Ray on one machine
#: a variable only the processes of one test's run carry (Ray's own processes inherit the
#: driver's environment), so that other Ray instances on the machine are not counted.
MARK = "ROOMSEG_TEST_RAY_RUN"


def _marked(token: str) -> dict[int, str]:
    """The living processes whose environment carries ``MARK=token``: pid -> command line."""
    want = f"{MARK}={token}".encode()
    out = {}
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            if want not in (d / "environ").read_bytes().split(b"\0"):
                continue
            if (d / "stat").read_text().rsplit(")", 1)[1].split()[0] in "ZXx":
                continue
            out[int(d.name)] = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")[:100]
        except OSError:  # gone meanwhile, or not ours to read
            continue
    return out


@pytest.mark.slow
@NEEDS_PROC
def test_ray_on_one_machine_runs_as_the_docs_give_it_and_leaves_no_ray_process(tmp_path):
    # before: exit status 1 after a few seconds, no line of ours, no rows, and ray::DashboardAgent /
    # ray::RuntimeEnvAgent left under PID 1 (ray.init ran in a thread that then ended)
    pytest.importorskip("ray")
    token = secrets.token_hex(8)
    env = {**ENV, MARK: token, "RAY_USAGE_STATS_ENABLED": "0"}
    args = ["env=synthetic", "classifier=oracle", "aggregator=vision_cone", "run.limit=2", *FAST, "run.progress=false"]
    out, err = tmp_path / "out.txt", tmp_path / "err.txt"
    seen: dict[int, str] = {}
    with open(out, "w") as o, open(err, "w") as e:  # the sweeps page's command, run.ray.address left null
        proc = subprocess.Popen([sys.executable, "-m", "benchmark.commands.bench", "run.executor=ray", *args,
                                 f"run.results_dir={tmp_path / 'ray'}"], cwd=ROOT, env=env, stdout=o, stderr=e)
        try:
            while proc.poll() is None:  # what of Ray ran, as seen by the check below
                seen.update(_marked(token))
                time.sleep(0.2)
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.wait()
    left = _marked(token)
    end = time.monotonic() + 30  # Ray's processes end as the driver stops them (a bounded wait, not a timing)
    while left and time.monotonic() < end:
        time.sleep(0.2)
        left = _marked(token)
    for pid in left:  # (what this test's run started, by pid)
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    assert proc.returncode == 0, err.read_text()[-3000:]
    assert any("raylet" in cmd or "ray::" in cmd for cmd in seen.values()), seen  # the check sees Ray's processes
    assert left == {}, f"Ray processes outlived the run: {left}"
    job = tmp_path / "ray" / "runs" / "default"
    summary = json.loads((job / "summary.json").read_text())
    assert summary["executor"] == "ray" and summary["n_ok"] == 2
    one = _bench("run.workers=1", *args, f"run.results_dir={tmp_path / 'one'}")
    assert one.returncode == 0, one.stderr[-2000:]
    assert (job / "metrics.csv").read_bytes() == (tmp_path / "one" / "runs" / "default" / "metrics.csv").read_bytes()


# ---------------------------------------------------------------- item 3: run.name stays under the results root
@pytest.mark.parametrize("name", ["default", "big", "2024", "my-run_1.2", "table5", "x~y", "a" * 120])
def test_plain_run_names_pass(name):
    check_run_overrides([f"run.name={name}"])
    check_config({"run": {"name": name}})


@pytest.mark.parametrize("name", ["../../../x", "..", ".", ".hidden", "a/b", "/tmp/x", "a\\b", "", "a" * 121, "a\tb"])
def test_a_run_name_that_is_not_one_folder_name_is_refused(name):
    with pytest.raises(ConfigError) as e:
        check_config({"run": {"name": name}})
    assert str(e.value) == f"run.name={name!r}: {NAME_RULE}"


@pytest.mark.slow
@pytest.mark.parametrize("args,shown", [(["run.name=../../../x"], "'../../../x'"),  # a job folder outside the results
                                        (["run.name=.."], "'..'"),  # the results root itself
                                        (["-m", "run.name=ok,../x", "aggregator=graph_knn"], "'../x'")])  # swept
def test_a_run_name_out_of_the_results_root_is_one_line_and_writes_nothing(tmp_path, args, shown):
    # before: run.name=../../../x wrote a whole job folder at <tmp>/a/x, run.name=.. one into <tmp>/a/b/R
    r = _bench(*args, "env=synthetic", "run.limit=1", *FAST, f"run.results_dir={tmp_path / 'a' / 'b' / 'R'}",
               "run.progress=false", timeout=300)
    assert r.returncode == 2
    assert r.stderr.strip() == f"roomseg-bench: error: run.name={shown}: {NAME_RULE}", r.stderr
    assert list(tmp_path.iterdir()) == []  # refused before Hydra made any folder


# ---------------------------------------------------------------- item 9: two sweeps into one run folder at once
@pytest.mark.slow
def test_two_sweeps_into_one_run_folder_at_once_each_count_their_own_jobs(tmp_path):
    """Sweep A (4 jobs) and sweep B (2 of the same configurations) into one run folder; B runs
    from start to end while A is between its second and third job (the test holds the cache
    lock of the third job's only house until B is done), so B rewrites the summary.json of two
    of A's job folders before A ends. Before: A summarised itself as "2 jobs, 2 rows" of its 4,
    exit status 0."""
    from benchmark.config import compose_job
    from benchmark.harness.cache import locked
    from benchmark.harness.runner import build_pipeline, select_houses

    results = tmp_path / "R"
    common = ["env=synthetic", "classifier=oracle", "run.limit=1", *FAST, "run.workers=1", "run.name=s",
              f"run.results_dir={results}", "run.progress=false", "hydra.launcher.n_jobs=1"]
    cfg, choices = compose_job([*common[:-1], "classifier.accuracy=0.8"])
    pipe = build_pipeline(cfg, choices)
    held = pipe.entry("score", select_houses(pipe.env.house_ids(), None, 1)[0])
    run = results / "runs" / "s"

    def done(accuracy: str) -> bool:
        return any((d / "summary.json").exists() for d in run.glob(f"*accuracy={accuracy}*"))

    with locked(held):  # A's job classifier.accuracy=0.8 waits for this entry
        a = subprocess.Popen([sys.executable, "-m", "benchmark.commands.bench", "-m",
                              "classifier.accuracy=0.6,0.7,0.8,0.9", *common], cwd=ROOT, env=ENV,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            end = time.monotonic() + 300
            while not (done("0.6") and done("0.7")) and a.poll() is None and time.monotonic() < end:
                time.sleep(0.2)
            assert a.poll() is None and done("0.6") and done("0.7"), "sweep A did not reach its third job"
            b = _bench("-m", "classifier.accuracy=0.6,0.7", *common)
            assert b.returncode == 0, b.stderr[-2000:]
            assert "2 jobs, 2 rows, 0 failed" in b.stdout, b.stdout[-1500:]
        except BaseException:
            a.kill()
            a.communicate()
            raise
    a_out, a_err = a.communicate(timeout=600)
    assert a.returncode == 0, a_err[-2000:]
    # the folders B rewrote last: their summary.json carries B's token, not A's
    tokens = {json.loads(p.read_text())["sweep_id"] for p in run.glob("*/summary.json")}
    assert len(tokens) == 2
    assert "4 jobs, 4 rows, 0 failed" in a_out, a_out[-1500:]
    table = pd.read_csv(run / "sweep_summary.csv")  # A ended last: the folder's summary is A's
    assert sorted(table["job"].str.extract(r"accuracy=([0-9.]+)")[0]) == ["0.6", "0.7", "0.8", "0.9"]
    assert len(json.loads((run / "last_sweep.json").read_text())["jobs"]) == 4
