"""Compile the numba kernels ahead of a first run (``make setup`` does it once).

numba compiles a kernel on its first call and keeps the machine code in its on-disk cache
(``cache=True``: ``__pycache__`` beside the source, or ``NUMBA_CACHE_DIR``); a later process
loads it in milliseconds. A fresh clone has no cache, so its first run used to wait seconds
of compiling before any house was done (``--measure`` says how many), and so did every pool or Ray worker on a
fresh machine. This command calls every stage that has a kernel through its public
function on one small generated house, with the argument types a run passes, so each
kernel is compiled (or loaded) with exactly the signature a run needs:

    python -m benchmark.commands.compile_kernels            # compile into numba's cache
    python -m benchmark.commands.compile_kernels --measure  # the options, timed (below)

The stages are shared among as many processes as the cores this process may use (at most
:data:`MAX_PROCESSES`; ``--processes N`` sets it): each takes the next stage no other has taken
(a work queue: a file per stage, created by the first to claim it) and compiles it into the same
cache (numba writes each kernel's files apart, by renaming them into place). A process that
fails makes the command fail with its message; Ctrl-C stops them all, and the others die with
the launching process if it is killed.

``--measure`` runs the warm-up in fresh processes and prints, per stage, the seconds with
an empty cache (a temporary ``NUMBA_CACHE_DIR``: what a fresh clone pays) and with the
cache filled (what every run after ``make setup`` pays), how many signatures the kernels
were compiled for (each one is a separate compile), and the wall time of the whole command
as ``make setup`` runs it (its processes side by side) with an empty cache. Nothing
outside the temporary folder is written by ``--measure`` but the table to ``--out`` (under a line
saying when, where and by which command it was measured: ``make compile-publish`` writes
``results/published/compile_kernels.md``, which docs/sweeps-and-clusters.md includes).

Every ``numba`` dispatcher in the ``benchmark`` and ``envs`` packages must be reached here:
:func:`kernels` lists them and the test suite checks none is left uncompiled.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import pkgutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

#: the most processes the warm-up is shared among (about 15 stages: beyond a few, each process's
#: start, imports and house cost more than its share of compiling)
MAX_PROCESSES = 4

#: packages whose modules hold kernels (algorithm modules only: commands hold none)
PACKAGES = ("envs", "benchmark")
SKIP = ("benchmark.commands", "benchmark.classifiers", "benchmark.reports", "envs.render.ai2thor",
        "envs.render.habitat")


def kernels() -> dict[str, object]:
    """Every numba dispatcher defined in the algorithm modules: ``{"module.name": dispatcher}``."""
    from numba.core.registry import CPUDispatcher

    found: dict[str, object] = {}
    for pkg_name in PACKAGES:
        pkg = importlib.import_module(pkg_name)
        for info in pkgutil.walk_packages(pkg.__path__, pkg_name + "."):
            if info.name.startswith(SKIP):
                continue
            try:
                mod = importlib.import_module(info.name)
            except ImportError:  # an optional simulator adapter whose library is absent
                continue
            for name, obj in vars(mod).items():
                if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == info.name:
                    found[f"{info.name}.{name}"] = obj
    return found


def _scene():
    from envs.datasets.synthetic import generate_house
    from envs.maps.scene import rasterise_house

    house = generate_house(0, length=(7.0, 7.0), depth=(6.5, 6.5))
    return house, rasterise_house(house, resolution=0.1)


def _front_end(grid, poses):
    """The SLAM front end (scan ranges, the matcher's grid and search) along the first views' route."""
    from benchmark.conditions.front_end import FrontEndSettings, run_front_end
    from benchmark.conditions.odometry import increments, move_sigmas, to_se2
    from benchmark.conditions.pose_graph import move_edge
    from envs.maps.trajectory import trajectory_with_views

    true, _ = trajectory_with_views(grid.walkable, grid, poses[:6], 0.5)
    states = to_se2(true)
    moves = increments(states)
    z, info = move_edge(moves, move_sigmas(moves, (1e-4, 1e-4, 1e-4, 1e-5)), 1e-3)
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(true[:, :2], axis=0).T))])
    from benchmark.conditions.scan_matching import LikelihoodGrid, match

    ring = np.column_stack([np.cos(np.linspace(0, 6.2, 90)), np.sin(np.linspace(0, 6.2, 90))]) * 3.0
    wide = match(LikelihoodGrid(ring, 0.05, 0.05), ring, (0.0, 0.0, 0.0), 1.0, 0.1, 0.05)  # branch and bound
    return run_front_end(~grid.walkable, grid, states, z, info, travelled, FrontEndSettings(closure_min_travel=1.0)), wide


def stages() -> list[tuple[str, Callable[[], object]]]:
    """(name, call) per stage with a kernel, on one small generated house (7 m x 6.5 m, 0.1 m/px)."""
    from benchmark.aggregators.euclidean_knn import EuclideanKNN
    from benchmark.aggregators.graph_knn import GraphKNN
    from benchmark.aggregators.vision_cone import VisionCone
    from benchmark.conditions.alignment import to_map_frame
    from benchmark.conditions.calibration import expected_hits
    from benchmark.conditions.coverage import view_coverage
    from benchmark.conditions.exploration import Frontier, RandomWalk
    from benchmark.metrics import segments
    from benchmark.postprocess import PostProcess
    from benchmark.segmenters.distance import DistanceTransform
    from benchmark.segmenters.voronoi import Voronoi
    from benchmark.viewpoints import Autotrace
    from envs.logs.raw_map import raw_log_odds
    from envs.maps.rays import cast_rays
    from envs.maps.scan import ScanSettings, house_wall_height, robot_scan_map, scan_obstacles
    from envs.maps.slam_map import scan_map_at_estimate
    from envs.maps.trajectory import route
    from envs.render.floorplan import FloorplanRenderer, occluders

    house, scene = _scene()
    poses = Autotrace().generate(scene)
    rng = np.random.default_rng(0)
    proba = rng.dirichlet(np.ones(len(scene.classes)), len(poses))
    grid = scene.grid
    labels = scene.semantic
    return [
        ("render (floorplan)", lambda: FloorplanRenderer().render(house, scene, poses)),
        ("graph_knn", lambda: (GraphKNN()(grid, poses, proba), GraphKNN(weighting="probability")(grid, poses, proba))),
        # whole votes in uint8 and, with 256 views or more within a cone's reach of a cell (a ProcTHOR
        # house's views often are), in uint16; probability votes in float32
        ("vision_cone", lambda: (VisionCone()(grid, poses, proba), VisionCone(vote="probability")(grid, poses, proba),
                                 VisionCone()(grid, np.repeat(poses, 256 // len(poses) + 1, axis=0),
                                              np.repeat(proba, 256 // len(poses) + 1, axis=0)))),
        ("euclidean_knn", lambda: EuclideanKNN()(grid, poses, proba)),
        ("postprocess", lambda: PostProcess()(labels, grid)),
        ("distance segmenter", lambda: DistanceTransform()(grid)),
        ("voronoi segmenter", lambda: Voronoi()(grid)),
        ("segments", lambda: [segments(labels.astype(t), c) for t in (np.int16, np.int32, np.int64) for c in (4, 8)]),
        ("scan map", lambda: robot_scan_map(scene, poses[:4], ScanSettings(range_noise=0.02, dropout=0.1, seed=1),
                                            house_wall_height(house))),
        ("scan map at a SLAM estimate", lambda: scan_map_at_estimate(
            scan_obstacles(scene, 0.25, house_wall_height(house)), grid, poses[:4], poses[:4] + [0.05, 0.0, 1.0],
            ScanSettings(range_noise=0.02, dropout=0.1, seed=1))),
        ("exploration", lambda: (Frontier(budget=3.0).explore(scene), RandomWalk(budget=3.0).generate(scene))),
        ("scan-matching front end", lambda: _front_end(grid, poses)),
        ("route", lambda: route(grid.walkable, grid, poses[:4])),
        ("map frame", lambda: to_map_frame(scene.instances, grid, 0.01, np.array([0.05, 0.0]))),
        ("coverage", lambda: view_coverage(scene, poses, 90.0, 6.0, occluders(scene, 1.2))),
        ("ray cast", lambda: cast_rays(~grid.walkable, *grid.world_to_cell(poses[0, 0], poses[0, 1]),
                                       np.array([0.0, 1.0]), 10.0)),
        ("calibration's expected hits", lambda: expected_hits(~grid.walkable, np.array([grid.walkable.shape[0] // 2]),
                                                              np.array([grid.walkable.shape[1] // 2]),
                                                              np.array([[0.0, 1.5, 3.0]]), 20.0)),
        ("raw map of real scans", lambda: raw_log_odds(np.array([[0.0, 0.0, 0.0], [0.5, 0.0, 0.3]]),
                                                       np.full((2, 3), 2.0), np.array([-0.5, 0.0, 0.5]))),
    ]


def warm(claims: Path | None = None) -> dict[str, float]:
    """Run every stage once; return the seconds each took (compile or cache load included).

    Args:
        claims: a folder shared by the processes of :func:`warm_shared`: a stage is run only by
            the process that claims it first there (None: every stage, here)."""
    t0 = time.perf_counter()
    todo = stages()
    took = {"setup (house, autotrace)": time.perf_counter() - t0}
    for i, (name, call) in enumerate(todo):
        if claims is not None and not _claim(claims, i):
            continue
        t = time.perf_counter()
        call()
        took[name] = time.perf_counter() - t
    return took


def _claim(claims: Path, i: int) -> bool:
    """Claim stage ``i`` in ``claims``: True for the one process whose file is created first."""
    try:
        os.close(os.open(claims / f"stage-{i}", os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
    except FileExistsError:
        return False
    return True


def warm_shared(processes: int) -> list[list[str]]:
    """:func:`warm`, its stages shared among ``processes`` processes (this one and the others it
    starts, ``--claims DIR``) that each take the next stage none has taken and compile into the
    same cache side by side.

    Returns:
        The stages each process ran (this one's first).

    Raises:
        RuntimeError: a process failed (its exit status and the end of its error output).
    """
    n = max(1, int(processes))
    if n == 1:
        return [_ran(warm())]
    with tempfile.TemporaryDirectory(prefix="roomseg-warm-up-") as claims:
        cmd = [sys.executable, "-m", "benchmark.commands.compile_kernels", "--claims", claims,
               "--parent", str(os.getpid())]
        others = [subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                  for _ in range(1, n)]
        try:
            ran = [_ran(warm(Path(claims)))]
        except BaseException:  # Ctrl-C or a failed stage here: the others stop too
            for p in others:
                p.kill()
                p.communicate()
            raise
        failed = []
        for i, p in enumerate(others, 1):
            out, err = p.communicate()
            if p.returncode != 0:
                failed.append(f"process {i + 1} of {n} exited {p.returncode}: {err.strip()[-1500:]}")
            else:  # its last line: the stages it ran (--claims)
                ran.append(json.loads(out.strip().splitlines()[-1]))
    if failed:
        raise RuntimeError("the kernel warm-up failed in another process: " + "; ".join(failed))
    return ran


def _ran(took: dict[str, float]) -> list[str]:
    """The stages a :func:`warm` record holds (not its set-up)."""
    return [k for k in took if k != "setup (house, autotrace)"]


def _child() -> None:
    t0 = time.perf_counter()
    import numba  # noqa: F401  (the import is part of what a run pays, counted apart)

    t_import = time.perf_counter() - t0
    took = warm()
    sigs = {k: len(d.signatures) for k, d in kernels().items()}
    print(json.dumps({"import numba": t_import, "stages": took, "signatures": sigs}))


def _measure_once(cache_dir: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "benchmark.commands.compile_kernels", "--child"], env=env,
                       capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"the warm-up process failed (exit {p.returncode}): {p.stderr.strip()[-2000:]}")
    res = json.loads(p.stdout.strip().splitlines()[-1])
    res["process"] = time.perf_counter() - t0
    return res


def _command_seconds(cache_dir: str, processes: int) -> float:
    """Wall seconds of the warm-up command as ``make setup`` runs it, on ``processes`` processes."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "benchmark.commands.compile_kernels", "--processes", str(processes)],
                       env=env, capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"the warm-up command failed (exit {p.returncode}): {p.stderr.strip()[-2000:]}")
    return time.perf_counter() - t0


def measure(processes: int) -> str:
    """The warm-up timed in fresh processes, empty cache then filled cache, stage by stage in one
    process, then the whole command on ``processes`` processes (a table)."""
    with tempfile.TemporaryDirectory(prefix="numba-cache-") as d:
        cold = _measure_once(d)
        warm_ = _measure_once(d)
    with tempfile.TemporaryDirectory(prefix="numba-cache-") as d:
        shared = {"processes": processes, "cold": _command_seconds(d, processes),
                  "warm": _command_seconds(d, processes)}
    return measure_table(cold, warm_, shared)


def measure_table(cold: dict, warm_: dict, shared: dict | None = None) -> str:
    """The Markdown table of two warm-up processes' records (``{"stages": {name: seconds},
    "process": seconds, "signatures": {kernel: count}}``; ``cold`` with an empty numba cache,
    ``warm_`` with it filled): seconds per stage, their sums, the whole processes, then (``shared``:
    ``{"processes": n, "cold": s, "warm": s}``) the whole command with its stages shared among n
    processes, then a line on the kernels and their signatures as ``cold`` compiled them."""
    lines = ["| stage | empty numba cache (s) | filled cache (s) |", "|---|---:|---:|"]
    for k in cold["stages"]:
        lines.append(f"| {k} | {cold['stages'][k]:.2f} | {warm_['stages'][k]:.2f} |")
    tc, tw = sum(cold["stages"].values()), sum(warm_["stages"].values())
    lines.append(f"| **all stages** | **{tc:.2f}** | **{tw:.2f}** |")
    lines.append(f"| whole process (python start, imports, stages) | {cold['process']:.2f} | {warm_['process']:.2f} |")
    if shared is not None:
        lines.append(f"| the command as `make setup` runs it (stages shared among {shared['processes']} processes) "
                     f"| {shared['cold']:.2f} | {shared['warm']:.2f} |")
    sigs = cold["signatures"]  # as compiled (a kernel loaded from the cache lists none)
    multi = {k: v for k, v in sigs.items() if v > 1}
    inner = sorted(k for k, v in sigs.items() if v == 0)
    lines.append("")
    lines.append(f"{len(sigs)} kernels, compiled for {sum(sigs.values())} argument-type signatures"
                 + (" (more than one: " + ", ".join(f"{k} x{v}" for k, v in multi.items())
                    + "; a call inside another kernel counts too)" if multi else "")
                 + (f"; inlined only into the kernels that call them: {', '.join(inner)}" if inner else "") + ".")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--measure", action="store_true",
                    help="time the warm-up with an empty and a filled numba cache in fresh processes (writes nothing "
                         "but --out)")
    ap.add_argument("--out", default=None,
                    help="with --measure: also write the table here (Markdown, under a line with the date, machine, "
                         "commit and command)")
    ap.add_argument("--processes", type=int, default=None,
                    help=f"processes the stages are shared among (default: the cores this process may use, at most "
                         f"{MAX_PROCESSES})")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--claims", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--parent", type=int, default=None, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        _child()
        return 0
    if a.claims is not None:  # one of warm_shared's processes: says which stages it ran
        if a.parent is not None:  # it dies with the launching process, which handles Ctrl-C
            from benchmark.harness.processes import worker_init

            worker_init(a.parent)
        print(json.dumps(_ran(warm(Path(a.claims)))))
        return 0
    if a.processes is not None and a.processes < 1:
        ap.error(f"--processes {a.processes}: expected a number of processes >= 1")
    if a.processes is None:
        from benchmark.harness.processes import available_cores

        a.processes = min(available_cores(), MAX_PROCESSES)
    if a.out is not None and not a.measure:
        ap.error(f"--out {a.out}: only with --measure (expected --measure --out FILE)")
    if a.measure:
        text = measure(a.processes)
        print(text)
        if a.out is not None:
            from benchmark.reports.published import write_measured

            write_measured(a.out, "benchmark.commands.compile_kernels", argv, text)
        return 0
    t0 = time.perf_counter()
    try:
        ran = warm_shared(a.processes)
    except RuntimeError as e:
        print(f"compile_kernels: {e}", file=sys.stderr)
        return 1
    shares = " + ".join(str(len(r)) for r in ran)
    print(f"numba kernels compiled into the cache in {time.perf_counter() - t0:.1f} s on {len(ran)} process"
          f"{'es' if len(ran) > 1 else ''} ({shares} stages; {len(kernels())} kernels; a first run now loads them "
          f"instead of compiling)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
