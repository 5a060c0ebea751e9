"""External programs in a process group of their own, under a guard (:func:`run_guarded`).
Standard library only; this file is also the guard's script.

A program the harness starts (ROSE²'s driver, and whatever that starts) must not outlive the
process that started it, nor fill its memory with output. :func:`run_guarded` starts a small
guard process (this file run as a script) that starts the program in a new process group and
waits for it while watching the caller:

- the caller dies (``kill -9`` of ``roomseg-bench``: its pool worker dies with it; out of
  memory; a worker terminated on Ctrl-C): the kernel tells the guard at once
  (``prctl(PR_SET_PDEATHSIG, SIGTERM)``, Linux), or the guard notices within 0.1 s that its
  parent changed; it kills the program's whole group (``SIGKILL``) and removes the folders it
  was given;
- the caller's timeout passes, or the caller is interrupted: the caller asks the guard to
  stop (``SIGTERM``; ``SIGKILL`` after :data:`GUARD_GRACE_S` s), with the same effect;
- the program exits: what it left running in its group is killed too.

The program's stdout and stderr reach the caller through pipes of which only the last
``keep_bytes`` are kept (a program that writes gigabytes costs no memory).
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

#: ``PR_SET_PDEATHSIG`` from ``<linux/prctl.h>`` (as in :mod:`benchmark.harness.processes`, which
#: imports the standard library only, for Hydra's plugins, and so cannot import this module).
PR_SET_PDEATHSIG = 1


def _prctl_pdeathsig(sig: int) -> bool:
    """``prctl(PR_SET_PDEATHSIG, sig)``; False where unavailable or refused."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        return libc.prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


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
    guard = [sys.executable, "-I", os.path.abspath(__file__), "--guard", str(os.getpid())]  # -I: no folder of ours on its path
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


__all__ = ["Guarded", "run_guarded", "KEEP_BYTES", "PR_SET_PDEATHSIG"]


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
