"""The end of a multirun: one table of its jobs (houses ok / failed, mean metrics), printed and
written into the sweep folder as ``sweep_summary.md`` and ``sweep_summary.csv`` (both
atomically), by a Hydra callback (``hydra.callbacks.sweep_summary`` in ``conf/config.yaml``).

It also keeps the outcome of the process (:data:`OUTCOME`): jobs, failed houses and whether
failures are allowed, so that ``roomseg-bench`` exits non-zero when any house failed. In a
multirun the callback runs in the launching process after every job; in a single run the
task function records its own job.
"""

from __future__ import annotations

import logging
import os
import time
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd
from hydra.experimental.callback import Callback
from omegaconf import DictConfig

from benchmark.harness.cache import atomic_write_text
from benchmark.harness.store import SWEEP_SUMMARY, Job, find_jobs

log = logging.getLogger("roomseg-bench")

#: the process's outcome: jobs run, houses failed, failures allowed (``run.allow_failures``).
OUTCOME: dict[str, Any] = {"jobs": 0, "n_failed": 0, "allow_failures": False, "errors": [], "died": []}

#: a job that could not run (bad setting, unwritable folder, stage not built) leaves this
#: one-line file in its Hydra output folder, so that the launching process can report it.
JOB_ERROR = "job_error.txt"

METRICS = ("iou", "precision", "recall", "accuracy")

#: the environment variable carrying the running multirun's token to its jobs (forked or
#: spawned workers inherit it); a job writes it into ``summary.json`` and ``job_error.txt``,
#: and the sweep's end reads back the jobs that carry it. File times cannot tell this
#: multirun's jobs from an earlier one's that ended within the file system's time resolution.
SWEEP_ENV = "ROOMSEG_SWEEP_ID"


def current_sweep() -> str | None:
    """The token of the multirun this process runs a job of (None outside one)."""
    return os.environ.get(SWEEP_ENV) or None


def record(n_failed: int, allow_failures: bool) -> None:
    """Add one finished job to :data:`OUTCOME`."""
    OUTCOME["jobs"] += 1
    OUTCOME["n_failed"] += int(n_failed)
    OUTCOME["allow_failures"] = bool(allow_failures)


def record_error(message: str, out_dir: Path) -> None:
    """A job that could not run: keep its one-line reason in :data:`OUTCOME` and in
    ``<out_dir>/job_error.txt`` (read by :class:`SweepSummary` in the launching process)."""
    OUTCOME["errors"].append(message)
    token = current_sweep()
    try:
        atomic_write_text(Path(out_dir) / JOB_ERROR, message + "\n" + (f"sweep {token}\n" if token else ""))
    except OSError:
        pass  # the folder itself is unwritable: the message is in OUTCOME (and the job's log)


def record_died(message: str) -> None:
    """A single run whose worker process died (:class:`benchmark.harness.executor.WorkerDied`):
    its one-line reason, for an exit status of 1 (in a multirun the launcher ends the sweep)."""
    OUTCOME["died"].append(message)


def read_error(path: Path) -> tuple[str, str | None]:
    """A ``job_error.txt``: its one-line reason and the token of the multirun that wrote it."""
    lines = Path(path).read_text(encoding="utf-8").strip().splitlines() or [""]
    token = lines[-1][len("sweep "):] if len(lines) > 1 and lines[-1].startswith("sweep ") else None
    return "\n".join(lines[:-1] if token else lines).strip(), token


def clear_error(out_dir: Path) -> None:
    """Remove an earlier job's error note from ``out_dir``."""
    try:
        (Path(out_dir) / JOB_ERROR).unlink()
    except OSError:
        pass


def sweep_table(jobs: Sequence[Job], root: Path) -> pd.DataFrame:
    """One row per job: its folder relative to ``root``, houses, ok, failed, mean metrics over
    its successful houses (from ``summary.json``) and wall time in seconds."""
    rows = []
    for job in jobs:
        s = job.summary()
        try:
            rel = str(job.dir.relative_to(root)) or "."
        except ValueError:
            rel = str(job.dir)
        row = {"job": rel, "houses": s.get("n_houses"), "ok": s.get("n_ok"), "failed": s.get("n_failed")}
        row.update({f"mean_{m}": s.get(f"mean_{m}") for m in METRICS})
        row["wall_s"] = s.get("wall_time_s")
        rows.append(row)
    return pd.DataFrame(rows, columns=["job", "houses", "ok", "failed", *[f"mean_{m}" for m in METRICS], "wall_s"])


def launched_dirs(sweep: str) -> set[Path]:
    """The job folders this process's launcher (``hydra/launcher: local``) reports the multirun
    ``sweep`` wrote, resolved (empty with another launcher)."""
    import importlib

    try:
        launched = importlib.import_module("hydra_plugins.roomseg_sweep.roomseg_sweep").LAUNCHED
    except (ImportError, AttributeError):
        return set()
    out = set()
    for ret in launched:
        info = getattr(ret, "roomseg_job", None) or {}
        if info.get("sweep") == sweep and info.get("dir"):
            out.add(Path(info["dir"]).resolve())
    return out


def write_summary(sweep_dir: Path, sweep: str | None = None, started: float | None = None) -> pd.DataFrame:
    """Summarise the jobs under ``sweep_dir`` into ``sweep_summary.{md,csv}`` there; with the
    multirun token ``sweep``, only that multirun's jobs, and record them in ``last_sweep.json``
    (``started``: the multirun's start, Unix time).

    A multirun's jobs are those whose ``summary.json`` carries its token and those its launcher
    reports it wrote (:func:`launched_dirs`): two multiruns into one folder at once that run the
    same configuration write the same job folder, whose ``summary.json`` is the last writer's,
    so each counts its own jobs whichever wrote last.

    Returns:
        The table (empty when no job finished)."""
    try:
        jobs = find_jobs([sweep_dir])
    except FileNotFoundError:
        jobs = []
    if sweep is not None:
        ran = launched_dirs(sweep)
        jobs = [j for j in jobs if j.summary().get("sweep_id") == sweep or j.dir.resolve() in ran]
    table = sweep_table(jobs, sweep_dir)
    n_failed = int(table["failed"].fillna(0).sum()) if len(table) else 0
    pct = table.copy()
    for m in METRICS:
        pct[f"mean_{m}"] = [f"{100 * v:.2f}" if isinstance(v, float) else "–" for v in table[f"mean_{m}"]]
    md = (f"### Sweep {sweep_dir}\n\n" + (pct.to_markdown(index=False) if len(pct) else "(no finished job)")
          + f"\n\n{len(table)} jobs, {int(table['houses'].fillna(0).sum()) if len(table) else 0} rows, "
          f"{n_failed} failed; metrics in percent over each job's successful houses.\n")
    atomic_write_text(sweep_dir / f"{SWEEP_SUMMARY}.csv", table.to_csv(index=False))
    atomic_write_text(sweep_dir / f"{SWEEP_SUMMARY}.md", md)
    if sweep is not None:  # the jobs this multirun ran: tables and the report can read them alone
        import sys

        from benchmark.harness.store import write_last_sweep

        write_last_sweep(sweep_dir, jobs, started if started is not None else time.time(), sys.argv[1:])
    return table


#: the multirun of this process (its folder and start time), for a summary after a failure.
_STARTED: dict[str, Any] = {}


def write_summary_after_failure() -> None:
    """Write the sweep summary of this process's multirun when a failed job stopped Hydra's
    sweeper before its end callback (best effort: a full disk may refuse it too)."""
    if "dir" not in _STARTED:
        return
    try:
        write_summary(_STARTED["dir"], sweep=_STARTED["sweep"], started=_STARTED["t0"])
    except OSError:
        pass


#: the longest job table a sweep prints at its end (longer ones: their file, and the totals).
PRINTED_JOBS = 40


class SweepSummary(Callback):
    """Hydra callback: at the end of a multirun, print and write the sweep's job table."""

    def __init__(self) -> None:
        self.t0: float | None = None
        self.sweep: str | None = None

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        self.t0 = time.time()
        self.sweep = uuid.uuid4().hex
        os.environ[SWEEP_ENV] = self.sweep  # before the launcher starts its workers
        _STARTED.update(dir=Path(str(config.hydra.sweep.dir)), t0=self.t0, sweep=self.sweep)

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(str(config.hydra.sweep.dir))
        table = write_summary(sweep_dir, sweep=self.sweep, started=self.t0)
        errors = [read_error(p) for p in sorted(sweep_dir.rglob(JOB_ERROR))]
        OUTCOME["errors"] = [msg for msg, token in errors if token == self.sweep]
        if os.environ.get(SWEEP_ENV) == self.sweep:
            del os.environ[SWEEP_ENV]
        OUTCOME["jobs"] = len(table)
        OUTCOME["n_failed"] = int(table["failed"].fillna(0).sum()) if len(table) else 0
        OUTCOME["allow_failures"] = bool(config.run.get("allow_failures", False))
        md = (sweep_dir / f"{SWEEP_SUMMARY}.md").read_text(encoding="utf-8")
        if len(table) <= PRINTED_JOBS:
            print(md, flush=True)
        else:  # a long sweep (make robustness: 624 jobs): its last line and where the table is
            print(f"{md.rstrip().splitlines()[-1]} Per job: {sweep_dir / (SWEEP_SUMMARY + '.md')}", flush=True)


__all__ = ["SweepSummary", "OUTCOME", "JOB_ERROR", "SWEEP_ENV", "clear_error", "current_sweep", "launched_dirs", "read_error", "record", "record_died", "record_error", "sweep_table",
           "write_summary"]
