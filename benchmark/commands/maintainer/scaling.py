"""``python -m benchmark.commands.maintainer.scaling``: how a run scales with houses and workers.

For each number of houses N (``--houses``) and of workers W (``--workers``) it runs one
configuration, by default the oracle classifier (80 %), vision cone and post-processing on N
generated houses (``env=synthetic env.n_houses=N``), as a fresh ``roomseg-bench`` process
with ``run.workers=W`` and an empty results folder and cache, and prints one table:

- wall time (s) of the whole process, start-up included;
- CPU time (s, user + system) of the process and every worker it reaped (``getrusage``
  of children: exact for local workers; Ray's own processes are not children, so with
  ``--executor ray`` it counts the driver only);
- peak memory (MB) of the process tree, sampled every ``--sample`` seconds from ``/proc``
  by a thread at niceness ``--sample-nice`` (default 19, the lowest CPU priority: samples
  come later while every core is busy; :class:`PeakMemory`):
  the sum of PSS (proportional set size: a page shared by forked workers counts once,
  split between them) and, for comparison, the sum of RSS (shared pages counted in
  every process); Linux only;
- houses per second (N / wall) and the mean milliseconds per stage of the houses computed
  in the run (``timings.csv``: ``t_scene``, ``t_render``, ...), and per house in its worker;
- whether ``metrics.csv`` is byte-identical to the first worker count's for the same N;
- the machine's 1-minute load average when the run started (other work on the machine
  slows the run: compare runs taken at similar loads).

Extra ``key=value`` arguments are Hydra overrides of the run (e.g. ``env=procthor_shared``);
the ones here are defaults they replace. Exit status 1 when a run fails (one line naming it).
"""

from __future__ import annotations

import contextlib
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pandas as pd

from benchmark.commands import cli

ROOT = Path(__file__).resolve().parents[3]

#: the configuration measured (issue #27): overridable by trailing key=value arguments.
DEFAULTS = ("env=synthetic", "classifier=oracle", "aggregator=vision_cone", "postprocess=default")
#: stage timings of timings.csv, in pipeline order (others follow alphabetically).
STAGES = ("t_scene", "t_viewpoints", "t_render", "t_render_load", "t_classify", "t_aggregate", "t_postprocess",
          "t_segment", "t_score")

#: the memory sampler's default CPU niceness: the lowest priority (see :class:`PeakMemory`)
SAMPLE_NICE = 19


def _proc_table() -> dict[int, int]:
    """{pid: parent pid} of every process (Linux ``/proc``)."""
    out = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                out[int(d.name)] = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
    return out


def descendants(pid: int) -> list[int]:
    """``pid`` and every process below it (Linux): from each process's ``children`` files, or,
    where the kernel has none, from every process's parent."""
    try:
        return _descendants_by_children(pid)
    except (OSError, ValueError):
        pass
    parent = _proc_table()
    kids: dict[int, list[int]] = {}
    for c, p in parent.items():
        kids.setdefault(p, []).append(c)
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        todo.extend(kids.get(p, []))
    return out


def _descendants_by_children(pid: int) -> list[int]:
    """``pid`` and its descendants from ``/proc/<pid>/task/<tid>/children`` (a process's own
    children, per thread): reads only the tree's files, not every process's. A process that
    ends in between is left out. Raises OSError where the kernel has no such file."""
    if not Path(f"/proc/{pid}/task/{pid}/children").exists():
        raise FileNotFoundError(f"/proc/{pid}/task/{pid}/children")
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        try:
            tasks = os.listdir(f"/proc/{p}/task")
        except OSError:
            continue
        for t in tasks:
            try:
                with open(f"/proc/{p}/task/{t}/children") as f:
                    todo.extend(int(c) for c in f.read().split())
            except OSError:
                continue
    return out


def _kb(path: Path, field: str) -> int | None:
    try:
        for line in path.read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return None


def tree_memory(pid: int) -> tuple[int, int, int]:
    """(PSS bytes, RSS bytes, processes) summed over ``pid`` and its descendants (Linux; a
    process without ``smaps_rollup`` counts its RSS as PSS)."""
    pss = rss = n = 0
    for p in descendants(pid):
        r = _kb(Path(f"/proc/{p}/status"), "VmRSS")
        if r is None:
            continue
        s = _kb(Path(f"/proc/{p}/smaps_rollup"), "Pss")
        rss += r * 1024
        pss += (s if s is not None else r) * 1024
        n += 1
    return pss, rss, n


class PeakMemory:
    """Samples :func:`tree_memory` of ``pid`` every ``every`` seconds in a thread; keeps the peaks.

    The thread runs at niceness ``nice`` (Linux: a thread's own priority; default 19, the
    lowest). A sample reads every process's ``smaps_rollup``, which walks its page tables:
    about 20 ms of CPU for a driver and two workers of 300 MB, so at normal priority (0)
    sampling every 0.25 s took about a twelfth of a core from the run it measures. At nice 19
    a sample waits while every core is busy, so the sampler takes little from the run, but
    samples are then further apart than ``every``: a run of a few seconds on a busy machine
    may end before its workers are sampled (use 0 there)."""

    def __init__(self, pid: int, every: float = 0.25, nice: int = SAMPLE_NICE) -> None:
        self.pid, self.every, self.nice = pid, every, nice
        self.pss = self.rss = self.procs = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        if self.nice and sys.platform.startswith("linux"):  # (elsewhere it would be the whole process's)
            with contextlib.suppress(OSError):
                os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), self.nice)
        while not self._stop.is_set():
            pss, rss, n = tree_memory(self.pid)
            self.pss, self.rss, self.procs = max(self.pss, pss), max(self.rss, rss), max(self.procs, n)
            self._stop.wait(self.every)

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def measure(n_houses: int, workers: int, overrides: list[str], work: Path, executor: str = "local",
            sample: float = 0.25, sample_nice: int = SAMPLE_NICE) -> dict:
    """One fresh ``roomseg-bench`` run of ``n_houses`` houses on ``workers`` workers into ``work``.

    Returns:
        a row of the table (see the module docstring), plus ``metrics`` (the path of its metrics.csv).

    Raises:
        RuntimeError: the run failed (its last line of stderr)."""
    shutil.rmtree(work, ignore_errors=True)
    work.parent.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "benchmark.commands.bench", *DEFAULTS, f"env.n_houses={n_houses}",
           f"run.workers={workers}", f"run.executor={executor}", f"run.results_dir={work}", "run.name=scaling",
           "run.progress=false", *overrides]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    with open(work.with_suffix(".log"), "w") as log:
        p = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT)
        peak = PeakMemory(p.pid, sample, sample_nice) if sys.platform.startswith("linux") else None
        code = p.wait()
    wall = time.perf_counter() - t0
    if peak is not None:
        peak.stop()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if code != 0:
        tail = [ln for ln in work.with_suffix(".log").read_text().splitlines() if ln.strip()][-1:]
        raise RuntimeError(f"{n_houses} houses on {workers} worker(s): roomseg-bench exited {code}: "
                           f"{tail[0] if tail else ''}")
    job = work / "runs" / "scaling"
    timings = pd.read_csv(job / "timings.csv")
    fresh = timings[~timings["cached"].astype(bool)]
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    row = {"houses": n_houses, "workers": workers, "wall s": wall, "CPU s": cpu, "CPU / wall": cpu / wall,
           "peak PSS MB": peak.pss / 2**20 if peak else float("nan"),
           "peak RSS MB": peak.rss / 2**20 if peak else float("nan"),
           "processes": peak.procs if peak else float("nan"), "houses / s": n_houses / wall,
           "computed": len(fresh), "ms / house": 1e3 * fresh["house_s"].mean(), "load before": load}
    cols = [c for c in STAGES if c in fresh] + sorted(c for c in fresh if c.startswith("t_") and c not in STAGES)
    for c in cols:
        row[f"{c[2:]} ms"] = 1e3 * fresh[c].mean()
    row["metrics"] = job / "metrics.csv"
    return row


def main(argv: list[str] | None = None) -> int:
    from benchmark.harness.processes import available_cores

    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0].split(": ", 1)[1],
                                 epilog="e.g. python -m benchmark.commands.maintainer.scaling --houses 100 1000 --workers 1 2")
    ap.add_argument("--houses", type=int, nargs="+", default=[100], help="numbers of houses (default 100)")
    ap.add_argument("--workers", type=int, nargs="+", default=None,
                    help=f"numbers of workers (default: 1 and the cores available, here {available_cores()})")
    ap.add_argument("--executor", choices=("local", "ray"), default="local", help="run.executor (default local)")
    ap.add_argument("--sample", type=float, default=0.25, help="seconds between two memory samples (default 0.25)")
    ap.add_argument("--sample-nice", type=int, default=SAMPLE_NICE, choices=range(20), metavar="0-19",
                    help="CPU niceness of the memory sampler (default 19: it takes CPU only when a core is free, "
                         "so samples come later while every core is busy; 0: on time, taking about a twelfth of "
                         "a core from the run)")
    ap.add_argument("--work", type=Path, default=None,
                    help="folder for the runs' results and caches (default: a temporary folder, removed)")
    ap.add_argument("--out", type=Path, default=None, help="also write the table here (Markdown; CSV beside it)")
    ap.add_argument("overrides", nargs="*", help="Hydra overrides of the run, key=value")
    a = ap.parse_args(argv)
    workers = a.workers or sorted({1, available_cores()})
    bad = [n for n in [*a.houses, *workers] if n < 1]
    if bad:
        print(f"scaling: error: --houses/--workers {bad[0]}: expected integers >= 1", file=sys.stderr)
        return 2
    work = a.work or Path(tempfile.mkdtemp(prefix="roomseg-scaling-"))
    rows = []
    try:
        for n in a.houses:
            first = None
            for w in workers:
                try:
                    row = measure(n, w, a.overrides, work / f"n{n}_w{w}", a.executor, a.sample, a.sample_nice)
                except RuntimeError as e:
                    print(f"scaling: error: {e}", file=sys.stderr)
                    return 1
                metrics = row.pop("metrics").read_bytes()
                first = metrics if first is None else first
                row["rows identical"] = "yes" if metrics == first else "NO"
                rows.append(row)
                print(f"{n} houses, {w} worker(s): {row['wall s']:.1f} s wall, {row['CPU s']:.1f} s CPU, "
                      f"{row['houses / s']:.2f} houses/s, peak {row['peak PSS MB']:.0f} MB PSS", flush=True)
    finally:
        if a.work is None:
            shutil.rmtree(work, ignore_errors=True)
    table = pd.DataFrame(rows)
    md = table.to_markdown(index=False, floatfmt=".1f")
    note = (f"\nOne configuration ({' '.join(DEFAULTS + tuple(a.overrides))}), each run a fresh process from an "
            f"empty cache; CPU: the process and its reaped workers; memory: peak over samples every {a.sample} s "
            f"(at nice {a.sample_nice}{': later while every core is busy' if a.sample_nice else ''}) "
            f"of the process tree's summed PSS (RSS counts pages shared by forked workers in each); stage times: "
            f"mean ms over the houses computed (timings.csv); 'rows identical': metrics.csv byte-equal to the "
            f"first worker count's for the same houses.")
    print()
    print(md)
    print(note)
    if a.out is not None:
        from benchmark.harness.cache import atomic_write_text
        from benchmark.reports.published import write_measured

        write_measured(a.out, "benchmark.commands.maintainer.scaling", argv, md + "\n" + note)
        atomic_write_text(a.out.with_suffix(".csv"), table.to_csv(index=False))
    return 0 if all(r["rows identical"] == "yes" for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
