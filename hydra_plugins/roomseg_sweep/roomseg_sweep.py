"""roomseg-bench's Hydra sweeper and launcher (``hydra/sweeper: grids``, ``hydra/launcher: local``).

Hydra finds plugins only under the ``hydra_plugins`` namespace, so these two classes live
here; the module imports Hydra, the standard library and one standard-library-only module of
the project, :mod:`benchmark.harness.processes` (Hydra imports it at start-up).

``GridsSweeper`` is Hydra's basic sweeper plus three things:

- ``grids``: more grids of ``key: values`` beside ``params``. The jobs are the cartesian
  product of ``params``, then the product of each extra grid, in that order (a job already
  listed is not repeated). Command-line sweep arguments apply to every grid. ``make bench``
  uses this to run the method grid and the Table IV sanity segmenters in one multirun.
- ``validate: quick`` (the default): before launching, it checks that every swept
  ``group=option`` names an option of its config group and composes the first job of each
  grid, instead of composing every job twice. ``validate: all`` is Hydra's own check (every
  job); ``none`` skips it. A job whose config still fails to compose fails alone, in the
  launcher, and the sweep exits non-zero naming it.
- ``group_by: <key>``: the jobs of every grid that give the key one value run one after the
  other, the values in the order they first come (``experiment=robustness``: a condition's
  segmenters right after its methods, while the workers still keep its maps in memory).
- ``same_worker: [<key>, ...]``: jobs whose overrides differ only in these keys are one unit,
  which the local launcher runs one after another on one worker, so that what the first leaves
  in that worker's per-process memos serves the next (``experiment=robustness``:
  ``[classifier]``, a condition's KNN neighbour tables, which do not depend on the classes).
  Other launchers run every job as always.

``LocalLauncher`` runs the jobs on ``n_jobs`` worker processes of this machine, like
``hydra-joblib-launcher``, but its workers are forked from the launching process on Linux, so
they start with Python, NumPy and the app already imported, and keep their per-process caches
from job to job. Elsewhere (or with ``start_method: spawn``) they are spawned. Each worker
composes its own jobs' configs, and dies with the launching process (``kill -9`` of it leaves
no worker behind: :mod:`benchmark.harness.processes`, a standard-library-only module).

``n_jobs: 1`` runs the jobs one after another in the launching process, where the app may
spread each job's houses over one pool of processes shared by every job of the sweep
(roomseg-bench's ``run.workers``). A job that fails because such a pool lost a process
(:class:`BrokenProcessPool`) ends the sweep, as a killed launcher worker does. ``n_jobs:
auto`` chooses between the two by the number of jobs: side by side on as many workers as
the cores available when the sweep has at least :data:`AUTO_JOBS_PER_CORE` jobs per core
(every core stays busy, and the few tenths of a second each job spends being composed and
set up overlap other jobs' work), else one after another (only the houses can use the cores).
Every job's ``hydra.launcher.n_jobs`` is the number of jobs that really run at once.
"""

from __future__ import annotations

import importlib
import logging
import multiprocessing
import os
import sys
import time
from collections.abc import Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import Override
from hydra.core.singleton import Singleton
from hydra.core.utils import (
    JobReturn,
    JobStatus,
    configure_log,
    filter_overrides,
    run_job,
    setup_globals,
)
from hydra.plugins.launcher import Launcher
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig, open_dict

from benchmark.harness.processes import JOB_SLOT_ENV, available_cores, share_threads, worker_init
from benchmark.harness.sweep_progress import SweepProgress
from benchmark.harness.write_errors import naming_the_file

log = logging.getLogger(__name__)

VALIDATE = ("quick", "all", "none")

#: ``n_jobs: auto`` runs jobs side by side when the sweep has at least this many jobs per core.
AUTO_JOBS_PER_CORE = 2


def auto_jobs(n_jobs_total: int, cores: int) -> int:
    """``n_jobs: auto``: ``cores`` workers when the sweep has at least
    :data:`AUTO_JOBS_PER_CORE` jobs per core, else 1 (jobs one after another)."""
    return cores if n_jobs_total >= AUTO_JOBS_PER_CORE * cores else 1


class GridsSweeper(BasicSweeper):
    """Hydra's basic sweeper over ``params`` and any extra ``grids``; quick validation.

    Args:
        max_batch_size: jobs per launcher call (None: all at once).
        params: the first grid, ``{key: "v1,v2"}`` as in Hydra's basic sweeper.
        grids: more grids of the same form, run after ``params``' jobs.
        validate: ``quick`` | ``all`` | ``none`` (see the module docstring).
        group_by: a key (``corruption``): the jobs of every grid that give it the same value run
            one after the other, the groups in the order their values first come (each group's
            jobs in their grids' order); None: each grid's jobs after the one before.
        same_worker: override keys (``[classifier]``): the local launcher runs jobs that differ
            only in them one after another on one worker (:func:`units`); read by it from the
            sweep's config.
    """

    def __init__(self, max_batch_size: int | None = None, params: Mapping[str, str] | None = None,
                 grids: Sequence[Mapping[str, str]] | None = None, validate: str = "quick",
                 group_by: str | None = None, same_worker: Sequence[str] | None = None) -> None:
        # BasicSweeper's own __init__ is not called: it names its class through a module global
        # that Hydra's plugin rescans rebind (``super(BasicSweeper, self)`` then fails)
        self.overrides = None
        self.batch_index = 0
        self.max_batch_size = max_batch_size
        self.params = dict(params or {})
        self.hydra_context = None
        self.config = None
        self.launcher = None
        if validate not in VALIDATE:
            raise ValueError(f"hydra.sweeper.validate must be one of {list(VALIDATE)}, got {validate!r}")
        self.grids = [dict(g or {}) for g in (grids or [])]
        self.validate = validate
        self.group_by = group_by or None
        if isinstance(same_worker, str) or not all(isinstance(k, str) for k in (same_worker or ())):
            raise ValueError(f"hydra.sweeper.same_worker must be a list of override keys, got {same_worker!r}")
        self.arguments: list[str] = []

    def sweep(self, arguments: list[str]) -> Any:
        self.arguments = list(arguments)  # the command line's sweeps, applied to every grid
        return super().sweep(arguments)

    def split_arguments(self, overrides: list[Override], max_batch_size: int | None) -> list[list[list[str]]]:
        """The jobs, in batches: Hydra's basic sweeper calls this on ``params`` + the command
        line (``overrides``); each extra grid + the command line follows, a job already listed
        is not repeated."""
        if not self.grids and not self.group_by:
            return BasicSweeper.split_arguments(overrides, max_batch_size)
        grids = [overrides]
        if self.grids:
            assert self.hydra_context is not None
            parser = OverridesParser.create(config_loader=self.hydra_context.config_loader)
            grids += [parser.parse_overrides([f"{k}={v}" for k, v in g.items()] + self.arguments) for g in self.grids]
        jobs: dict[tuple[str, ...], list[str]] = {}
        for grid in grids:
            for job in BasicSweeper.split_arguments(grid, None)[0]:
                jobs.setdefault(tuple(sorted(job)), job)
        ordered = grouped(list(jobs.values()), self.group_by) if self.group_by else list(jobs.values())
        return list(BasicSweeper.split_overrides_to_chunks(ordered, max_batch_size))

    def validate_batch_is_legal(self, batch: Sequence[Sequence[str]]) -> None:
        if self.validate == "none":
            return
        if self.validate == "all":
            return super().validate_batch_is_legal(batch)
        assert self.hydra_context is not None
        loader = self.hydra_context.config_loader
        check_options(batch, loader)
        return super().validate_batch_is_legal(one_per_grid(batch))


def grouped(jobs: Sequence[Sequence[str]], key: str) -> list[Sequence[str]]:
    """``jobs`` with those that give ``key`` the same value (``key=value`` among their
    overrides, or none) next to each other, the groups in the order their values first come,
    each group's jobs in their order."""
    def value(job: Sequence[str]) -> str | None:
        for o in job:
            k, eq, v = o.partition("=")
            if eq and k.lstrip("+~") == key:
                return v
        return None

    first: dict[str | None, int] = {}
    for job in jobs:
        first.setdefault(value(job), len(first))
    return sorted(jobs, key=lambda job: first[value(job)])  # (stable)


def units(jobs: Sequence[tuple[int, Sequence[str]]], keys: Sequence[str]) -> list[list[tuple[int, Sequence[str]]]]:
    """``jobs`` ((index, overrides) pairs) in units of those whose overrides are the same but
    for ``keys`` (``key=value``, with or without ``+``/``~``), each unit's jobs in their order, the
    units in the order of their first job; without ``keys`` every job is a unit of its own."""
    if not keys:
        return [[job] for job in jobs]
    out: dict[tuple[str, ...], list[tuple[int, Sequence[str]]]] = {}
    for i, overrides in jobs:
        rest = tuple(sorted(o for o in overrides if o.partition("=")[0].lstrip("+~") not in keys))
        out.setdefault(rest, []).append((i, overrides))
    return list(out.values())


def one_per_grid(batch: Sequence[Sequence[str]]) -> list[Sequence[str]]:
    """The first job of each set of override keys in ``batch`` (one job per grid), in order."""
    seen: set[tuple[str, ...]] = set()
    out = []
    for job in batch:
        keys = tuple(sorted(o.split("=", 1)[0] for o in job))
        if keys not in seen:
            seen.add(keys)
            out.append(job)
    return out


def check_options(batch: Sequence[Sequence[str]], loader: Any) -> None:
    """Every ``group=option`` of ``batch`` names an option of that config group.

    Raises:
        ConfigCompositionException: one line naming the override and the group's options."""
    from hydra.errors import ConfigCompositionException

    parser = OverridesParser.create(config_loader=loader)
    options: dict[str, list[str]] = {}
    for text in dict.fromkeys(o for job in batch for o in job):
        ov = parser.parse_overrides([text])[0]
        value = ov.value()
        if ov.is_delete() or not isinstance(value, str):
            continue
        group = ov.key_or_group
        if group not in options:
            options[group] = loader.get_group_options(group)
        if options[group] and value not in options[group]:
            raise ConfigCompositionException(
                f"sweep override {text!r}: {value!r} is not an option of config group '{group}' "
                f"(options: {', '.join(options[group])})")


# ---- the launcher
#: (hydra_context, config, task_function, singleton_state) of the sweep, in every worker.
_SWEEP: tuple[HydraContext, DictConfig, TaskFunction, dict[Any, Any]] | None = None


def _init_worker(sweep: tuple | bytes, parent_pid: int, slots: Any = None, n: int = 1) -> None:
    global _SWEEP
    # dies with the launching process; Ctrl-C is the launching process's: it stops us
    worker_init(parent_pid, None if isinstance(sweep, tuple) else n)  # (forked: OpenCV's threads inherited)
    if slots is not None:  # this worker's place among the n: its jobs take their houses from there
        with slots.get_lock():
            slot = slots.value % n
            slots.value += 1
        os.environ[JOB_SLOT_ENV] = f"{slot}/{n}"
    if isinstance(sweep, bytes):  # spawned: the state comes cloudpickled (the task function is
        import cloudpickle  # the app's undecorated main, which pickle cannot name; as in joblib)

        sweep = cloudpickle.loads(sweep)
        Singleton.set_state(sweep[3])  # restores Hydra's singletons; rescans the plugins (which
    setup_globals()                    # runs this module again), so the state is set after it
    _SWEEP = sweep  # forked: the parent's objects as they are
    _HEAP[:] = [0, True]


#: [jobs this worker has started, whether this process is a sweep worker (its heap kept apart)]
_HEAP: list = [0, False]


def _keep_heap_apart() -> None:
    """Before a worker's 1st, 2nd, 4th, 8th, ... job: collect, then freeze what is left (the
    modules, compiled kernels and per-process caches a worker keeps from job to job) out of the
    collector's reach. Each job's composed configs are thousands of objects in reference cycles
    that live long enough to reach the oldest generation, and each full collection they set off
    otherwise walks the whole kept heap again (measured: about a tenth of a worker's time in a
    sweep of one-house jobs). Unfrozen first: whatever died since the last time (an evicted cache
    entry in a cycle) is freed then; what a job lets go of is kept at most until the next of these
    (or the worker's end), as much as the worker held at the one before."""
    import gc

    _HEAP[0] += 1
    if _HEAP[1] and _HEAP[0] & (_HEAP[0] - 1) == 0:
        gc.unfreeze()
        gc.collect()
        gc.freeze()


#: every job this process's launchers ran, in order (status and return value or error).
LAUNCHED: list[JobReturn] = []


def _run(idx: int, overrides: Sequence[str], n_jobs: int) -> JobReturn:
    """Compose and run one job in this worker (a config that does not compose fails alone).
    ``n_jobs``: the jobs that really run at once (the job's ``hydra.launcher.n_jobs`` says so:
    fewer jobs than ``n_jobs`` run in this process)."""
    assert _SWEEP is not None
    hydra_context, config, task_function, _ = _SWEEP
    _keep_heap_apart()  # (the job before this one is garbage by now: its return was sent back)
    app_config = sys.modules.get("benchmark.config")  # the app's: each YAML config parsed once per process
    if app_config is not None:
        app_config.parse_configs_once()
    try:
        cfg = hydra_context.config_loader.load_sweep_config(config, list(overrides))
    except Exception as e:  # noqa: BLE001 - reported as this job's failure
        ret = JobReturn(overrides=list(overrides), status=JobStatus.FAILED)
        ret.return_value = _picklable(e)
        return ret
    with open_dict(cfg):
        cfg.hydra.job.id = f"{cfg.hydra.job.name}_{idx}"
        cfg.hydra.job.num = idx
        if cfg.hydra.get("launcher") is not None and "n_jobs" in cfg.hydra.launcher:
            cfg.hydra.launcher.n_jobs = n_jobs
    try:  # (run_job sets the job's config as Hydra's, then back to the one before it)
        ret = run_job(hydra_context=hydra_context, task_function=task_function, config=cfg,
                      job_dir_key="hydra.sweep.dir", job_subdir_key="hydra.sweep.subdir")
    except Exception as e:  # noqa: BLE001 - Hydra's own job set-up failed (e.g. a full disk): this job only
        ret = JobReturn(overrides=list(overrides), status=JobStatus.FAILED)
        ret.return_value = naming_the_file(e)
    if ret.status == JobStatus.FAILED:  # sent to the launching process: no traceback goes with it
        ret.return_value = _picklable(naming_the_file(ret._return_value))
    runner = sys.modules.get("benchmark.harness.runner")  # the job's houses, for the sweep's progress line
    last = dict(getattr(runner, "LAST_RUN", None) or {})
    ret.roomseg_job = {"houses": int(last.get("houses", 0)), "moved": str(last.get("moved", ""))} \
        if ret.status == JobStatus.COMPLETED else {"houses": 0, "moved": ""}
    if ret.status == JobStatus.COMPLETED:
        # the folder it wrote, and its multirun's token: that sweep's summary counts the job even
        # where another sweep into the same folder has rewritten the job's summary.json since
        sweep = sys.modules.get("benchmark.harness.sweep")
        ret.roomseg_job.update(dir=str(last.get("dir", "")),
                               sweep=(sweep.current_sweep() if sweep is not None else None) or "")
    return ret


def _run_unit(unit: Sequence[tuple[int, Sequence[str]]], n_jobs: int) -> list[tuple[int, JobReturn]]:
    """:func:`_run` of each job of ``unit`` in turn, in this worker; (index, return) each."""
    return [(i, _run(i, overrides, n_jobs)) for i, overrides in unit]


def _raise_if_pool_broken(ret: JobReturn) -> JobReturn:
    """A job run in this process whose pool of house workers lost a process ends the sweep
    (as a killed launcher worker does); any other failure is the job's own."""
    if ret.status == JobStatus.FAILED and isinstance(ret._return_value, BrokenProcessPool):
        raise ret._return_value
    return ret


def _picklable(e: Any) -> Any:
    import pickle

    try:
        pickle.dumps(e)
        return e
    except Exception:  # noqa: BLE001
        return RuntimeError(f"{type(e).__name__}: {e}")


class LocalLauncher(Launcher):
    """Runs a sweep's jobs on ``n_jobs`` local worker processes (forked on Linux).

    Args:
        n_jobs: worker processes (1: run the jobs in the launching process; ``auto``: see the
            module docstring).
        start_method: ``fork`` | ``spawn`` | ``forkserver``; None: ``fork`` on Linux, else ``spawn``.
    """

    def __init__(self, n_jobs: int | str = "auto", start_method: str | None = None) -> None:
        try:
            self.n_jobs: int | None = None if n_jobs == "auto" else int(n_jobs)
        except (TypeError, ValueError):
            self.n_jobs = 0
        if self.n_jobs is not None and self.n_jobs < 1:
            raise ValueError(f"hydra.launcher.n_jobs must be an integer >= 1 or auto, got {n_jobs!r}")
        methods = multiprocessing.get_all_start_methods()
        if start_method is not None and start_method not in methods:
            raise ValueError(f"hydra.launcher.start_method must be one of {methods}, got {start_method!r}")
        self.start_method = start_method or ("fork" if sys.platform == "linux" and "fork" in methods else "spawn")
        self.config: DictConfig | None = None
        self.task_function: TaskFunction | None = None
        self.hydra_context: HydraContext | None = None

    def setup(self, *, hydra_context: HydraContext, task_function: TaskFunction, config: DictConfig) -> None:
        self.config, self.hydra_context, self.task_function = config, hydra_context, task_function

    def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> Sequence[JobReturn]:
        """Run the jobs; their returns are also kept in :data:`LAUNCHED` (the launching process
        reads them to tell "some jobs finished" from "nothing ran" when a job failed)."""
        returns = self._launch(job_overrides, initial_job_idx)
        # the module object in sys.modules (Hydra's plugin scan may have loaded this file as another)
        importlib.import_module(__name__).LAUNCHED.extend(returns)
        return returns

    def _launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> Sequence[JobReturn]:
        global _SWEEP
        setup_globals()
        assert self.config is not None and self.hydra_context is not None and self.task_function is not None
        configure_log(self.config.hydra.hydra_logging, self.config.hydra.verbose)
        sweep_dir = Path(str(self.config.hydra.sweep.dir))
        sweep_dir.mkdir(parents=True, exist_ok=True)
        wanted = self.n_jobs if self.n_jobs is not None else auto_jobs(len(job_overrides), available_cores())
        n = min(wanted, len(job_overrides))
        how = "one after another in this process" if n <= 1 else f"on {n} {self.start_method} worker(s)"
        # the job list goes to the sweep's log file (each job's own lines go to its <job>/bench.log)
        listing = sweep_dir / "sweep.log"
        with open(listing, "a", encoding="utf-8") as f:
            f.write(f"[{time.strftime('%Y-%m-%d %H:%M:%S')}] Launching {len(job_overrides)} jobs {how}, "
                    f"sweep output dir: {sweep_dir}\n")
            for i, overrides in enumerate(job_overrides):
                f.write(f"\t#{initial_job_idx + i} : {' '.join(filter_overrides(overrides))}\n")
        log.info(f"Launching {len(job_overrides)} jobs {how} -> {sweep_dir} (jobs: {listing.name}; "
                 f"each job's log, all its warnings included: <job>/bench.log; a warning repeated by later "
                 f"houses or jobs shows here once per worker)")
        _SWEEP = (self.hydra_context, self.config, self.task_function, Singleton.get_state())
        jobs = [(initial_job_idx + i, list(o)) for i, o in enumerate(job_overrides)]
        progress = SweepProgress(len(jobs))
        moved: list[str] = []

        def done(ret: JobReturn) -> JobReturn:
            info = getattr(ret, "roomseg_job", None) or {}
            if info.get("moved"):
                moved.append(info["moved"])
            progress.update(info.get("houses", 0), ret.status != JobStatus.COMPLETED)
            return ret

        try:
            return self._run_all(jobs, n, sweep_dir, done)
        finally:
            progress.close()
            if moved:  # one line for every job that wrote beside a folder holding another run's results
                print(f"note: {len(moved)} of {len(jobs)} job(s) wrote to a <folder>~<key> sibling: their folders "
                      f"hold another run's results, e.g. {moved[0]}", file=sys.stderr, flush=True)

    def _run_all(self, jobs: list[tuple[int, list[str]]], n: int, sweep_dir: Path, done) -> list[JobReturn]:
        """Run ``jobs`` in this process (``n`` <= 1) or on ``n`` worker processes; ``done`` is
        called with each job's return as it finishes."""
        if n <= 1:
            try:
                return [done(_raise_if_pool_broken(_run(i, o, 1))) for i, o in jobs]
            finally:
                configure_log(self.config.hydra.hydra_logging, self.config.hydra.verbose)
        ctx = multiprocessing.get_context(self.start_method)
        # Hydra's plugin scan may load this file under a module object other than the one
        # in sys.modules, which is where a worker finds the functions it is sent: use that one
        mod = importlib.import_module(__name__)
        state: tuple | bytes = _SWEEP
        if self.start_method != "fork":
            import cloudpickle

            state = cloudpickle.dumps(_SWEEP)
        slots = ctx.Value("i", 0)
        if self.start_method == "fork":  # the workers inherit OpenCV's threads: their share of the cores
            share_threads(n)
        pool = ProcessPoolExecutor(n, mp_context=ctx, initializer=mod._init_worker,
                                   initargs=(state, os.getpid(), slots, n))
        # jobs that differ only in the sweeper's same_worker keys go to one worker, one after another
        keys = (self.config.hydra.get("sweeper") or {}).get("same_worker") or ()
        try:
            futures = [pool.submit(mod._run_unit, unit, n) for unit in units(jobs, list(keys))]
            returns: dict[int, JobReturn] = {}
            for f in as_completed(futures):  # the progress line advances as jobs finish, in any order
                for i, ret in f.result():
                    returns[i] = done(ret)
            return [returns[i] for i, _ in jobs]
        except BrokenProcessPool:
            _stop(pool)
            raise BrokenProcessPool(f"a worker process of the sweep in {sweep_dir} died (killed, or out "
                                    f"of memory?); finished jobs are kept, rerun to complete the rest") from None
        except BaseException:  # Ctrl-C (or any error here): no job starts, running ones stop now
            _stop(pool)
            raise
        finally:
            pool.shutdown(wait=True)


def _stop(pool: ProcessPoolExecutor) -> None:
    """Cancel the jobs not started and terminate the workers (their files are written
    atomically and their locks die with them, so an interrupted job leaves nothing half-done)."""
    procs = list((getattr(pool, "_processes", None) or {}).values())  # (shutdown forgets them)
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        if p.is_alive():
            p.terminate()
    for p in procs:
        p.join(timeout=10)
