"""Houses as Ray tasks (``run.executor=ray``) on a Ray instance that the test starts on
127.0.0.1 (``ray start --head``, as a cluster's head node is started): the same rows, byte
for byte, as one process. Skips with the reason where Ray is not installed or cannot start."""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from procs import gone_within

ROOT = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _ray_env() -> dict[str, str]:
    """Ray on the loopback only (RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0: Ray then names this node
    127.0.0.1 instead of its network address), with its own token and no usage report."""
    return {**os.environ, "PYTHONPATH": str(ROOT), "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0",
            "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(16), "RAY_USAGE_STATS_ENABLED": "0"}


@pytest.fixture
def ray_head(tmp_path):
    """A Ray head node on 127.0.0.1 with 2 CPUs: (address, env for drivers); stopped after the test."""
    ray_bin = Path(sys.executable).with_name("ray")
    if not ray_bin.exists():
        pytest.skip("Ray is not installed (pip install -e '.[cluster]')")
    env = _ray_env()
    port = _free_port()
    log = tmp_path / "ray_head.log"
    cmd = [str(ray_bin), "start", "--head", "--node-ip-address=127.0.0.1", f"--port={port}", "--num-cpus=2",
           f"--dashboard-agent-listen-port={_free_port()}",
           "--include-dashboard=false", "--disable-usage-stats", "--block"]
    with open(log, "w") as out:
        head = subprocess.Popen(cmd, env=env, cwd=ROOT, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        end = time.monotonic() + 90
        while "Ray runtime started" not in log.read_text() and head.poll() is None and time.monotonic() < end:
            time.sleep(0.2)
        if "Ray runtime started" not in log.read_text():
            tail = " ".join(log.read_text().split()[-40:])
            pytest.skip(f"a Ray head node could not start on 127.0.0.1: {tail[-400:]}")
        yield f"127.0.0.1:{port}", env
    finally:
        with contextlib.suppress(ProcessLookupError):  # the head and every Ray process it started (one group)
            os.killpg(head.pid, signal.SIGKILL)
        head.wait(timeout=30)
        gone_within(head.pid, 10.0)


def _bench(tmp_path: Path, env: dict, houses: Path, name: str, *overrides: str) -> Path:
    res = tmp_path / name
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "env=procthor_shared", f"env.path={houses}",
                        "env.start=0", "env.resolution=0.1", "viewpoints.spacing=1.0", "classifier=oracle",
                        "aggregator=vision_cone", f"run.results_dir={res}", "run.progress=false", *overrides],
                       cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return res / "runs" / "default"


@pytest.mark.slow
def test_ray_runs_four_houses_like_one_process(tmp_path, procthor_file, ray_head):
    import gzip

    address, env = ray_head
    with gzip.open(procthor_file, "rt") as f:
        lines = [next(f).strip() for _ in range(4)]
    houses = tmp_path / "houses.jsonl"
    houses.write_text("\n".join(lines) + "\n")
    one = _bench(tmp_path, env, houses, "one", "run.workers=1")
    ray = _bench(tmp_path, env, houses, "ray", "run.executor=ray", f"run.ray.address={address}")
    assert (ray / "metrics.csv").read_bytes() == (one / "metrics.csv").read_bytes()
    summary = json.loads((ray / "summary.json").read_text())
    assert summary["executor"] == "ray" and summary["n_ok"] == 4 and summary["n_cached"] == 0
    timings = pd.read_csv(ray / "timings.csv")
    assert timings["house_id"].tolist() == pd.read_csv(one / "metrics.csv")["house_id"].tolist()
    assert not timings["cached"].any() and "t_render" in timings
    # the rows were computed in Ray's worker processes, into the same cache folder layout
    assert len(list((tmp_path / "ray" / "cache" / "scores").rglob("*.json"))) == 4


# ---------------------------------------------------------------- reaching a cluster (issue 38, item 3)
def _bench_fails(tmp_path: Path, *overrides: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "env=synthetic", "run.limit=1",
                           "run.executor=ray", f"run.results_dir={tmp_path / 'R'}", "run.progress=false", *overrides],
                          cwd=ROOT, env=env or {**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True, text=True,
                          timeout=120)


def _nothing_written(tmp_path: Path) -> None:
    job = tmp_path / "R" / "runs" / "default"
    assert not any((job / f).exists() for f in ("job.json", "metrics.csv", "summary.json", "resolved_config.yaml"))


@pytest.mark.slow
@pytest.mark.parametrize("address,why", [("127.0.0.1:1", "Connection refused"),
                                         ("nosuchhost.invalid:6379", "unknown host 'nosuchhost.invalid'")])
def test_an_unreachable_cluster_is_one_line_at_once(tmp_path, address, why):
    # before: 62 lines of Ray's retries over 823 s, then "cannot write (... cannot connect to Ray ...)"
    pytest.importorskip("ray")
    t = time.monotonic()
    r = _bench_fails(tmp_path, f"run.ray.address={address}")
    assert time.monotonic() - t < 60
    assert r.returncode == 2
    assert r.stderr.strip() == (f"roomseg-bench: error: run.ray.address={address}: cannot connect to Ray ({why}; "
                                f"run.ray.connect_timeout=30)"), r.stderr
    _nothing_written(tmp_path)


@pytest.mark.slow
def test_a_port_that_never_answers_waits_connect_timeout_seconds(tmp_path):
    # the port accepts connections but no Ray answers on it: Ray alone would retry for minutes
    pytest.importorskip("ray")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(16)
        address = f"127.0.0.1:{s.getsockname()[1]}"
        t = time.monotonic()
        r = _bench_fails(tmp_path, f"run.ray.address={address}", "run.ray.connect_timeout=3")
        took = time.monotonic() - t
    assert r.returncode == 2 and took < 40, (took, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert f"roomseg-bench: error: run.ray.address={address}: cannot connect to Ray (no answer from Ray within 3 s; " \
           f"run.ray.connect_timeout)" in lines, r.stderr
    _nothing_written(tmp_path)


@pytest.mark.slow
def test_ray_not_installed_is_one_line_naming_the_extra(tmp_path):
    # before: a 44-line traceback. A package named ray that cannot be imported stands for none.
    fake = tmp_path / "noray" / "ray"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("raise ImportError(\"No module named 'ray'\")\n")
    env = {**os.environ, "PYTHONPATH": f"{fake.parent}{os.pathsep}{ROOT}"}
    r = _bench_fails(tmp_path, "run.ray.address=127.0.0.1:1", env=env)
    assert r.returncode == 2
    assert r.stderr.strip() == ("roomseg-bench: error: run.executor=ray needs Ray, which is not installed: "
                                "pip install -e '.[cluster]' (or pip install ray)"), r.stderr
    _nothing_written(tmp_path)


def test_connect_timeout_is_checked_and_changes_no_job_identity():
    from benchmark.config import compose_job
    from benchmark.harness.checks import ConfigError, check_config
    from benchmark.harness.runner import job_identity

    for bad, shown in (("0", "0"), ("-1", "-1"), ("x", "'x'"), ("null", "None")):
        cfg, _ = compose_job([f"run.ray.connect_timeout={bad}"])
        with pytest.raises(ConfigError, match=re.escape(f"run.ray.connect_timeout={shown}: expected seconds > 0")):
            check_config(cfg)
    a, _ = compose_job([])
    b, _ = compose_job(["run.ray.connect_timeout=5"])
    assert job_identity(a, ["h"])[0] == job_identity(b, ["h"])[0]
