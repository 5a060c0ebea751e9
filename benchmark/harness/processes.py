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

An external program (ROSE²'s driver, and whatever it starts) runs through
:func:`run_guarded`: a small guard process (this file run as a script) starts the program in
a process group of its own, watches the caller and, when the caller dies (``kill -9``, out of
memory, a pool worker terminated on Ctrl-C) or asks it to stop (a timeout), kills the
program's whole group and removes the folders it was given; the program's output reaches the
caller through pipes of which only the last ``keep_bytes`` are kept, so a program that writes
gigabytes costs no memory.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import shutil
import signal
import subprocess
import sys
import threading
from dataclasses import dataclass

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


def worker_init(parent_pid: int) -> None:
    """A pool initializer: die with the parent, and leave Ctrl-C to the parent, which stops
    the workers itself (SIGINT goes to the whole foreground process group)."""
    die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` exists (a zombie counts; so does one of another user)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


# ---------------------------------------------------------------- external programs
#: bytes of each of a program's output streams that :func:`run_guarded` keeps (the end).
KEEP_BYTES = 64 * 1024
#: seconds the guard gets to kill its group and clean up after being asked to stop.
GUARD_GRACE_S = 5.0


@dataclass
class Guarded:
    """A finished program (:func:`run_guarded`): its exit status (negative: killed by that
    signal), and the last bytes of its stdout and stderr (decoded, invalid bytes replaced)."""

    returncode: int
    stdout: str
    stderr: str


def _tail_reader(stream, keep: int) -> tuple[threading.Thread, bytearray]:
    buf = bytearray()

    def loop() -> None:
        while True:
            chunk = stream.read1(65536) if hasattr(stream, "read1") else stream.read(65536)
            if not chunk:
                break
            buf.extend(chunk)
            if len(buf) > 2 * keep:
                del buf[:-keep]
        stream.close()

    t = threading.Thread(target=loop, name="output-tail", daemon=True)
    t.start()
    return t, buf


def _stop_guard(proc: subprocess.Popen) -> None:
    """Ask the guard to kill its program's group and clean up; kill it when it does not."""
    if proc.poll() is None:
        try:
            proc.send_signal(signal.SIGTERM)
            proc.wait(timeout=GUARD_GRACE_S)
        except (subprocess.TimeoutExpired, ProcessLookupError):
            proc.kill()
    proc.wait()


def run_guarded(cmd: list[str], *, timeout: float | None = None, env: dict[str, str] | None = None,
                cwd: str | None = None, remove: list[str] | tuple[str, ...] = (), keep_bytes: int = KEEP_BYTES,
                ) -> Guarded:
    """Run ``cmd`` in a process group of its own, under a guard process (module doc).

    Args:
        cmd: the program and its arguments.
        timeout: seconds before the program's whole group is killed (``TimeoutExpired``).
        env, cwd: the program's environment and working folder.
        remove: folders the guard removes when the caller dies or the program is stopped
            (the caller removes them itself otherwise).
        keep_bytes: bytes kept of the end of each output stream.

    Returns:
        The program's exit status and the ends of its output. Processes the program left in
        its group when it exited are killed too.

    Raises:
        subprocess.TimeoutExpired: the program ran longer than ``timeout`` (its group is gone).
    """
    guard = [sys.executable, os.path.abspath(__file__), "--guard", str(os.getpid())]
    for r in remove:
        guard += ["--remove", str(r)]
    proc = subprocess.Popen([*guard, "--", *cmd], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env=env, cwd=cwd, start_new_session=True)
    readers = [_tail_reader(proc.stdout, keep_bytes), _tail_reader(proc.stderr, keep_bytes)]
    try:
        proc.wait(timeout=timeout)
    except BaseException:  # a timeout, Ctrl-C: the program's group goes first
        _stop_guard(proc)
        for t, _ in readers:
            t.join(timeout=GUARD_GRACE_S)
        if isinstance(sys.exc_info()[1], subprocess.TimeoutExpired):
            raise subprocess.TimeoutExpired(cmd, timeout) from None
        raise
    for t, _ in readers:
        t.join()
    out, err = (bytes(b[-keep_bytes:]).decode("utf-8", "replace") for _, b in readers)
    return Guarded(proc.returncode, out, err)


def _guard_main(parent: int, remove: list[str], cmd: list[str]) -> int:
    """The guard: start ``cmd`` in a new process group, wait for it while watching ``parent``;
    on the parent's death or SIGTERM kill the group, remove ``remove``, exit 128+15."""
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    _prctl_pdeathsig(signal.SIGTERM)  # the kernel tells at once where it can; the poll below otherwise
    try:
        child = subprocess.Popen(cmd, start_new_session=True)
    except OSError as e:
        print(f"cannot run {cmd[0]}: {e}", file=sys.stderr)
        return 127
    wnohang = os.WEXITED | os.WNOHANG | os.WNOWAIT
    while True:
        if os.getppid() != parent:
            stop.set()
        if stop.is_set():
            with _suppress():
                os.killpg(child.pid, signal.SIGKILL)
            child.wait()
            for r in remove:
                shutil.rmtree(r, ignore_errors=True)
            return 128 + signal.SIGTERM
        if os.waitid(os.P_PID, child.pid, wnohang) is not None:  # exited (not reaped: its group id is still ours)
            with _suppress():
                os.killpg(child.pid, signal.SIGKILL)  # what it left running
            return child.wait()
        stop.wait(0.1)


class _suppress:
    def __enter__(self):
        return self

    def __exit__(self, *exc) -> bool:
        return exc[0] is not None and issubclass(exc[0], (ProcessLookupError, PermissionError))


def _main(argv: list[str]) -> int:
    if len(argv) < 4 or argv[0] != "--guard" or "--" not in argv:
        print("usage: processes.py --guard PARENT_PID [--remove DIR]... -- CMD...", file=sys.stderr)
        return 2
    cut = argv.index("--")
    opts, cmd = argv[2:cut], argv[cut + 1:]
    remove = [opts[i + 1] for i in range(0, len(opts) - 1, 2) if opts[i] == "--remove"]
    return _guard_main(int(argv[1]), remove, cmd)


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))


__all__ = ["available_cores", "available_memory", "worker_cap", "die_with_parent", "worker_init", "run_guarded", "Guarded", "pid_alive", "PR_SET_PDEATHSIG"]
