"""Errors that say what to do, and Ctrl-C that is one line (issue 61 items 10 and 11, issue 62
item 9): every case is the real console command where the behaviour is the command's."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from procs import NEEDS_PROC, alive_in_group, default_sigint, gone_within, wait_for

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
BIN = Path(sys.executable).parent


def _bench(tmp_path: Path, *args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / "roomseg-bench"), *args, f"run.results_dir={tmp_path / 'R'}",
                           "run.progress=false"], cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=timeout)


def _lines(text: str) -> list[str]:
    return [ln for ln in text.strip().splitlines() if ln.strip()]


def _cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of process ``pid`` (0 when it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _pids_running(pgid: int) -> list[tuple[int, str]]:
    """(pid, command line) of the living processes of group ``pgid``."""
    out = []
    for pid in alive_in_group(pgid):
        try:
            out.append((pid, Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()))
        except OSError:
            pass
    return out


def _cmdlines(pgid: int) -> list[str]:
    return [c for _, c in _pids_running(pgid)]


# ---------------------------------------------------------------- Ctrl-C (issue 61 item 10)
@pytest.fixture(scope="module")
def big_example(tmp_path_factory) -> Path:
    """A map ``roomseg-segment`` takes seconds on (20 x 20 rooms, 6400 views)."""
    out = tmp_path_factory.mktemp("big")
    subprocess.run([sys.executable, "-m", "benchmark.commands.segment_example", str(out), "--rooms", "20x20",
                    "--no-gt"], cwd=ROOT, env=ENV, check=True, capture_output=True, timeout=300)
    # one whole run first: numba's cache then holds the kernels the command uses, so the Ctrl-C
    # below lands in the command's work rather than in its first compilation
    subprocess.run([str(BIN / "roomseg-segment"), f"map={out / 'map.yaml'}", f"poses={out / 'poses.csv'}", "frame=ros",
                    f"labels={out / 'labels.csv'}", f"out={tmp_path_factory.mktemp('warm') / 'seg'}"],
                   cwd=ROOT, env=ENV, check=True, capture_output=True, timeout=600)
    return out


_CALLBACK_CTRL_C = """
import atexit, ctypes, ctypes.util, os, signal, sys
from pathlib import Path
from benchmark.commands.cli import handle_interrupts
handle_interrupts()
atexit.register(lambda: Path(sys.argv[1]).write_text("cleaned"))
libc = ctypes.CDLL(ctypes.util.find_library("c"))
CMP = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_int))
def cmp(a, b):
    os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C lands while Python runs the callback
    return a[0] - b[0]
values = (ctypes.c_int * 4)(3, 1, 2, 0)
libc.qsort(values, 4, ctypes.sizeof(ctypes.c_int), CMP(cmp))
print("went on")
"""


def test_ctrl_c_inside_a_ctypes_callback_still_stops_the_command(tmp_path):
    """Before: a Ctrl-C that landed while numba's compiler was in llvmlite's object-cache
    callback was printed as "Exception ignored on calling ctypes callback function" and the
    command finished with exit 0 (CI of stop 65). The same with libc's qsort calling back into
    Python: one line, exit 130, the atexit cleanup ran, nothing after the call ran."""
    marker = tmp_path / "cleanup"
    r = subprocess.run([sys.executable, "-c", _CALLBACK_CTRL_C, str(marker)], cwd=ROOT, env=ENV,
                       capture_output=True, text=True, timeout=60, preexec_fn=default_sigint)
    assert r.returncode == 130, r.stderr[-2000:]
    assert len(_lines(r.stderr)) == 1 and _lines(r.stderr)[0].endswith(": interrupted"), r.stderr
    assert "went on" not in r.stdout and "Exception ignored" not in r.stderr
    assert marker.read_text() == "cleaned"


@NEEDS_PROC
@pytest.mark.slow
@pytest.mark.parametrize("command", [["roomseg-segment"], ["roomseg", "segment"]])
def test_ctrl_c_of_segment_is_one_line_exit_130_and_nothing_is_left(big_example, tmp_path, command):
    """Before: 35 lines of traceback. SIGINT to the command's process group once it is at work:
    one line on stderr, ``<command>: interrupted``, exit status 130, no process of it left, and
    neither the output folder nor its temporary sibling."""
    out = tmp_path / "seg"
    ex = big_example
    p = subprocess.Popen([str(BIN / command[0]), *command[1:], f"map={ex / 'map.yaml'}",
                          f"poses={ex / 'poses.csv'}", "frame=ros", f"labels={ex / 'labels.csv'}", f"out={out}"],
                         cwd=ROOT, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, preexec_fn=default_sigint)
    try:
        assert wait_for(lambda: p.poll() is not None or _cpu_seconds(p.pid) >= 1.5, timeout=120)
        assert p.poll() is None, f"ended before the Ctrl-C: {p.communicate()[1][-1500:]}"
        os.killpg(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    assert p.returncode == 130, err[-2000:]
    assert _lines(err) == [f"{' '.join(command)}: interrupted"], err[-2000:]
    assert gone_within(p.pid, 5.0) == []
    assert list(tmp_path.iterdir()) == []  # no out, no .seg.tmp-* left


@NEEDS_PROC
@pytest.mark.slow
def test_ctrl_c_of_make_bench_in_its_tables_step_stops_the_figures_job_too(tmp_path):
    """Before: 15 lines of KeyboardInterrupt from the tables step, and the background ``figures
    from-run`` job (which ignores SIGINT, as every background job of a non-interactive shell)
    went on writing figures after make had exited. Now the tables step says one line and no
    process of make's group is left to write."""
    p = subprocess.Popen(["make", "--no-print-directory", "bench", "BENCH_HOUSES=1", f"RESULTS={tmp_path / 'R'}",
                          f"BENCH_OUT={tmp_path / 'out'}", f"SHARED={tmp_path / 'no-shared-data'}"],
                         cwd=ROOT, env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, preexec_fn=default_sigint)
    try:
        def at_tables() -> bool:
            """The tables step at work (past Python's own start-up, which no handler of ours
            covers) beside the figures job."""
            running = _pids_running(p.pid)
            tables = [pid for pid, c in running if "benchmark.commands.tables" in c]
            return p.poll() is not None or (any("benchmark.commands.figures" in c for _, c in running)
                                            and any(_cpu_seconds(pid) >= 0.8 for pid in tables))

        assert wait_for(at_tables, timeout=900, step=0.05)
        assert p.poll() is None, f"make ended before its tables step: {p.communicate()[1][-1500:]}"
        os.killpg(p.pid, signal.SIGINT)
        _, err = p.communicate(timeout=120)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    assert p.returncode != 0
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err[-3000:]
    said = [ln for ln in _lines(err) if "interrupted" in ln]  # (the sweep's progress lines come before)
    assert said == ["python -m benchmark.commands.tables: interrupted"], err[-3000:]
    assert gone_within(p.pid, 5.0) == [], _cmdlines(p.pid)  # the figures job is gone: nothing writes on


def test_the_interrupt_hook_is_installed_once_and_leaves_other_errors_to_the_previous_hook(monkeypatch):
    from benchmark.commands import cli

    seen = []
    monkeypatch.setattr(sys, "excepthook", lambda *a: seen.append(a[0]))
    cli.handle_interrupts()
    hook = sys.excepthook
    cli.handle_interrupts()
    assert sys.excepthook is hook  # not wrapped twice
    hook(ValueError, ValueError("x"), None)
    assert seen == [ValueError]
    monkeypatch.setattr(cli, "interrupted", lambda *a, **k: seen.append("interrupted"))
    hook(KeyboardInterrupt, KeyboardInterrupt(), None)
    assert seen[-2:] == ["interrupted", KeyboardInterrupt]  # (the real one never returns)


# ---------------------------------------------------------------- group overrides (issue 61 item 11)
@pytest.mark.slow
@pytest.mark.parametrize("override,want", [
    ("pose_error=null", "pose_error=null: a config group takes one of its options, not null; pose_error is unset by "
                        "default, so leave the override out (pose_error's options: odometry, slam)"),
    ("segmenter=null", "segmenter=null: a config group takes one of its options, not null; segmenter is unset by "
                       "default, so leave the override out (segmenter's options: distance,"),
    ("env=5", "env=5: expected one of env's options: architecthor, maps, procthor, procthor_shared, synthetic"),
])
def test_a_group_override_that_is_not_an_option_is_named_with_its_options(tmp_path, override, want):
    """Before: each was answered with a line about ``corruption=``."""
    r = _bench(tmp_path, override, "run.limit=1")
    assert r.returncode == 2, r.stderr[-2000:]
    lines = _lines(r.stderr)
    assert len(lines) == 1 and lines[0].startswith(f"roomseg-bench: config error: {want}"), r.stderr[-2000:]
    assert "corruption" not in lines[0] and not (tmp_path / "R").exists()


# ---------------------------------------------------------------- uneven errors (issue 62 item 9)
def test_an_unknown_run_key_says_did_you_mean():
    from benchmark.harness.checks import ConfigError, check_run_overrides

    with pytest.raises(ConfigError) as e:
        check_run_overrides(["run.limt=3"])
    line = str(e.value)
    assert line.startswith("run.limt: unknown key (with or without +); valid keys under run: name,")
    assert line.endswith("; did you mean 'run.limit'?") and "\n" not in line
    with pytest.raises(ConfigError) as e:  # nothing near: the valid keys only
        check_run_overrides(["run.zzzzzz=3"])
    assert "did you mean" not in str(e.value)


@pytest.mark.slow
def test_an_unknown_option_is_one_line_with_the_options_not_hydras_search_path(tmp_path):
    r = _bench(tmp_path, "aggregator=vision_cones", "run.limit=1")
    assert r.returncode == 2, r.stderr[-2000:]
    assert _lines(r.stderr) == ["roomseg-bench: config error: aggregator=vision_cones: unknown option; expected one "
                                "of aggregator's options: euclidean_knn, graph_knn, vision_cone; did you mean "
                                "'vision_cone'?"], r.stderr[-2000:]


def test_a_target_not_on_the_path_is_named_with_what_to_do(tmp_path, monkeypatch):
    from benchmark.harness.checks import ConfigError
    from benchmark.harness.typed import check_targets, locate_problem

    with pytest.raises(ConfigError) as e:
        check_targets({"aggregator": {"_target_": "my_absent_plugin.Nearest", "k": 3}})
    assert str(e.value) == ("aggregator._target_='my_absent_plugin.Nearest': no module named 'my_absent_plugin' on "
                            "Python's path; expected an importable class or function (a plug-in: put the folder that "
                            "holds its package on PYTHONPATH, docs/plugins.md)")
    assert locate_problem("benchmark.aggregators.NoSuchAggregator") == "benchmark.aggregators has no 'NoSuchAggregator'"
    assert locate_problem("benchmark.aggregators.vision_cone.VisionCone") is None
    # a plug-in that is there but imports a library that is not: left to its build, which names the library
    (tmp_path / "needs_lib.py").write_text("import a_library_not_installed_xyz\n\nclass Agg:\n    pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert locate_problem("needs_lib.Agg") is None
    check_targets({"aggregator": {"_target_": "needs_lib.Agg"}})


@pytest.mark.slow
def test_a_run_refused_with_exit_2_leaves_no_hydra_folder_and_no_job_error(tmp_path):
    """Before: a plug-in target not on the path said only "Error locating target", and the run
    left ``.hydra/``, ``job.json``, ``resolved_config.yaml`` and ``job_error.txt``."""
    r = _bench(tmp_path, "aggregator._target_=my_absent_plugin.Nearest", "run.limit=1")
    assert r.returncode == 2, r.stderr[-2000:]
    lines = _lines(r.stderr)
    assert len(lines) == 1 and "no module named 'my_absent_plugin' on Python's path" in lines[0]
    assert "Error locating target" not in r.stderr
    runs = tmp_path / "R" / "runs"
    assert not runs.exists() or list(runs.iterdir()) == [], sorted(runs.rglob("*"))


@pytest.mark.slow
def test_a_missing_pose_file_is_named_on_the_last_line(tmp_path):
    """Before: ``failed (FileNotFoundError: 1)``; the path only in metrics.csv."""
    missing = tmp_path / "poses" / "absent.csv"
    r = _bench(tmp_path, "viewpoints=file", f"viewpoints.path={missing}", "run.limit=1")
    assert r.returncode == 1, r.stderr[-2000:]
    last = _lines(r.stderr)[-1]
    assert last.startswith("roomseg-bench: 1 house(s) failed in 1 job(s); first synthetic-s000000: "
                           "FileNotFoundError: ") and str(missing) in last, r.stderr[-2000:]
    log = (tmp_path / "R" / "runs" / "default" / "bench.log").read_text()
    finished = [ln for ln in _lines(log) if "1 failed (" in ln]  # the job's finished line
    assert len(finished) == 1 and str(missing) in finished[0] and "(FileNotFoundError: 1;" in finished[0], log


def test_a_smaller_runs_note_keeps_its_brackets_balanced(tmp_path):
    """Before: ``(differs in houses: 1 houses: synthetic-s000000 .. synthetic-s000000
    (3bd9fdf8dd -> 2 houses: ...``: the cut left a bracket open."""
    from benchmark.harness.cache import config_key
    from benchmark.harness.store import claim_job_dir

    def houses(ids):
        return {"houses": f"{len(ids)} houses: {ids[0]} .. {ids[-1]} ({config_key(ids)})", "run.limit": len(ids)}

    two, one = ["synthetic-s000000", "synthetic-s000001"], ["synthetic-s000000"]
    out = tmp_path / "runs" / "default"
    claim_job_dir(out, "a" * 16, houses(two))
    (out / "metrics.csv").write_text("house_id\n")
    moved, note = claim_job_dir(out, "b" * 16, houses(one))
    assert moved.name == "default~bbbbbbbb" and note
    depth = 0
    for ch in note:
        depth += {"(": 1, ")": -1}.get(ch, 0)
        assert depth >= 0, note
    assert depth == 0, note
    assert "2 houses: synthetic-s000000 .. synthetic-s000001" in note and "run.limit: 2 -> 1" in note


def test_a_finished_run_gives_its_mean_iou_in_percent():
    """Before: ``mean IoU 0.5898`` where every table prints 58.98."""
    from collections import Counter

    from benchmark.harness.runner import finished_line

    ok = {"n_houses": 1, "n_ok": 1, "mean_iou": 0.58984, "wall_time_s": 1.23}
    assert finished_line(ok, [], Counter()) == "1 house, 1 ok, 0 failed; mean IoU 58.98 %; 1.2 s"
    failed = [{"house_id": "h1", "error": "FileNotFoundError: pose file not found: /x/p.csv"}]
    none = {"n_houses": 2, "n_ok": 0, "wall_time_s": 0.5}
    assert finished_line(none, failed, Counter({"FileNotFoundError": 1})) == (
        "2 houses, 0 ok, 1 failed (FileNotFoundError: 1; first h1: FileNotFoundError: pose file not found: "
        "/x/p.csv); no mean IoU (no house succeeded); 0.5 s")


# ---------------------------------------------------------------- explore budgets (issue 61 item 11)
@pytest.fixture(scope="module")
def house_scene():
    from hydra.utils import instantiate

    from benchmark.config import compose

    env = instantiate(compose("config", ["env=synthetic"]).env)
    return env.scene(env.house_ids()[0])


def test_an_explore_budget_too_short_for_the_robots_map_says_the_smallest_that_works(house_scene):
    """Before: budgets of 2 m or less failed houses with "all views off the walkable map". Now
    the line says none of the views is on the map the robot built, and the smallest budget
    (in steps of scan_spacing) that puts one there for this house; that budget works and the
    step below it does not."""
    from benchmark.conditions.exploration import Frontier, no_view_on_own_map, views_on_own_map
    from benchmark.conditions.explored_map import ExploredMapping

    short = Frontier(budget=0.5)
    ex = short.explore(house_scene)
    assert not views_on_own_map(ex, house_scene.grid)
    best = short.smallest_budget(house_scene)
    assert best is not None and best > 0.5
    line = no_view_on_own_map(ex, house_scene)
    assert line.endswith(f"viewpoints.budget=0.5: expected at least {best:g} m for this house"), line
    assert f"none of the {len(ex.poses)} views lies on the map the exploring robot built" in line
    with pytest.raises(ValueError, match="expected at least"):
        ExploredMapping()(house_scene, ex.poses, exploration=ex)
    enough = Frontier(budget=best).explore(house_scene)
    assert views_on_own_map(enough, house_scene.grid) and no_view_on_own_map(enough, house_scene) is None
    free = ExploredMapping()(house_scene, enough.poses, exploration=enough)
    grid = house_scene.grid
    r, c = grid.world_to_cell(enough.poses[:, 0], enough.poses[:, 1])
    assert np.asarray(free)[r, c].any()  # a view the aggregators keep
    below = Frontier(budget=best - short.scan.spacing).explore(house_scene)
    assert not views_on_own_map(below, house_scene.grid)
