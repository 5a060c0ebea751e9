"""The file a failed write was writing (standard library only: the sweep plugins use it too).

A write that fails at ``open()`` names its file (``OSError.filename``); one that fails at
``write()``, ``flush()`` or ``close()`` (a full disk) names none, so a one-line error would say
"cannot write (No space left on device)". :func:`failed_path` finds the file from the
traceback, and :func:`naming_the_file` gives an error that carries it (so it survives being
sent from a worker process, which drops tracebacks).
"""

from __future__ import annotations

import io


def failed_path(e: BaseException) -> str:
    """The file an ``OSError`` was writing: its ``filename``; else the file object open in the
    innermost frame of its traceback that has one; "" when none is found."""
    if getattr(e, "filename", None):
        return str(e.filename)
    tb, frames = e.__traceback__, []
    while tb is not None:
        frames.append(tb.tb_frame)
        tb = tb.tb_next
    for frame in reversed(frames):
        for value in frame.f_locals.values():
            if isinstance(value, io.IOBase) and isinstance(getattr(value, "name", None), str):
                return value.name
    return ""


def cannot_write(e: OSError, default: object = "") -> str:
    """The one line a command prints for a write that failed: ``cannot write FILE (reason)``,
    the file from :func:`failed_path`, else ``default`` (e.g. the output folder asked for)."""
    return f"cannot write {failed_path(e) or default} ({e.strerror or e})"


def naming_the_file(e: BaseException) -> BaseException:
    """``e``, or for an ``OSError`` that names no file but whose file the traceback shows, an
    ``OSError`` with the same errno and message that names it."""
    if isinstance(e, OSError) and not e.filename:
        path = failed_path(e)
        if path:
            return OSError(e.errno, e.strerror or str(e), path)
    return e


__all__ = ["cannot_write", "failed_path", "naming_the_file"]
