"""Unknown keys under ``run.`` (issue #24): ``run.limt=3`` was refused by Hydra with the
advice ``+run.limt=3``, which then ran every house with exit 0. Both, and ``++run.limt``,
are refused with one line listing the valid keys, exit 2, before anything is written; the
valid keys are the fields of ``RunSettings``, which are those of the ``run:`` node of
``conf/config.yaml`` (tests/test_run_settings.py)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from benchmark.config import compose
from benchmark.harness.checks import ConfigError, check_config

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def _valid_line() -> str:
    """The keys listed, from the composed default config (not from the code under test)."""
    return "valid keys under run: " + ", ".join(str(k) for k in compose("config").run.keys())


@pytest.mark.parametrize("args", [["+run.limt=1"], ["run.limt=1"], ["++run.limt=1"],
                                  ["-m", "+run.limt=1", "aggregator=graph_knn,vision_cone"]])
def test_bench_refuses_unknown_run_keys_in_one_line_before_any_work(tmp_path, args):
    res = tmp_path / "r"
    out = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", *args, "run.limit=1",
                          f"run.results_dir={res}", "run.progress=false"], cwd=ROOT, env=ENV, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 2, out.stderr[-2000:]
    assert out.stderr.strip().splitlines() == [
        f"roomseg-bench: error: run.limt: unknown key (with or without +); {_valid_line()}; did you mean 'run.limit'?"]
    assert not res.exists()  # no folder, no row, no cache entry


def test_the_valid_keys_are_the_run_node_of_the_default_config():
    from benchmark.harness.checks import run_keys

    keys = run_keys()
    assert {"name", "limit", "houses", "results_dir", "cache_dir", "allow_failures"} <= set(keys)
    assert list(keys) == [str(k) for k in compose("config").run.keys()]  # as composed, in order


def test_a_key_only_in_the_yaml_is_refused_until_run_settings_declares_it(tmp_path, monkeypatch):
    """The valid keys are RunSettings' fields, not the file's: a key added to the yaml alone is
    refused (and tests/test_run_settings.py fails until the dataclass has it too)."""
    import benchmark.paths
    from benchmark.harness.checks import check_run_overrides, run_keys

    conf = tmp_path / "conf"
    shutil.copytree(benchmark.paths.CONF_DIR, conf)
    text = (conf / "config.yaml").read_text()
    (conf / "config.yaml").write_text(text.replace("\nrun:\n", "\nrun:\n  shards: 1      # test\n", 1))
    monkeypatch.setattr(benchmark.paths, "CONF_DIR", str(conf))
    assert "shards" not in run_keys()
    with pytest.raises(ConfigError, match=r"^run.shards: unknown key \(with or without \+\); valid keys under run: name, "):
        check_run_overrides(["run.shards=4"])


def test_check_config_and_the_command_line_check_agree():
    from benchmark.harness.checks import check_run_overrides

    valid = [str(k) for k in compose("config").run.keys()]
    for bad in ({"run": {"limt": 3, "limit": 1}}, {"run": {"name": "x", "Limit": 2}}):
        with pytest.raises(ConfigError) as e:
            check_config(bad)
        assert str(e.value).startswith(f"run.{[k for k in bad['run'] if k not in valid][0]}: unknown key")
        assert _valid_line() in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(ConfigError, match="run.limt, run.foo: unknown keys"):
        check_run_overrides(["-m", "+run.limt=1", "~run.foo", "aggregator.k=3", "hydra.run.dir=x"])
    check_run_overrides(["run.limit=2", "+run.name=x", "~run.label", "hydra.run.dir=x", "env.run=3"])
    check_config({"run": {"limit": 2, "force": ["score"], "name": "x"}})
