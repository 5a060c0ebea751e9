"""Houses as Ray tasks (``run.executor=ray``) on a Ray instance that the test starts on
127.0.0.1 (``ray start --head``, as a cluster's head node is started): the same rows, byte
for byte, as one process. Skips with the reason where Ray is not installed or cannot start."""

from __future__ import annotations

import contextlib
import json
import os
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
