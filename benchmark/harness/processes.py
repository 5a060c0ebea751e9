"""Worker processes: how many cores this process may use (:func:`available_cores`),
workers that die with their parent (:func:`die_with_parent`), and independent tasks run on
forked ones (:func:`run_forked`). Standard library only: the
Hydra launcher (``hydra_plugins/roomseg_sweep``, which Hydra imports whenever an app starts)
uses it too.

A worker of a process pool that outlives its parent (``kill -9`` of the parent, an
out-of-memory kill) blocks for ever on the pool's pipe, holding its memory. Call
:func:`die_with_parent` first thing in the worker (the pool's initializer):

- on Linux, ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` asks the kernel to kill the worker when
  its parent dies. The kernel sends it when the *thread* that forked the worker ends, so
  create pools from a thread that lives as long as the pool (the main thread here);
- elsewhere (or where ``prctl`` fails) a daemon thread polls ``os.getppid()`` every
  ``poll_s`` seconds and ends the process when the parent has changed (the worker was
  re-parented, so its parent is gone).

Either way a parent that died before the call is noticed at once (its pid is given).

External programs (ROSE²'s driver) run under :mod:`benchmark.guarded` instead.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import sys
import threading

#: ``PR_SET_PDEATHSIG`` from ``<linux/prctl.h>``.
PR_SET_PDEATHSIG = 1


def available_cores() -> int:
    """The cores this process may run on (``os.sched_getaffinity``; the CPU count elsewhere)."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except (AttributeError, OSError):
        return max(os.cpu_count() or 1, 1)


#: the least memory a worker process is counted as needing (bytes) when capping ``run.workers``.
MIN_WORKER_BYTES = 256 * 2**20


def available_memory() -> int | None:
    """Bytes of memory available for new work (``MemAvailable`` of ``/proc/meminfo``), or None
    where unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def resident_bytes() -> int:
    """This process's resident memory in bytes (0 where unknown)."""
    try:
        with open("/proc/self/statm", encoding="ascii") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


def worker_cap(requested: int | None) -> tuple[int, str | None]:
    """How many worker processes to start for ``requested`` (None: as many as the cores).

    At most the cores this process may use (:func:`available_cores`: more processes than cores
    only take turns, each holding its memory), and at most what the available memory holds at
    ``max(this process's resident memory, MIN_WORKER_BYTES)`` a worker (a forked worker
    starts as a copy of this process; a simplified estimate: a worker's peak is not known in
    advance).

    Returns:
        (the workers, one line saying why fewer than requested, or None).
    """
    cores = available_cores()
    want = cores if requested is None else int(requested)
    got, why = want, None
    if want > cores:
        got, why = cores, f"the {cores} core(s) this process may use"
    mem = available_memory()
    per = max(resident_bytes(), MIN_WORKER_BYTES)
    if mem is not None and got > max(mem // per, 1):
        got = max(mem // per, 1)
        why = f"what the available memory holds ({mem / 2**30:.1f} GiB, about {per / 2**30:.2f} GiB a worker)"
    if got >= want:
        return want, None
    asked = f"run.workers={requested}" if requested is not None else "run.workers (the cores)"
    return got, f"{asked}: capped at {got} worker process(es), {why}"


def _prctl_pdeathsig(sig: int) -> bool:
    """``prctl(PR_SET_PDEATHSIG, sig)``; False where unavailable or refused."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        return libc.prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _watch(parent_pid: int, poll_s: float) -> None:
    def loop() -> None:
        event = threading.Event()
        while not event.wait(poll_s):
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=loop, name="die-with-parent", daemon=True).start()


def die_with_parent(parent_pid: int, *, use_prctl: bool = True, poll_s: float = 0.5) -> str:
    """End this process when its parent ``parent_pid`` dies.

    Args:
        parent_pid: the parent's pid as the parent saw it (``os.getpid()`` there, passed to
            the pool's initializer), so that a parent already dead is noticed.
        use_prctl: False forces the polling fallback (tests).
        poll_s: seconds between two looks at ``os.getppid()`` in the fallback.

    Returns:
        ``"prctl"`` or ``"watch"``: how the death will be noticed.
    """
    how = "prctl" if use_prctl and _prctl_pdeathsig(signal.SIGKILL) else "watch"
    if how == "watch":
        _watch(parent_pid, poll_s)
    if os.getppid() != parent_pid:  # the parent died before the kernel or the thread could see it
        os._exit(1)
    return how


#: set in each worker of a sweep's launcher to ``"<slot>/<workers>"``: which of the jobs that run
#: at once this process runs (:func:`job_slot`).
JOB_SLOT_ENV = "ROOMSEG_JOB_SLOT"


def job_slot() -> tuple[int, int]:
    """(slot, workers): this launcher worker's place among the sweep's jobs that run side by side
    (``$ROOMSEG_JOB_SLOT``), (0, 1) outside such a worker or when the variable is malformed."""
    try:
        slot, n = (int(v) for v in os.environ.get(JOB_SLOT_ENV, "").split("/"))
    except ValueError:
        return 0, 1
    return (slot, n) if 0 <= slot < n else (0, 1)


def staggered(n_items: int) -> list[int]:
    """The order in which this process takes ``n_items`` houses of a job: from its share's start
    (slot / workers of the way through, :func:`job_slot`) round to the one before, so that
    jobs running side by side (other methods under the same robot condition) start on different
    houses: the stages they share for a house (its robot map, its SLAM estimate, its render) are
    computed by one of them while the others compute other houses, and found in the cache when
    they get there, instead of one job waiting on the other's lock house after house. Outside a
    sweep's side-by-side jobs: 0, 1, 2, ..."""
    slot, n = job_slot()
    start = slot * n_items // n
    return [(start + i) % n_items for i in range(n_items)] if n_items else []


def share_threads(workers: int) -> int:
    """Give OpenCV's thread pool its share of the cores: ``available_cores() // workers`` threads
    (at least 1) for each of ``workers`` processes that run side by side, as Ray and Dask give
    their workers' OpenMP. Left as it is, each worker's OpenCV keeps a thread per core, and
    between calls they spin (``sched_yield``) on the cores the other workers need.

    Called in a process that forks the workers before it forks them (they inherit the setting),
    or first thing in a started one: never in a forked child, where OpenCV's pool still counts
    the parent's threads and setting it waits for them for ever. OpenCV is not imported here (the
    sweep launcher imports this module, and stays light): its ``OPENCV_FOR_THREADS_NUM`` is set,
    which OpenCV reads when it first needs its threads and a started child inherits, and an
    OpenCV this process has loaded is set too (``cv2.setNumThreads``).

    Returns:
        The number of threads OpenCV now uses.
    """
    n = max(1, available_cores() // max(1, int(workers)))
    os.environ[OPENCV_THREADS_ENV] = str(n)
    cv2 = sys.modules.get("cv2")
    if cv2 is not None and hasattr(cv2, "setNumThreads"):
        cv2.setNumThreads(n)
    return n


#: OpenCV's thread count, read when it first needs its threads (:func:`share_threads`).
OPENCV_THREADS_ENV = "OPENCV_FOR_THREADS_NUM"


def worker_init(parent_pid: int, workers: int | None = None) -> None:
    """A pool initializer: die with the parent, and leave Ctrl-C to the parent, which stops the
    workers itself (SIGINT goes to the whole foreground process group); a started (not forked)
    worker of a pool of ``workers`` takes its share of the cores (:func:`share_threads`; a forked
    one inherits it from the parent)."""
    die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if workers is not None:
        share_threads(workers)


#: the tasks of the :func:`run_forked` call under way, for its forked workers (which inherit
#: them: nothing is pickled but each task's index and result).
_TASKS: list = []


def _run_task(i: int):
    return _TASKS[i]()


def forked_workers() -> int:
    """Processes :func:`run_forked` uses by default: ``ROOMSEG_JOBS`` if set, else the cores this
    process may run on."""
    return int(os.environ.get("ROOMSEG_JOBS") or available_cores())


def run_forked(tasks: list, workers: int | None = None) -> list:
    """Each task's result (``tasks``: callables without arguments), in order, the tasks run on
    ``workers`` forked processes where the platform forks (Linux), else one after the other
    here. Each process dies with this one (``kill -9`` here leaves none blocked on a pipe).

    Args:
        tasks: the callables; their results must pickle.
        workers: processes (None: ``ROOMSEG_JOBS`` if set, else the cores this process may run
            on, :func:`available_cores`); at most one per task.

    Raises:
        The first failed task's exception (in task order); on it, or Ctrl-C, the tasks not
        started are not run.
    """
    global _TASKS
    import gc
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    n = workers if workers is not None else forked_workers()
    n = max(1, min(n, len(tasks)))
    if n == 1 or sys.platform != "linux":
        return [t() for t in tasks]
    _TASKS = list(tasks)
    # the objects made so far are frozen out of the collector's reach: a worker's collections
    # would otherwise touch (copy) every page of the parent's heap the fork shares with it
    gc.freeze()
    pool = ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("fork"), initializer=die_with_parent,
                               initargs=(os.getpid(),))
    try:
        return list(pool.map(_run_task, range(len(tasks))))
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    finally:
        pool.shutdown(wait=True)
        gc.unfreeze()
        _TASKS = []


__all__ = ["available_cores", "available_memory", "worker_cap", "die_with_parent", "worker_init", "share_threads",
           "OPENCV_THREADS_ENV", "PR_SET_PDEATHSIG", "JOB_SLOT_ENV", "job_slot", "staggered", "forked_workers",
           "run_forked"]
