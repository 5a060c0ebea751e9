"""Worker processes: how many cores this process may use (:func:`available_cores`), and
workers that die with their parent (:func:`die_with_parent`). Standard library only: the
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


def worker_init(parent_pid: int) -> None:
    """A pool initializer: die with the parent, and leave Ctrl-C to the parent, which stops
    the workers itself (SIGINT goes to the whole foreground process group)."""
    die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


__all__ = ["available_cores", "die_with_parent", "worker_init", "PR_SET_PDEATHSIG"]
