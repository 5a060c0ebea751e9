"""``roomseg``: one tool with a subcommand per user command (benchmark/cli.py)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from benchmark import cli

ROOT = Path(__file__).resolve().parents[1]
MAINTAINER_TOOLS = ("docs", "gpu_check", "vlm_bench", "perf", "perf_metrics", "perf_postprocess", "scaling",
                    "readme_tables")


def test_help_lists_the_user_commands_and_no_maintainer_tool(capsys):
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in ("bench", "segment", "tables", "report", "figures", "robustness", "baselines", "data", "doctor"):
        assert f"\n  {name} " in out
    listed = {mod for mod, _ in cli.COMMANDS.values()}
    assert not listed & set(MAINTAINER_TOOLS)
    assert cli.main([]) == 2


@pytest.mark.parametrize("name", [n for n in cli.COMMANDS if n not in ("bench", "segment")])
def test_every_command_has_help_under_its_roomseg_name(name, capsys):
    assert cli.main([name, "--help"]) == 0
    out = capsys.readouterr().out
    if name == "score":  # a Hydra app: Hydra's own help
        assert "external" in out
        return
    assert f"roomseg {name}" in out.splitlines()[0]  # argparse's prog is the subcommand, not "tables.py"


def test_unknown_command_is_one_line_with_the_nearest(capsys):
    assert cli.main(["tabels"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["roomseg: error: unknown command 'tabels'; did you mean 'tables'? (roomseg --help lists them)"]


@pytest.mark.slow
def test_roomseg_bench_runs_the_hydra_app_and_passes_its_exit_status(tmp_path):
    exe = Path(sys.executable).with_name("roomseg")
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "benchmark.cli"]
    r = subprocess.run([*cmd, "bench", "run.limit=1", f"run.results_dir={tmp_path}", "run.progress=false"],
                       cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "runs" / "default" / "metrics.csv").exists()
    r = subprocess.run([*cmd, "bench", "aggregater=vision_cone"], cwd=ROOT, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 2 and "did you mean 'aggregator'" in r.stderr


def test_old_module_names_say_what_replaced_them_on_a_terminal(monkeypatch, capsys):
    import benchmark.commands as commands

    monkeypatch.setattr(sys, "orig_argv", ["python", "-m", "benchmark.commands.view_confusion", "x"])
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    commands._say_what_replaced()
    assert "is now `roomseg confusion`" in capsys.readouterr().err
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    commands._say_what_replaced()  # a script or a pipe: nothing new on stderr
    assert capsys.readouterr().err == ""


def test_segment_help_reads_without_markup(capsys):
    assert cli.main(["segment", "--help"]) == 0
    out = capsys.readouterr().out
    assert "roomseg-segment map=robot.yaml" in out and "``" not in out and ":mod:" not in out
