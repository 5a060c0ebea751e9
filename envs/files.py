"""Input files that must be regular files: checked with ``stat``, never opened.

A FIFO blocks whoever opens it, and a device such as ``/dev/zero`` reads without end, so every
reader of a user's input file (a bag, a map, poses, labels, a house file, a file a stage's
config names) asks :func:`regular_file` (or :func:`file_kind`) first. The one check, here.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path


def file_kind(mode: int) -> str:
    """What a ``st_mode`` names, in words (``a folder``, ``a FIFO (named pipe)``, ...)."""
    for test, name in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"


def regular_file(path: str | Path, what: str, error: type[Exception] = ValueError) -> Path:
    """``path`` (``~`` expanded) when it is a regular file, or a symbolic link to one: checked
    with ``stat``, never opened, so that a FIFO (which blocks whoever opens it) or a device
    (``/dev/zero`` reads without end) is refused before any reader touches it.

    Args:
        path: the file.
        what: how the user named it, for the message (``bag``, ``map``, ``labels``, ``env.path``).
        error: the exception raised for a file that is not regular.

    Raises:
        FileNotFoundError: ``path`` does not exist (one line naming it).
        error: ``path`` is a folder, FIFO, device or socket (one line naming it, and the link's
            target when it is a symbolic link).
    """
    p = Path(path).expanduser()
    try:
        st = os.stat(p)
    except FileNotFoundError:
        raise FileNotFoundError(f"{what}={p} does not exist; expected a regular file") from None
    except OSError as e:
        raise error(f"{what}={p}: cannot stat it ({e.strerror}); expected a regular file") from None
    if not stat.S_ISREG(st.st_mode):
        raise error(f"{what}={p}{link_note(p)} is {file_kind(st.st_mode)}; expected a regular file")
    return p


def link_note(p: Path) -> str:
    """`` (a symbolic link to <target>)`` when ``p`` is one, else the empty string."""
    return f" (a symbolic link to {os.path.realpath(p)})" if p.is_symlink() else ""
