"""Map a job's houses to rows: one interface, three executors.

Every executor runs the same unit of work, :func:`run_house` (``Pipeline.run_house(house_id)``
timed, with the house's cache content and whether its row was served from the cache), and
returns one :class:`HouseResult` per house **in house order**, whatever order the houses
finished in, so that a job's ``metrics.csv`` is the same bytes with one worker or many:

- :class:`SerialExecutor`: in this process, on the driver's own pipeline (``run.workers=1``);
- :class:`LocalPool`: on ``run.workers`` local processes (forked on Linux, else spawned). One
  pool serves every job of a process (:func:`local_pool`): the jobs of a multirun run one
  after another in the launching process and share it;
- :class:`RayExecutor`: as Ray tasks (``run.executor=ray``) on the cluster at
  ``run.ray.address``, or on a local Ray instance.

A worker builds a job's pipeline from its :class:`JobSpec` (the job's resolved plain config
and chosen options, see :func:`benchmark.harness.runner.pipeline_from_plain`) the first time
it gets one of the job's houses and keeps it, keyed by the spec's key, for the job's next
houses (:func:`pipeline_for`). The spec reaches a local worker through a file in a private
temporary folder (written once per job, read once per worker) and a Ray worker through
Ray's object store, so that a task carries only the job's key and one house id.

Pool workers die with the driver (:mod:`benchmark.harness.processes`), ignore Ctrl-C (the
driver stops them at once) and send their log records to the driver, which handles them
with its current handlers (the job's log file, the console). A worker that dies (kill -9,
out of memory) ends the job with :class:`WorkerDied`, one line naming it; the houses scored
before are cached, so the same command goes on from there.
"""

from __future__ import annotations

import atexit
import contextlib
import logging
import logging.handlers
import multiprocessing
import os
import pickle
import shutil
import signal
import socket
import sys
import tempfile
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from benchmark.harness.cache import EntryBusy, defer_when_busy
from benchmark.harness.processes import available_cores, share_threads, staggered, worker_init
from envs.atomic import file_identity

log = logging.getLogger("roomseg-bench")

#: a progress wrapper (:func:`benchmark.harness.progress.house_progress`): iterable, total -> iterable.
Progress = Callable[..., Iterable[Any]]


class WorkerDied(BrokenProcessPool):
    """A worker process (local) or a task's worker (Ray) died: the job ends, one line naming it.
    A :class:`BrokenProcessPool`, so the launcher and ``roomseg-bench`` treat it as a killed
    sweep worker (exit status 1)."""


@dataclass(frozen=True)
class JobSpec:
    """What a worker needs to run a job's houses.

    Args:
        key: names the job's pipeline in the workers (a hash of everything ``build`` uses).
        build: zero-argument, picklable callable that returns the job's pipeline (a
            ``functools.partial`` of a module-level function).
        cwd: the driver's working directory: relative paths in the config are relative to it
            (local workers inherit it; a Ray worker changes to it where it exists).
    """

    key: str
    build: Callable[[], Any]
    cwd: str = ""


@dataclass
class HouseResult:
    """One house, as a worker ran it.

    Attributes:
        row: the metrics row (``Pipeline.run_house``).
        content: the content hash of the house's score entry ("" for an unreadable house).
        cached: True when the row was served from the cache (its score entry, or its logged
            failure with ``run.cache_failures``, existed and was left untouched).
        seconds: wall time of the house in its worker, cache look-up included.
        worker: ``host:pid`` of the process that ran it.
        built: the stages that worker's pipeline has built so far.
    """

    row: dict[str, Any]
    content: str
    cached: bool
    seconds: float
    worker: str
    built: tuple[str, ...]


class Executor(Protocol):
    """Maps a job's houses to :class:`HouseResult`, in house order."""

    name: str

    def map(self, spec: JobSpec, house_ids: Sequence[str], progress: Progress | None = None,
            where: str = "") -> list[HouseResult]:
        """Run ``house_ids``; ``progress`` wraps the stream of finished houses; ``where`` names
        the job in messages (its folder).

        Raises:
            StageError: a stage cannot be built (from the first house that needed it).
            WorkerDied: a worker died.
            KeyboardInterrupt: Ctrl-C (every worker is stopped first).
        """
        ...


# ---------------------------------------------------------------- the unit of work
def _stamp(path_of: Callable[[str], Path], hid: str) -> tuple[int, int, int] | None:
    try:
        path = path_of(hid)
    except Exception:  # noqa: BLE001 - an unreadable house (no path)
        return None
    return file_identity(path)


def run_house(pipe: Any, hid: str) -> HouseResult:
    """House ``hid`` on ``pipe``: its row, timed, with its content hash and whether the row was
    served from the cache (its entry existed before and is unchanged after: writes are atomic
    renames, so a recomputed entry is a new file)."""
    force = getattr(pipe, "force", set()) or set()
    use_failures = bool(getattr(pipe, "cache_failures", False))
    score, failure = (lambda h: pipe.entry("score", h)), (lambda h: pipe.entry("failure", h))
    before = (_stamp(score, hid), _stamp(failure, hid) if use_failures else None)
    t = time.perf_counter()
    row = pipe.run_house(hid)
    seconds = time.perf_counter() - t
    after = (_stamp(score, hid), _stamp(failure, hid) if use_failures else None)
    which = 0 if row.get("status") == "ok" else 1
    cached = "score" not in force and before[which] is not None and before[which] == after[which]
    try:
        content = pipe.contents(hid)["score"]
    except Exception:  # noqa: BLE001 - an unreadable house has no cache entries
        content = ""
    return HouseResult(row=row, content=content, cached=cached, seconds=seconds,
                       worker=f"{socket.gethostname()}:{os.getpid()}", built=tuple(pipe.built()))


#: pipelines built in this (worker) process, by job key: a job's houses share one.
_PIPELINES: OrderedDict[str, Any] = OrderedDict()
#: pipelines kept per process (a sweep's jobs come one after another).
KEEP_PIPELINES = 2


def pipeline_for(key: str, load_spec: Callable[[], JobSpec]) -> Any:
    """This process's pipeline of job ``key``, built from ``load_spec()`` the first time."""
    if key in _PIPELINES:
        _PIPELINES.move_to_end(key)
        return _PIPELINES[key]
    spec = load_spec()
    if spec.cwd and os.path.isdir(spec.cwd) and os.getcwd() != spec.cwd:
        os.chdir(spec.cwd)
    pipe = spec.build()
    _PIPELINES[key] = pipe
    while len(_PIPELINES) > KEEP_PIPELINES:
        _PIPELINES.popitem(last=False)
    return pipe


# ---------------------------------------------------------------- in this process
class SerialExecutor:
    """The houses one after another in this process, on the driver's pipeline ``pipe``."""

    name = "serial"

    def __init__(self, pipe: Any) -> None:
        self.pipe = pipe
        self.workers = 1

    def map(self, spec: JobSpec, house_ids: Sequence[str], progress: Progress | None = None,
            where: str = "") -> list[HouseResult]:
        """The results in the order of ``house_ids``. The houses are run in the order of
        :func:`benchmark.harness.processes.staggered` (a job running beside others of a sweep
        starts at its own share of the houses); a house that needs an entry another process is
        computing (its lock is held: :class:`benchmark.harness.cache.EntryBusy`) is put off,
        and run, waiting for the entry if need be, after the others."""
        out: list[HouseResult | None] = [None] * len(house_ids)

        def run() -> Iterator[str]:
            order, later = staggered(len(house_ids)), []
            for k, i in enumerate(order):
                try:
                    with defer_when_busy(k < len(order) - 1):  # other houses to run meanwhile
                        out[i] = run_house(self.pipe, house_ids[i])
                except EntryBusy:
                    later.append(i)
                    continue
                yield house_ids[i]
            for i in later:
                out[i] = run_house(self.pipe, house_ids[i])
                yield house_ids[i]

        for _ in progress(run(), total=len(house_ids)) if progress else run():
            pass
        return out  # type: ignore[return-value]


# ---------------------------------------------------------------- local processes
def _forward_logs(queue: Any) -> None:
    """In a worker: send every log record to the driver (instead of the handlers it inherited,
    which name the job that was running when the pool started)."""
    root = logging.getLogger()
    for h in list(root.handlers):
        root.removeHandler(h)
    root.addHandler(logging.handlers.QueueHandler(queue))


def _pool_init(parent_pid: int, queue: Any, workers: int | None = None) -> None:
    worker_init(parent_pid, workers)
    _forward_logs(queue)


def _pool_task(key: str, spec_path: str, hid: str) -> HouseResult:
    def load() -> JobSpec:
        with open(spec_path, "rb") as f:
            return pickle.load(f)

    return run_house(pipeline_for(key, load), hid)


def _exit_reason(code: int | None) -> str:
    if code is None:
        return "still running"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


def _spec_dir() -> Path:
    """A private folder for a pool's job specs: ``<tmp>/.roomseg-pool.tmp-<pid>-*``. The
    folders of pools whose process is gone (killed: no chance to remove its own) go first."""
    from envs.atomic import clean_leftovers, leftover_prefix

    base = Path(tempfile.gettempdir()) / "roomseg-pool"
    clean_leftovers(base)
    return Path(tempfile.mkdtemp(prefix=leftover_prefix(base, "tmp"), dir=base.parent))


class LocalPool:
    """``workers`` local processes that run the houses of any number of jobs.

    Args:
        workers: processes (>= 1).
        start_method: ``fork`` | ``spawn`` | ``forkserver``; None: ``fork`` on Linux, else ``spawn``.
    """

    name = "local"

    def __init__(self, workers: int, start_method: str | None = None) -> None:
        if workers < 1:
            raise ValueError(f"run.workers={workers!r}: expected an integer >= 1")
        self.workers = int(workers)
        methods = multiprocessing.get_all_start_methods()
        self.start_method = start_method or ("fork" if sys.platform.startswith("linux") and "fork" in methods
                                             else "spawn")
        self._ctx = multiprocessing.get_context(self.start_method)
        self._dir = _spec_dir()
        self._specs: set[str] = set()
        self._logs = self._ctx.Queue()
        self._listener: threading.Thread | None = None
        forked = self.start_method == "fork"
        if forked:  # the workers inherit OpenCV's threads: their share of the cores
            share_threads(self.workers)
        self._pool: ProcessPoolExecutor | None = ProcessPoolExecutor(
            self.workers, mp_context=self._ctx, initializer=_pool_init,
            initargs=(os.getpid(), self._logs, None if forked else self.workers))
        self._procs: list[Any] = []

    @property
    def closed(self) -> bool:
        return self._pool is None

    def pids(self) -> list[int]:
        """The worker processes' pids (empty before the first job)."""
        return [p.pid for p in self._procs]

    def _publish(self, spec: JobSpec) -> str:
        from envs.atomic import atomic_write_bytes

        path = self._dir / f"{spec.key}.pkl"
        if spec.key not in self._specs:
            atomic_write_bytes(path, pickle.dumps(spec, protocol=pickle.HIGHEST_PROTOCOL))
            self._specs.add(spec.key)
        return str(path)

    def _listen(self) -> None:
        """Handle the workers' log records here (started once the workers exist: no thread is
        running in this process when it forks them)."""
        if self._listener is not None:
            return
        queue = self._logs

        def loop() -> None:
            while True:
                try:
                    record = queue.get()
                except (EOFError, OSError, ValueError):
                    return
                if record is None:
                    return
                logging.getLogger(record.name).handle(record)

        self._listener = threading.Thread(target=loop, name="pool-logs", daemon=True)
        self._listener.start()

    def map(self, spec: JobSpec, house_ids: Sequence[str], progress: Progress | None = None,
            where: str = "") -> list[HouseResult]:
        if self._pool is None:
            raise RuntimeError("the pool is closed")
        futures: list[Future] = []
        try:  # (from the first submission on: a Ctrl-C while the pool starts its workers stops them too)
            path = self._publish(spec)
            for h in house_ids:
                futures.append(self._pool.submit(_pool_task, spec.key, path, h))
            if not self._procs:
                self._procs = list((getattr(self._pool, "_processes", None) or {}).values())
                self._listen()
            index = {f: i for i, f in enumerate(futures)}
            out: list[HouseResult | None] = [None] * len(futures)
            done: Iterable[Future] = as_completed(futures)
            if progress:
                done = progress(done, total=len(futures))
            for f in done:
                out[index[f]] = f.result()
        except BrokenProcessPool:
            self.close(now=True)  # (joins every worker: their exit codes are known after it)
            ended = [p for p in self._procs if p.exitcode is not None]
            # the pool terminates the others (SIGTERM) once one is gone: name the ones it did not
            first = [p for p in ended if p.exitcode != -signal.SIGTERM] or ended
            dead = [f"pid {p.pid}, {_exit_reason(p.exitcode)}" for p in first]
            raise WorkerDied(f"a worker process ({'; '.join(dead) or 'pid unknown'}) of the job in {where or '?'} "
                             f"died (killed, or out of memory?); the houses already scored are cached, so the "
                             f"same command goes on from there") from None
        except Exception:  # a stage error (or a bug) in a house: the job stops, the pool serves the next
            for f in futures:
                f.cancel()
            wait(futures)  # (the running ones finish; their rows are cached)
            raise
        except BaseException:  # Ctrl-C: every worker stops now
            self.close(now=True)
            raise
        return out  # type: ignore[return-value]

    def close(self, now: bool = False) -> None:
        """Stop the workers: ``now`` terminates them (their writes are atomic, their locks die
        with them); otherwise they finish and exit. Removes the folder of job specs."""
        pool, self._pool = self._pool, None
        if pool is not None:
            procs = self._procs or list((getattr(pool, "_processes", None) or {}).values())
            if now:
                pool.shutdown(wait=False, cancel_futures=True)
                for p in procs:
                    with contextlib.suppress(Exception):
                        if p.is_alive():
                            p.terminate()
                for p in procs:
                    with contextlib.suppress(Exception):
                        p.join(timeout=10)
            else:
                pool.shutdown(wait=True)
            with contextlib.suppress(Exception):
                self._logs.put(None)
            if self._listener is not None:
                self._listener.join(timeout=2)
        shutil.rmtree(self._dir, ignore_errors=True)


#: the process's pool (:func:`local_pool`).
_POOL: LocalPool | None = None


def local_pool(workers: int) -> LocalPool:
    """This process's pool of ``workers`` processes, created on first use and shared by the jobs
    that follow (a multirun's); a request for another size replaces it."""
    global _POOL
    if _POOL is not None and (_POOL.closed or _POOL.workers != workers):
        _POOL.close()
        _POOL = None
    if _POOL is None:
        _POOL = LocalPool(workers)
    return _POOL


def close_pool(now: bool = False) -> None:
    """Close this process's workers, if any (the end of a single run, or of the process): its
    pool, and the local Ray instance it started (:func:`close_ray`)."""
    global _POOL
    pool, _POOL = _POOL, None
    try:
        if pool is not None:
            pool.close(now=now)
    finally:
        close_ray()


atexit.register(close_pool)


# ---------------------------------------------------------------- Ray
def import_ray():
    """``ray``, or one line saying how to install it.

    Raises:
        ConfigError: Ray is not installed (one line naming the extra)."""
    from benchmark.harness.checks import ConfigError  # noqa: PLC0415

    try:
        import ray  # noqa: PLC0415
    except ImportError:
        raise ConfigError("run.executor=ray needs Ray, which is not installed: pip install -e '.[cluster]' "
                          "(or pip install ray)") from None
    return ray


#: seconds to reach a Ray cluster when ``run.ray.connect_timeout`` is not set.
CONNECT_TIMEOUT_S = 30.0


def unreachable(address: str, timeout: float) -> str | None:
    """Why the head at ``address`` (``host:port`` or ``ray://host:port``) cannot be reached
    with TCP within ``timeout`` seconds (an unknown host, a refused port, no answer), or None."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout):
            return None
    except socket.gaierror:
        return f"unknown host {host!r}"
    except TimeoutError:
        return f"no answer within {timeout:g} s"
    except (OSError, ValueError) as e:
        return getattr(e, "strerror", None) or str(e)


#: ``{"pid": ...}``: the process that started a local Ray instance (:func:`_start_local`); empty when none runs.
_LOCAL_RAY: dict[str, int] = {}


def _start_local(ray, kwargs: dict[str, Any]) -> None:
    """Start a local Ray instance (``ray.init(address="local", ...)``) in this thread.

    Ray starts its GCS server and raylet with a parent-death signal (``PR_SET_PDEATHSIG``),
    which Linux sends when the *thread* that started them exits: started from a thread that then
    ends (as a cluster's address is reached: :meth:`RayExecutor._init`), they die at once, the
    driver exits with status 1 and no line, and the raylet's dashboard and runtime-env agents
    stay behind under PID 1. So the instance is started in the calling thread (the run's), and
    :func:`close_ray` stops it at the end of a single run, or when the process ends: at exit, and
    in a launcher's worker process (which ends without running ``atexit``) by a multiprocessing
    finalizer.

    Raises:
        ConfigError: Ray could not start (one line with Ray's reason)."""
    from benchmark.harness.checks import ConfigError  # noqa: PLC0415

    try:
        ray.init(**kwargs)
    except (ConnectionError, RuntimeError, ValueError, TimeoutError) as e:
        raise ConfigError(f"run.executor=ray: cannot start a local Ray instance "
                          f"({' '.join(str(e).split())[:200]})") from None
    _LOCAL_RAY["pid"] = os.getpid()
    from multiprocessing import util  # noqa: PLC0415

    util.Finalize(None, close_ray, exitpriority=10)  # (run at the end of a multiprocessing child too)


def close_ray() -> None:
    """Stop the local Ray instance this process started (:func:`_start_local`), with every
    process of it (``ray.shutdown``: workers, raylet, agents, GCS server); a cluster this process
    only connected to is left running, and so is an instance a forked child inherited the
    record of."""
    if _LOCAL_RAY.pop("pid", None) != os.getpid():
        return
    import ray  # noqa: PLC0415

    if ray.is_initialized():
        ray.shutdown()


def _ray_task(key: str, box: list, hid: str) -> HouseResult:
    """A Ray task: ``box`` holds the ObjectRef of the job's spec, fetched only by a worker that
    has not built the job's pipeline yet. The task holds one CPU, so OpenCV gets one thread, a
    core's share when every core runs a task (:func:`benchmark.harness.processes.share_threads`)."""
    def load() -> JobSpec:
        import ray  # noqa: PLC0415

        return ray.get(box[0])

    share_threads(available_cores())
    return run_house(pipeline_for(key, load), hid)


class RayExecutor:
    """Houses as Ray tasks (one CPU each) on the cluster at ``address``.

    Args:
        address: ``host:port`` of a running cluster's head, ``auto`` (the cluster this machine
            belongs to, from ``ray start``), or None: a local Ray instance with ``workers`` CPUs
            (the one this process already has, if any).
        workers: CPUs of a local instance (ignored when connecting to a cluster).
    """

    name = "ray"

    def __init__(self, address: str | None = None, workers: int | None = None,
                 connect_timeout: float = CONNECT_TIMEOUT_S) -> None:
        self.address = address
        self.workers = workers
        self.connect_timeout = float(connect_timeout)
        self._remote = None

    def connect(self):
        """Ray, connected (once per process).

        A cluster's address is first reached with TCP, then ``ray.init`` gets what is left of
        ``connect_timeout`` seconds (Ray itself retries for many minutes). Without an address,
        a local instance is started in this thread (:func:`_start_local`) and stopped by
        :func:`close_ray`.

        Raises:
            ConfigError: Ray is not installed, or the cluster cannot be reached in time (one line)."""
        from benchmark.harness.checks import ConfigError  # noqa: PLC0415

        ray = import_ray()
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {"address": self.address, "logging_level": logging.WARNING}
            if self.address is None:
                kwargs.update(address="local", num_cpus=self.workers, include_dashboard=False)
            where = f"run.ray.address={self.address}: cannot connect to Ray"
            if self.address is None:
                _start_local(ray, kwargs)
            else:
                t0 = time.monotonic()
                if self.address != "auto":
                    why = unreachable(self.address, self.connect_timeout)
                    if why:
                        raise ConfigError(f"{where} ({why}; run.ray.connect_timeout={self.connect_timeout:g})")
                self._init(ray, kwargs, max(self.connect_timeout - (time.monotonic() - t0), 1.0), where)
        if self._remote is None:
            self._remote = ray.remote(num_cpus=1)(_ray_task)
        return ray

    def _init(self, ray, kwargs: dict[str, Any], timeout: float, where: str) -> None:
        """``ray.init(**kwargs)`` of a cluster's address in a daemon thread, waited for ``timeout``
        seconds. Only to connect: a local instance started in a thread that ends would end with it
        (its processes are started with a parent-death signal, which Linux sends when the
        starting thread exits: :func:`_start_local`)."""
        from benchmark.harness.checks import ConfigError  # noqa: PLC0415

        box: list[BaseException | None] = []

        def go() -> None:
            try:
                ray.init(**kwargs)
                box.append(None)
            except BaseException as e:  # noqa: BLE001 - reported in the calling thread
                box.append(e)

        quiet = _DropNotMainThread()
        logging.getLogger("ray").addFilter(quiet)
        for h in logging.getLogger("ray").handlers:
            h.addFilter(quiet)
        try:
            t = threading.Thread(target=go, name="ray-init", daemon=True)
            t.start()
            t.join(timeout)
        finally:
            logging.getLogger("ray").removeFilter(quiet)
            for h in logging.getLogger("ray").handlers:
                h.removeFilter(quiet)
        if not box:
            raise ConfigError(f"{where} (no answer from Ray within {self.connect_timeout:g} s; "
                              f"run.ray.connect_timeout)")
        if box[0] is not None:
            e = box[0]
            if isinstance(e, (ConnectionError, RuntimeError, ValueError, TimeoutError)):
                raise ConfigError(f"{where} ({' '.join(str(e).split())[:200]})") from None
            raise e

    def map(self, spec: JobSpec, house_ids: Sequence[str], progress: Progress | None = None,
            where: str = "") -> list[HouseResult]:
        ray = self.connect()
        from benchmark.harness.pipeline import StageError  # noqa: PLC0415

        box = [ray.put(spec)]
        refs = [self._remote.remote(spec.key, box, h) for h in house_ids]
        index = {r: i for i, r in enumerate(refs)}
        out: list[HouseResult | None] = [None] * len(refs)
        done: Iterable[Any] = _ray_completed(ray, refs)
        if progress:
            done = progress(done, total=len(refs))
        try:
            for r in done:
                i = index[r]
                try:
                    out[i] = ray.get(r)
                except ray.exceptions.RayTaskError as e:
                    cause = getattr(e, "cause", None)
                    if isinstance(cause, StageError):
                        raise StageError(str(cause)) from None
                    raise
                except (ray.exceptions.WorkerCrashedError, ray.exceptions.NodeDiedError,
                        ray.exceptions.ObjectLostError) as e:
                    raise WorkerDied(f"the Ray worker of house {house_ids[i]!r} of the job in {where or '?'} died "
                                     f"({type(e).__name__}, after Ray's retries); the houses already scored are "
                                     f"cached, so the same command goes on from there") from None
        except BaseException:
            for r in refs:
                with contextlib.suppress(Exception):
                    ray.cancel(r, force=True)
            raise
        return out  # type: ignore[return-value]


class _DropNotMainThread(logging.Filter):
    """Ray's warning that ``ray.init`` outside the main thread sets no SIGTERM handler (this
    process keeps its own)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "not the main thread" not in record.getMessage()


def _ray_completed(ray, refs: list) -> Iterator[Any]:
    """``refs`` as their tasks finish (one ``ray.wait`` over all pending refs per round)."""
    pending = list(refs)
    while pending:
        ready, pending = ray.wait(pending, num_returns=len(pending), timeout=0.2)
        yield from ready


__all__ = ["Executor", "HouseResult", "JobSpec", "LocalPool", "RayExecutor", "SerialExecutor", "WorkerDied",
           "close_pool", "close_ray", "import_ray", "local_pool", "pipeline_for", "run_house"]
