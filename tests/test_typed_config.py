"""Typed configuration (benchmark/harness/typed.py): a key no stage reads, a value of the wrong
type and a robot label out of range are one line naming the key, before any work, in every
command (roomseg-bench, roomseg-segment)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from benchmark.config import compose, compose_job
from benchmark.harness.checks import ConfigError
from benchmark.harness.typed import RobotLabel, check_targets, check_top_keys, check_typed, nearest

ROOT = Path(__file__).resolve().parents[1]


def _plain(overrides):
    cfg, _ = compose_job(overrides)
    return OmegaConf.to_container(cfg, resolve=True)


def test_the_default_config_and_a_robot_condition_are_typed():
    check_typed(_plain([]))
    check_typed(_plain(["corruption=realistic_5", "aggregator=vision_cone"]))


@pytest.mark.parametrize("overrides,match", [
    (["+aggregater=vision_cone"], r"aggregater: unknown key .*did you mean 'aggregator'\?"),
    (["+aggregator.kk=3"], r"aggregator.kk: unknown key, not a parameter of .*GraphKNN .*did you mean 'k'\?"),
    (["aggregator.k=x"], r"aggregator.k='x': expected an integer"),
    (["aggregator=vision_cone", "aggregator.window=true"], r"aggregator.window=True: expected an integer"),
    (["postprocess.min_area=[1]"], r"postprocess.min_area=\[1\]: expected"),
    (["robot.severity=6"], r"robot.severity=6: expected an integer 0..5"),
    (["robot.severity=1.5"], r"robot.severity=1.5: expected an integer 0..5"),
    (["robot.severity=x"], r"robot.severity='x': expected an integer 0..5"),
    (["robot.corruption=bogus"], r"robot.corruption='bogus': expected one of classifier, clean, explore"),
    (["corruption=pose_3", "robot.severity=0"], r"severity 0 exactly for clean"),
])
def test_bad_keys_and_values_are_one_line_naming_them(overrides, match):
    with pytest.raises(ConfigError, match=match):
        check_typed(_plain(overrides))


def test_a_users_own_stage_is_checked_by_its_signature():
    node = {"aggregator": {"_target_": "benchmark.aggregators.vision_cone.VisionCone", "fov": 90.0,
                           "max_range_m": 6.0, "windw": 5}}
    with pytest.raises(ConfigError, match=r"aggregator.windw: unknown key.*did you mean 'window'"):
        check_targets(node)
    # a target that takes **kwargs accepts any key; one whose module is not on the path is refused
    # naming it (issue 62.9; a module that fails to import a dependency is left to its build:
    # tests/test_trust_errors.py)
    check_targets({"x": {"_target_": "builtins.dict", "anything": 1}})
    with pytest.raises(ConfigError, match=r"x._target_='no.such.Module': no module named 'no' on Python's path"):
        check_targets({"x": {"_target_": "no.such.Module", "anything": 1}})


def test_the_robot_families_are_the_corruption_files():
    fams = RobotLabel.families()
    assert {"classifier", "clean", "explore", "pose", "realistic", "scan", "slam", "lost", "kidnap"} <= set(fams)
    assert list(fams) == sorted(fams)  # one per conf/corruption prefix, sorted
    assert RobotLabel.check({"corruption": "scan", "severity": 3}) == RobotLabel("scan", 3)
    assert nearest("aggregater", ["aggregator", "classes"]) == "; did you mean 'aggregator'?"
    with pytest.raises(ConfigError, match="on the command line"):
        check_top_keys(["postproces"], where=" on the command line")


def test_roomseg_segment_refuses_a_key_no_stage_reads():
    cfg = compose("segment", ["+agregator=vision_cone"])
    with pytest.raises(ConfigError, match="did you mean 'aggregator'"):
        check_typed(OmegaConf.to_container(cfg, resolve=True), "segment")
    from benchmark.commands.segment import main

    assert main(["map=m.yaml", "+agregator=vision_cone", "out=x"]) == 2


@pytest.mark.slow
@pytest.mark.parametrize("args,line", [
    (["aggregater=vision_cone"], "aggregater: unknown key on the command line (with or without +); no stage reads it; "
                                 "did you mean 'aggregator'?"),
    (["+aggregater=vision_cone"], "did you mean 'aggregator'?"),
    (["aggregator.kk=3"], "aggregator.kk: unknown key (with or without +); valid keys of aggregator: k, connectivity, "
                          "weighting; did you mean 'k'?"),
    (["robot.severity=6"], "robot.severity=6: expected an integer 0..5"),
])
def test_roomseg_bench_says_one_line_and_exits_2_without_running(tmp_path, args, line):
    """Hydra's own advice ("To append to your config use +aggregater=...") is never shown: with
    or without ``+`` the key is refused, naming the nearest known one, and nothing runs."""
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", *args, "run.limit=1",
                        f"run.results_dir={tmp_path}"], cwd=ROOT, capture_output=True, text=True, timeout=180)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and line in lines[0] and "To append" not in lines[0]
    assert not list(tmp_path.rglob("metrics.csv"))


@pytest.mark.slow
def test_a_failed_run_leaves_the_other_runs_folder_alone_and_nothing_of_its_own(tmp_path):
    """issue 39 item 1: a run whose folder name is taken by another run's results claims a
    ``~<key>`` sibling; when it then fails, nothing goes into the other run's folder. Issue 62.9:
    a run refused with exit status 2 leaves no folder of its own either (its ``~<key>`` claim,
    its ``job_error.txt``): the reason is its one line."""
    base = [sys.executable, "-m", "benchmark.commands.bench", "env=synthetic", "run.limit=1", "run.name=typo2",
            f"run.results_dir={tmp_path}", "run.progress=false"]
    assert subprocess.run(base, cwd=ROOT, capture_output=True, text=True, timeout=300).returncode == 0
    r = subprocess.run([*base, "classifier=oracle", "classifier.classes=[kitchen,bedroom]"], cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2, r.stderr
    runs = tmp_path / "runs"
    assert not (runs / "typo2" / "job_error.txt").exists() and (runs / "typo2" / "metrics.csv").exists()
    assert "classes" in r.stderr.strip().splitlines()[-1]
    assert [p.name for p in runs.iterdir()] == ["typo2"] and not list(runs.rglob("job_error.txt"))


@pytest.mark.slow
@pytest.mark.parametrize("args,line", [
    (["corruption=pose_3", "pose_error=null"], "config error: pose_error=null: a config group takes one of its options, not null"),
    (["-m", "experiment=robustness", "run.limit=0"], "run.limit=0: expected an integer >= 1, or null"),
])
def test_composition_errors_and_a_bad_run_value_in_a_sweep_are_one_line_before_anything(tmp_path, args, line):
    """issue 38 item 4: a group set to null that a corruption chooses was a 38-line Hydra
    traceback; ``run.limit=0`` in a sweep left 624 empty job folders and a summary."""
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", *args, f"run.results_dir={tmp_path / 'R'}"],
                       cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and line in lines[0], r.stderr[-2000:]
    assert not (tmp_path / "R").exists()


def test_the_known_top_keys_are_those_of_the_composed_default_configs():
    """known_top_keys reads the primary config's file instead of composing it: the same keys."""
    from pathlib import Path as P

    from benchmark.harness.typed import known_top_keys
    from benchmark.paths import CONF_DIR

    groups = {p.name for p in P(CONF_DIR).iterdir() if p.is_dir() and p.name != "hydra"}
    for name in ("config", "segment"):
        composed = {str(k) for k in compose(name).keys() if k != "hydra"}
        assert set(known_top_keys(name)) == composed | groups
