"""Input files that are no regular files (issue 61, item 5): a house file or any file a stage's
config names is checked with ``stat`` before anything opens it. ``env.path=/dev/zero`` hung the
run in the cache key's fingerprint (reading /dev/zero without end); a FIFO blocked it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from benchmark.harness.cache import file_fingerprint, leaf_inputs
from envs.datasets.house_files import iter_house_records
from envs.files import regular_file

ROOT = Path(__file__).resolve().parents[1]


def test_a_house_file_that_is_a_fifo_or_a_device_is_one_line(tmp_path):
    fifo = tmp_path / "houses.jsonl"
    os.mkfifo(fifo)  # opening it would block: the check only stats it
    with pytest.raises(ValueError, match=r"house file=.*houses\.jsonl is a FIFO \(named pipe\); expected a regular file"):
        next(iter_house_records(fifo))
    with pytest.raises(ValueError, match="house file=/dev/zero is a character device"):
        next(iter_house_records("/dev/zero"))
    link = tmp_path / "zero.jsonl.gz"
    link.symlink_to("/dev/zero")
    with pytest.raises(ValueError, match=r"a symbolic link to /dev/zero\) is a character device"):
        next(iter_house_records(link))


def test_a_fingerprinted_input_that_is_no_file_names_its_config_key(tmp_path):
    fifo = tmp_path / "weights.pt"
    os.mkfifo(fifo)
    with pytest.raises(ValueError, match="FIFO"):
        file_fingerprint(fifo)
    with pytest.raises(ValueError, match=r"^classifier\.weights: input file .* is a FIFO .*expected a regular file or a folder"):
        leaf_inputs((("classifier.weights", str(fifo)),))
    # a regular file and a folder are fingerprinted as before
    (tmp_path / "w.pt").write_bytes(b"abc")
    assert file_fingerprint(tmp_path / "w.pt").startswith("sha1:")
    assert file_fingerprint(tmp_path).startswith("dir:")
    assert regular_file(tmp_path / "w.pt", "x") == tmp_path / "w.pt"


@pytest.mark.slow
@pytest.mark.parametrize("what", ["dev_zero", "fifo"])
def test_env_path_that_is_no_file_is_one_line_not_a_hang(tmp_path, what):
    path = "/dev/zero" if what == "dev_zero" else str(tmp_path / "houses.jsonl")
    if what == "fifo":
        os.mkfifo(path)
    cmd = [sys.executable, "-m", "benchmark.commands.bench", "env=procthor", f"env.path={path}", "run.limit=1",
           f"run.results_dir={tmp_path / 'results'}", "classifier=oracle", "aggregator=graph_knn"]
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, p.stderr[-2000:]
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, lines
    assert "env.path" in lines[0] and "expected a regular file" in lines[0], lines[0]
