"""Compiling the numba kernels ahead of a run (``make setup``): the warm-up reaches every
kernel, and a run after it (clean and every robot condition's stages)
finds all the machine code it needs in the cache: it writes no cache entry of its own."""

from __future__ import annotations

import inspect
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from benchmark.commands.compile_kernels import kernels

ROOT = Path(__file__).resolve().parents[1]


def _cache_files(d: Path) -> dict[str, int]:
    return {str(p.relative_to(d)): p.stat().st_mtime_ns for p in d.rglob("*") if p.is_file()}


def test_kernels_lists_every_njit_function_of_the_algorithm_modules():
    """The list the warm-up is checked against holds the kernels known to exist (one per
    stage that has one) and only numba dispatchers."""
    ks = kernels()
    for name in ("benchmark.aggregators.vision_cone._cone_votes", "benchmark.aggregators.graph_knn._knn_bfs",
                 "benchmark.aggregators.euclidean_knn._k_nearest", "benchmark.postprocess._fill_fronts",
                 "envs.render.floorplan._render_views", "envs.maps.scan._scan_kernel", "envs.maps.trajectory._dijkstra",
                 "envs.maps.slam_map._estimate_kernel"):
        assert name in ks
    assert all(hasattr(d, "py_func") and hasattr(d, "signatures") for d in ks.values())


@pytest.mark.slow
def test_warm_up_compiles_every_kernel_and_a_run_after_it_compiles_nothing(tmp_path):
    cache = tmp_path / "numba-cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), ROOMSEG_SHARED_DATA=str(ROOT.parent / "shared" / "data"))
    p = subprocess.run([sys.executable, "-m", "benchmark.commands.compile_kernels", "--child"], env=env, cwd=ROOT,
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    sigs = json.loads(p.stdout.strip().splitlines()[-1])["signatures"]
    assert set(sigs) == set(kernels())
    ks = kernels()
    # a kernel with no signature of its own is compiled inside one that calls it, directly or
    # through inline helpers that are themselves reached that way
    reached = {k for k, n in sigs.items() if n >= 1}
    while True:
        src = "\n".join(inspect.getsource(ks[k].py_func) for k in reached)
        more = {k for k in sigs if k not in reached and f"{k.rsplit('.', 1)[1]}(" in src}
        if not more:
            break
        reached |= more
    for k in sigs:
        assert k in reached, f"{k} is never compiled by the warm-up"
    before = _cache_files(cache)
    assert before, "the warm-up wrote nothing to numba's cache"
    # a robustness run of one house: clean and realistic_3 (scan map, frontier exploration,
    # pose error, label noise), every view-based method and geometric segmenter
    run = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "experiment=robustness", "env=synthetic",
                          "run.limit=1", f"run.results_dir={tmp_path / 'results'}", "corruption=clean,realistic_3"],
                         env=env, cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]
    assert _cache_files(cache) == before  # every kernel a run calls was loaded, none compiled
    # the vision cone's whole votes in uint16: 256 views or more within a cone's reach of a cell,
    # as a ProcTHOR house's views often are (a synthetic house's never)
    many = ("import numpy as np\n"
            "from benchmark.aggregators import vision_cone as V\n"
            "from benchmark.commands.compile_kernels import _scene\n"
            "from benchmark.viewpoints import Autotrace\n"
            "_, scene = _scene()\n"
            "poses = np.repeat(np.asarray(Autotrace().generate(scene)), 40, axis=0)\n"
            "proba = np.eye(len(scene.classes))[np.arange(len(poses)) % len(scene.classes)]\n"
            "assert V.VisionCone().votes(scene.grid, poses, proba).dtype == np.uint16\n")
    big = subprocess.run([sys.executable, "-c", many], env=env, cwd=ROOT, capture_output=True, text=True)
    assert big.returncode == 0, big.stderr[-2000:]
    assert _cache_files(cache) == before


def _record(stages: dict[str, float], process: float, sigs: dict[str, int]) -> dict:
    return {"import numba": 0.1, "stages": stages, "process": process, "signatures": sigs}


COLD = _record({"setup (house, autotrace)": 0.5, "graph_knn": 1.25, "postprocess": 2.0}, 4.5,
               {"m.a": 1, "m.b": 2, "m.c": 0})
WARM = _record({"setup (house, autotrace)": 0.25, "graph_knn": 0.01, "postprocess": 0.02}, 1.0, {})


def test_the_measure_table_of_two_known_warm_ups():
    from benchmark.commands.compile_kernels import measure_table

    lines = measure_table(COLD, WARM).splitlines()
    assert lines[2:6] == ["| setup (house, autotrace) | 0.50 | 0.25 |", "| graph_knn | 1.25 | 0.01 |",
                          "| postprocess | 2.00 | 0.02 |", "| **all stages** | **3.75** | **0.28** |"]
    assert lines[6] == "| whole process (python start, imports, stages) | 4.50 | 1.00 |"
    assert lines[8] == ("3 kernels, compiled for 3 argument-type signatures (more than one: m.b x2; a call inside "
                        "another kernel counts too); inlined only into the kernels that call them: m.c.")


def test_measure_out_writes_the_table_under_a_measured_line(tmp_path, monkeypatch, capsys):
    from benchmark.commands import compile_kernels as ck

    records = iter([COLD, WARM])
    monkeypatch.setattr(ck, "_measure_once", lambda cache_dir: next(records))
    commands = iter([9.0, 1.5])
    monkeypatch.setattr(ck, "_command_seconds", lambda cache_dir, processes: next(commands))
    out = tmp_path / "pub" / "compile.md"
    assert ck.main(["--measure", "--processes", "3", "--out", str(out)]) == 0
    text = out.read_text()
    head, rest = text.split("\n\n", 1)
    assert head.startswith("Measured on ") and head.endswith(
        f"by `python -m benchmark.commands.compile_kernels --measure --processes 3 --out {out}`.")
    assert rest == ck.measure_table(COLD, WARM, {"processes": 3, "cold": 9.0, "warm": 1.5}) + "\n"
    assert "| the command as `make setup` runs it (stages shared among 3 processes) | 9.00 | 1.50 |" in rest
    with pytest.raises(SystemExit) as e:
        ck.main(["--out", str(out)])
    assert e.value.code == 2
    assert f"--out {out}: only with --measure" in capsys.readouterr().err


@pytest.mark.slow
def test_the_warm_up_shared_among_processes_fills_the_cache_one_process_would(tmp_path):
    """``make setup``'s warm-up, its stages shared among 2 processes, leaves nothing for the
    whole warm-up in one process to compile: every stage was run by one of them."""
    cache = tmp_path / "numba-cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    p = subprocess.run([sys.executable, "-m", "benchmark.commands.compile_kernels", "--processes", "2"], env=env,
                       cwd=ROOT, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    assert " on 2 processes (" in p.stdout
    from benchmark.commands.compile_kernels import stages

    every = [name for name, _ in stages()]
    # the two processes' stages (the command's line names their counts): together every stage, once
    counts = p.stdout.split(" on 2 processes (", 1)[1].split(" stages;", 1)[0].split(" + ")
    assert sum(int(c) for c in counts) == len(every) and len(counts) == 2
    before = _cache_files(cache)
    assert before
    one = subprocess.run([sys.executable, "-m", "benchmark.commands.compile_kernels", "--child"], env=env, cwd=ROOT,
                         capture_output=True, text=True)
    assert one.returncode == 0, one.stderr
    assert _cache_files(cache) == before


def test_processes_sharing_a_warm_up_run_every_stage_once(tmp_path, monkeypatch):
    from benchmark.commands import compile_kernels as ck

    ran: list[tuple[int, str]] = []
    names = [f"stage {i}" for i in range(7)]
    who = [0]

    def stage(n):
        ran.append((who[0], n))
        if n == "stage 0":  # while the first process compiles this, the second takes the next ones
            who[0] = 1
            assert [n for _, n in ran] == ["stage 0"]
            took.append(ck.warm(tmp_path))
            who[0] = 0

    monkeypatch.setattr(ck, "stages", lambda: [(n, lambda n=n: stage(n)) for n in names])
    took: list[dict] = []
    took.append(ck.warm(tmp_path))
    assert sorted(n for _, n in ran) == names  # each stage once, by the process that claimed it
    assert ran == [(0, "stage 0"), *((1, n) for n in names[1:])]
    assert set(took[0]) == {"setup (house, autotrace)", *names[1:]} and set(took[1]) == {"setup (house, autotrace)", "stage 0"}
    ran.clear()
    ck.warm()  # without claims: every stage, here
    assert [n for _, n in ran] == names


def test_a_failed_process_fails_the_shared_warm_up_and_an_interrupt_stops_the_others(monkeypatch):
    import time as _time

    from benchmark.commands import compile_kernels as ck

    real_popen = subprocess.Popen
    started: list[subprocess.Popen] = []

    def popen(script):
        def start(cmd, **kw):
            started.append(real_popen([sys.executable, "-c", script], **kw))
            return started[-1]
        return start

    monkeypatch.setattr(ck, "warm", lambda claims=None: {"setup (house, autotrace)": 0.1})
    monkeypatch.setattr(ck.subprocess, "Popen", popen("import sys; sys.stderr.write('stage boom'); sys.exit(3)"))
    with pytest.raises(RuntimeError, match=r"process 2 of 2 exited 3: stage boom"):
        ck.warm_shared(2)
    assert ck.main(["--processes", "2"]) == 1  # the command says so and fails
    assert ck.warm_shared(1) == [[]] and len(started) == 2  # one process: no other started
    monkeypatch.setattr(ck.subprocess, "Popen", popen("print('compiling'); print('[' + chr(34) + 'scan map' + chr(34) + ']')"))
    assert ck.warm_shared(2) == [[], ["scan map"]]  # each process's stages, this one's first

    def interrupted(claims=None):
        raise KeyboardInterrupt

    started.clear()
    monkeypatch.setattr(ck, "warm", interrupted)
    monkeypatch.setattr(ck.subprocess, "Popen", popen("import time; time.sleep(60)"))
    t = _time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        ck.warm_shared(3)
    assert len(started) == 2 and all(p.returncode is not None for p in started)  # stopped, not left running
    assert _time.monotonic() - t < 30


def test_a_sharing_process_whose_launcher_is_gone_stops_at_once(tmp_path):
    """A process of the shared warm-up dies with the process that started it: started for a
    parent that is not its own (already gone), it exits before claiming any stage."""
    p = subprocess.run([sys.executable, "-m", "benchmark.commands.compile_kernels", "--claims", str(tmp_path),
                        "--parent", "1"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 1 and p.stdout == ""
    assert list(tmp_path.iterdir()) == []


def _sharing_processes(parent: int) -> list[int]:
    """Pids of the shared warm-up's other processes started by ``parent`` (from /proc)."""
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                args = (d / "cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if b"--claims" in args and b"--parent" in args and args[args.index(b"--parent") + 1] == str(parent).encode():
                found.append(int(d.name))
    return found


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_kill_9_of_the_warm_up_leaves_none_of_its_processes(tmp_path):
    """``kill -9`` of ``roomseg compile`` while its other processes compile: none is left running."""
    import signal
    import time as _time

    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))  # empty: seconds of compiling
    p = subprocess.Popen([sys.executable, "-m", "benchmark.commands.compile_kernels", "--processes", "3"], env=env,
                         cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = _time.monotonic() + 60
        while len(_sharing_processes(p.pid)) < 2 and _time.monotonic() < deadline and p.poll() is None:
            _time.sleep(0.05)
        assert len(_sharing_processes(p.pid)) == 2, "the other processes never started"
        os.kill(p.pid, signal.SIGKILL)
        p.wait()
        deadline = _time.monotonic() + 10
        while _sharing_processes(p.pid) and _time.monotonic() < deadline:
            _time.sleep(0.05)
        assert _sharing_processes(p.pid) == []
    finally:
        if p.poll() is None:
            p.kill()
