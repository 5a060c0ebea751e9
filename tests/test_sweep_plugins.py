"""The Hydra sweeper and launcher of ``hydra_plugins/roomseg_sweep``: extra grids, validation
by cover, forked (and spawned) workers that give the same jobs as the launching process, and
a job whose config does not compose failing alone. A tiny Hydra app written by each test
records what every job saw."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from procs import default_sigint

from hydra_plugins.roomseg_sweep.roomseg_sweep import (
    GridsSweeper,
    LocalLauncher,
    auto_jobs,
    grouped,
    one_per_grid,
    units,
)

ROOT = Path(__file__).resolve().parents[1]

APP = '''
import json, os, sys, time
from pathlib import Path
import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import OmegaConf

@hydra.main(version_base="1.3", config_path="conf", config_name="config")
def app(cfg):
    hc = HydraConfig.get()
    time.sleep(float(os.environ.get("JOB_SLEEP", "0")))
    out = {"a": OmegaConf.to_container(cfg.a), "b": cfg.get("b"), "n": cfg.n, "pid": os.getpid(), "num": hc.job.num,
           "overrides": sorted(hc.overrides.task), "slot": os.environ.get("ROOMSEG_JOB_SLOT")}
    if "benchmark.config" in sys.modules:  # the project's app: its YAML parsed once per process
        from hydra._internal.core_plugins import file_config_source
        out["source_load"] = type(file_config_source.OmegaConf).__name__
        out["parsed"] = len(sys.modules["benchmark.config"]._PARSED_CONFIGS)
    (Path(hc.runtime.output_dir) / "job.json").write_text(json.dumps(out))
    return cfg.n

if __name__ == "__main__":
    if os.environ.get("APP_CONFIG"):
        sys.path.insert(0, os.environ["APP_CONFIG"])
        import benchmark.config
    app()
'''


def _app(tmp_path: Path, sweeper: str) -> Path:
    conf = tmp_path / "conf"
    (conf / "a").mkdir(parents=True)
    (conf / "a" / "x.yaml").write_text("v: 1\n")
    (conf / "a" / "y.yaml").write_text("v: 2\n")
    (conf / "a" / "broken.yaml").write_text("v: ${nope_unknown_resolver:1}\nw: [unclosed\n")
    head = textwrap.dedent(f"""\
        defaults:
          - a: x
          - _self_
          - override hydra/launcher: local
          - override hydra/sweeper: grids
        n: 0
        b: null
        hydra:
          searchpath: [file://{ROOT / 'conf'}]
          sweep:
            dir: {tmp_path / 'out'}
            subdir: ${{hydra.job.override_dirname}}
          sweeper:
        """)
    (conf / "config.yaml").write_text(head + textwrap.indent(sweeper, "    ") + "\n")
    (tmp_path / "app.py").write_text(APP)
    return tmp_path / "app.py"


def _run(app: Path, *args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(app), "-m", *args], capture_output=True, text=True,
                          cwd=app.parent, timeout=300, env=env)


def _jobs(tmp_path: Path) -> dict[str, dict]:
    return {p.parent.name: json.loads(p.read_text()) for p in (tmp_path / "out").glob("*/job.json")}


def test_one_job_per_grid():
    batch = [["a=x", "n=1"], ["a=x", "n=2"], ["a=y", "n=1"], ["b=u", "n=1"], ["b=v", "n=2"], ["n=3", "a=y"]]
    assert one_per_grid(batch) == [["a=x", "n=1"], ["b=u", "n=1"]]
    assert one_per_grid([]) == []


def test_auto_runs_jobs_side_by_side_only_with_enough_jobs():
    """n_jobs=auto: as many workers as cores from 2 jobs per core on; else one after another."""
    assert [auto_jobs(j, 2) for j in (1, 2, 3, 4, 30)] == [1, 1, 1, 2, 2]
    assert [auto_jobs(j, 64) for j in (30, 127, 128)] == [1, 1, 64]
    assert LocalLauncher(n_jobs="auto").n_jobs is None and LocalLauncher(n_jobs="3").n_jobs == 3
    for bad in (0, "many"):
        with pytest.raises(ValueError, match="n_jobs must be an integer >= 1 or auto"):
            LocalLauncher(n_jobs=bad)


def test_bad_validate_mode_is_refused():
    with pytest.raises(ValueError, match="hydra.sweeper.validate must be one of"):
        GridsSweeper(validate="some")


@pytest.mark.parametrize("launcher", ["hydra.launcher.n_jobs=2", "hydra.launcher.n_jobs=1",
                                      "hydra.launcher.start_method=spawn"])
def test_grids_union_and_workers(tmp_path, launcher):
    """params' grid then the extra grid, command-line sweeps applied to both, no job twice;
    every launcher mode runs the same jobs with the same configs."""
    app = _app(tmp_path, """\
params:
  a: x,y
  n: 1,2
grids:
  - b: u,v
    n: 1
  - a: x
    n: 1""")
    workers = [] if launcher.endswith("n_jobs=1") else ["hydra.launcher.n_jobs=2"]
    r = _run(app, "n=1,3", launcher, *workers)
    assert r.returncode == 0, r.stderr[-2000:]
    jobs = _jobs(tmp_path)
    # params x command line: a in {x,y}, n in {1,3}; grid 2: b in {u,v}, n in {1,3};
    # grid 3 (a=x, n in {1,3}) repeats two jobs of the first grid and adds none
    assert sorted(jobs) == sorted(["a=x,n=1", "a=x,n=3", "a=y,n=1", "a=y,n=3",
                                   "b=u,n=1", "b=u,n=3", "b=v,n=1", "b=v,n=3"])
    assert jobs["a=y,n=3"]["a"] == {"v": 2} and jobs["a=y,n=3"]["n"] == 3
    assert jobs["b=v,n=1"]["b"] == "v" and jobs["b=v,n=1"]["a"] == {"v": 1}
    assert sorted(j["num"] for j in jobs.values()) == list(range(8))
    pids = {j["pid"] for j in jobs.values()}
    slots = {(j["pid"], j["slot"]) for j in jobs.values()}
    if launcher.endswith("n_jobs=1"):
        assert len(pids) == 1 and {s for _, s in slots} == {None}
    else:
        assert 1 <= len(pids) <= 2 and "on 2" in r.stderr + r.stdout
        # each worker has its own place among the two (its jobs start on their own houses)
        assert len({s for _, s in slots}) == len(slots) == len(pids) and {s for _, s in slots} <= {"0/2", "1/2"}


def test_grouped_keeps_each_value_s_jobs_together_in_order():
    jobs = [["n=1", "a=x"], ["n=2", "a=x"], ["n=1", "a=y"], ["b=u"], ["n=2", "b=u"], ["+n=1", "b=v"], ["b=v"]]
    assert grouped(jobs, "n") == [["n=1", "a=x"], ["n=1", "a=y"], ["+n=1", "b=v"], ["n=2", "a=x"], ["n=2", "b=u"],
                                  ["b=u"], ["b=v"]]
    assert grouped(jobs, "zzz") == jobs and grouped([], "n") == []


def test_group_by_runs_every_grid_s_jobs_of_one_value_together(tmp_path):
    """hydra.sweeper.group_by: the jobs of both grids with the same n run one after the other
    (job numbers in that order), n in the order it first comes; without it each grid's jobs
    follow the grid before. The same jobs either way."""
    sweeper = "params:\n  a: x,y\n  n: 2,1\ngrids:\n  - b: u,v\n    n: 2,1"
    orders = {}
    for name, extra in (("plain", []), ("grouped", ["hydra.sweeper.group_by=n"])):
        app = _app(tmp_path / name, sweeper)
        r = _run(app, "hydra.launcher.n_jobs=1", *extra)
        assert r.returncode == 0, r.stderr[-2000:]
        jobs = _jobs(tmp_path / name)
        orders[name] = [k for k, _ in sorted(jobs.items(), key=lambda kv: kv[1]["num"])]
    assert orders["plain"] == ["a=x,n=2", "a=x,n=1", "a=y,n=2", "a=y,n=1", "b=u,n=2", "b=u,n=1", "b=v,n=2", "b=v,n=1"]
    assert orders["grouped"] == ["a=x,n=2", "a=y,n=2", "b=u,n=2", "b=v,n=2", "a=x,n=1", "a=y,n=1", "b=u,n=1", "b=v,n=1"]


def test_units_join_the_jobs_that_differ_only_in_the_keys():
    jobs = list(enumerate([["a=x", "n=1"], ["a=y", "n=1"], ["b=u"], ["a=x", "n=2"], ["+a=y", "n=2"], ["b=v"]]))
    assert units(jobs, ["a"]) == [[jobs[0], jobs[1]], [jobs[2]], [jobs[3], jobs[4]], [jobs[5]]]
    assert units(jobs, ["a", "n"]) == [[jobs[0], jobs[1], jobs[3], jobs[4]], [jobs[2]], [jobs[5]]]
    assert units(jobs, []) == [[j] for j in jobs] and units([], ["a"]) == []
    with pytest.raises(ValueError, match="same_worker must be a list of override keys"):
        GridsSweeper(same_worker="a")


def test_same_worker_runs_a_unit_s_jobs_one_after_another_on_one_worker(tmp_path):
    """hydra.sweeper.same_worker=[a]: on two workers, the jobs that differ only in ``a`` run in
    one process, in their order; the same jobs and configs as without it."""
    app = _app(tmp_path, "params:\n  n: 1,2,3,4\n  a: x,y")
    r = _run(app, "hydra.launcher.n_jobs=2", "hydra.sweeper.same_worker=[a]", env={**os.environ, "JOB_SLEEP": "0.2"})
    assert r.returncode == 0, r.stderr[-2000:]
    jobs = _jobs(tmp_path)
    assert len(jobs) == 8 and len({j["pid"] for j in jobs.values()}) == 2
    for n in "1234":
        x, y = jobs[f"a=x,n={n}"], jobs[f"a=y,n={n}"]
        assert x["pid"] == y["pid"] and y["num"] == x["num"] + 1 and x["a"] == {"v": 1} and y["a"] == {"v": 2}


@pytest.mark.parametrize("launcher", ["hydra.launcher.n_jobs=1", "hydra.launcher.n_jobs=2"])
def test_the_launcher_has_the_app_s_configs_parsed_once_with_the_same_jobs(tmp_path, launcher):
    """With the project's app loaded (benchmark.config), every job of a sweep, in the launching
    process or a forked worker, composes with Hydra's file configs parsed once per process
    (benchmark.config.parse_configs_once), and gets the configs it gets without: the same jobs
    and values as the same sweep of an app that does not load it; a config that does not parse
    fails its job with the same error."""
    import os

    sweeper = "params:\n  a: x,y,broken\n  n: 1,2\nvalidate: none"
    runs = {}
    for name, extra in (("plain", {}), ("app", {"APP_CONFIG": str(ROOT)})):
        where = tmp_path / name
        app = _app(where, sweeper)
        r = _run(app, launcher, env={**os.environ, **extra})
        assert r.returncode != 0  # the broken option's jobs fail
        runs[name] = (_jobs(where), r.stderr)
    plain, app_jobs = runs["plain"][0], runs["app"][0]
    assert sorted(plain) == sorted(app_jobs) == ["a=x,n=1", "a=x,n=2", "a=y,n=1", "a=y,n=2"]
    for k, job in app_jobs.items():
        assert {f: job[f] for f in ("a", "b", "n", "overrides")} == {f: plain[k][f] for f in ("a", "b", "n", "overrides")}
        assert job["source_load"] == "_ConfigsParsedOnce" and job["parsed"] >= 3
        assert "source_load" not in plain[k]
    # the broken config's error as Hydra words it (PyYAML's, naming the file), in both runs
    import re

    def errors(name):
        found = re.findall(r'ParserError: (while parsing a flow sequence)\s+in "([^"]+)", line (\d+), column (\d+)\s+'
                           r"(expected [^\n]+)", runs[name][1])
        return {(what, str(Path(f).relative_to(tmp_path / name)), line, col, exp) for what, f, line, col, exp in found}
    assert "<file>" not in runs["app"][1]  # (the once-parse's own error is not chained to it)
    assert errors("plain") == errors("app") == {("while parsing a flow sequence", "conf/a/broken.yaml", "2", "4",
                                                  "expected ',' or ']', but got '<stream end>'")}


def test_a_job_that_does_not_compose_fails_alone(tmp_path):
    """validate=none lets a broken option reach the workers: its job fails, the others run,
    and the sweep exits non-zero naming it."""
    app = _app(tmp_path, "validate: none")
    r = _run(app, "a=x,broken,y")
    assert r.returncode != 0
    assert "broken" in r.stderr
    assert sorted(_jobs(tmp_path)) == ["a=x", "a=y"]


@pytest.mark.parametrize("mode", ["quick", "all"])
def test_validation_stops_a_bad_option_before_any_job(tmp_path, mode):
    app = _app(tmp_path, f"validate: {mode}")
    r = _run(app, "a=x,y,nope", "n=1,2")
    assert r.returncode != 0 and "nope" in r.stderr
    if mode == "quick":  # one line naming the override and the options
        assert "'a=nope': 'nope' is not an option of config group 'a' (options: broken, x, y)" in r.stderr
    assert _jobs(tmp_path) == {}


def test_quick_validation_composes_the_first_job_of_each_grid(tmp_path):
    """An override that breaks composition (a key the config lacks, not a group option) is
    caught when it is in a grid's first job."""
    app = _app(tmp_path, "validate: quick")
    r = _run(app, "n=1,2", "no_such_key=3")
    assert r.returncode != 0 and "no_such_key" in r.stderr
    assert _jobs(tmp_path) == {}


NEEDS_PGREP = pytest.mark.skipif(shutil.which("pgrep") is None, reason="pgrep (procps) is not installed")


@NEEDS_PGREP
@pytest.mark.slow
def test_ctrl_c_stops_the_workers_at_once(tmp_path):
    """Ctrl-C (SIGINT to the process group) ends the sweep within a second or two: running
    jobs are stopped, waiting ones never start, no worker is left behind."""
    import os
    import signal
    import time

    app = _app(tmp_path, "validate: quick")
    env = dict(os.environ, JOB_SLEEP="20")
    p = subprocess.Popen([sys.executable, str(app), "-m", "n=1,2,3,4,5,6"], cwd=app.parent, env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True,
                         preexec_fn=default_sigint)  # (SIGINT may be ignored here: make test as a background job)
    time.sleep(3)  # the workers are in their first jobs
    workers = subprocess.run(["pgrep", "-g", str(p.pid)], capture_output=True, text=True).stdout.split()
    assert len(workers) == 3, workers  # the launching process and its two workers
    os.killpg(p.pid, signal.SIGINT)
    t = time.monotonic()
    _, err = p.communicate(timeout=15)
    assert time.monotonic() - t < 5 and p.returncode != 0, err[-1500:]
    assert _jobs(tmp_path) == {}
    assert subprocess.run(["pgrep", "-g", str(p.pid)], capture_output=True).returncode == 1  # none left


@NEEDS_PGREP
@pytest.mark.slow
def test_a_killed_worker_ends_the_sweep_naming_it(tmp_path):
    """kill -9 of a worker: the sweep stops with a line naming the sweep folder (not a hang),
    and the other worker is stopped too."""
    import os
    import signal
    import time

    app = _app(tmp_path, "validate: quick")
    env = dict(os.environ, JOB_SLEEP="20")
    p = subprocess.Popen([sys.executable, str(app), "-m", "n=1,2,3,4"], cwd=app.parent, env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    time.sleep(3)
    workers = subprocess.run(["pgrep", "-P", str(p.pid)], capture_output=True, text=True).stdout.split()
    assert len(workers) == 2, workers
    os.kill(int(workers[0]), signal.SIGKILL)
    _, err = p.communicate(timeout=15)
    assert p.returncode != 0 and f"a worker process of the sweep in {tmp_path / 'out'} died" in err
    assert subprocess.run(["pgrep", "-g", str(p.pid)], capture_output=True).returncode == 1


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads processes from /proc (Linux only)")
@pytest.mark.parametrize("start_method", ["fork", "spawn"])
def test_kill9_of_the_launching_process_leaves_no_worker(tmp_path, start_method):
    """kill -9 of the sweep's launching process while its workers run jobs: no worker is alive
    5 s later (they die with their parent instead of blocking on a pipe; issue #24)."""
    import os
    import signal

    from procs import children, gone_within, wait_for

    app = _app(tmp_path, "validate: quick")
    env = dict(os.environ, JOB_SLEEP="60")
    p = subprocess.Popen([sys.executable, str(app), "-m", "n=1,2,3,4", f"hydra.launcher.start_method={start_method}",
                          "hydra.launcher.n_jobs=2"], cwd=app.parent, env=env, stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    assert wait_for(lambda: len(children(p.pid)) >= 2, timeout=60), "the workers never appeared"
    os.kill(p.pid, signal.SIGKILL)
    p.wait(timeout=30)
    assert gone_within(p.pid, 5.0) == []


def test_a_worker_keeps_its_heap_apart_and_frees_what_died_since():
    """Before a sweep worker's 1st, 2nd, 4th, ... job its heap is collected and frozen (no full
    collection walks it again); what died since (a cycle let go of between freezes) is freed at
    the next one; a process that is not a sweep worker is left alone."""
    code = textwrap.dedent("""
        import gc, weakref
        from hydra_plugins.roomseg_sweep import roomseg_sweep as rs

        class Cycle:
            pass

        rs._keep_heap_apart()  # not a worker: nothing frozen
        assert gc.get_freeze_count() == 0, gc.get_freeze_count()
        rs._HEAP[:] = [0, True]  # as _init_worker leaves a worker
        kept = Cycle(); kept.me = kept
        rs._keep_heap_apart()  # job 1: frozen
        frozen = gc.get_freeze_count()
        assert frozen > 0
        gone = weakref.ref(kept)
        del kept  # a cycle kept through job 1, let go of before job 2: frozen, not collected
        gc.collect()
        assert gone() is not None
        rs._keep_heap_apart()  # job 2: unfrozen, collected, frozen again
        assert gone() is None
        assert gc.get_freeze_count() > 0
        made = Cycle(); made.me = made
        rs._keep_heap_apart()  # job 3: not a power of two, nothing done
        counts = gc.get_freeze_count()
        rs._keep_heap_apart()  # job 4
        assert gc.get_freeze_count() > counts
        print("ok")
    """)
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert p.returncode == 0 and p.stdout.strip() == "ok", p.stderr[-2000:]
