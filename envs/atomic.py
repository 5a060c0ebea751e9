"""Atomic file writes (temporary file in the same folder, then ``os.replace``).

Temporary files and folders are created here with the mode an ordinary new file or folder
gets (``0o666`` / ``0o777`` less the process's umask: 0644 / 0755 with umask 022, 0664 /
0775 with 002), by the kernel at creation (``os.open(..., O_EXCL, 0o666)``, ``os.mkdir(...,
0o777)``), so that what is renamed into place is not left private the way ``tempfile.mkstemp``
and ``mkdtemp`` make it (0600 / 0700), and no umask is read or changed (which would not be
thread safe).
"""

from __future__ import annotations

import contextlib
import os
import secrets
from pathlib import Path

#: tries before giving up on a free random name (each name has 48 random bits).
_TRIES = 100


def ordinary_temp_file(folder: str | Path, prefix: str, suffix: str = "") -> tuple[int, Path]:
    """Create a new empty file ``<folder>/<prefix><random><suffix>`` for writing, with the
    mode of an ordinary new file (0o666 less the umask).

    Returns:
        (an open file descriptor, opened for writing in binary mode, the file's path).

    Raises:
        FileExistsError: no free name after many tries (a full or hostile folder).
    """
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0)
    for _ in range(_TRIES):
        path = Path(folder) / f"{prefix}{secrets.token_hex(6)}{suffix}"
        try:
            return os.open(path, flags, 0o666), path
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary name {prefix}*{suffix} in {folder}")


def ordinary_temp_dir(folder: str | Path, prefix: str) -> Path:
    """Create a new empty folder ``<folder>/<prefix><random>`` with the mode of an ordinary
    new folder (0o777 less the umask).

    Raises:
        FileExistsError: no free name after many tries.
    """
    for _ in range(_TRIES):
        path = Path(folder) / f"{prefix}{secrets.token_hex(6)}"
        try:
            os.mkdir(path, 0o777)
            return path
        except FileExistsError:
            continue
    raise FileExistsError(f"no free temporary folder name {prefix}* in {folder}")


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` so that readers see the old file or the whole new one; the
    new file has the mode of an ordinary new file (0o666 less the umask)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = ordinary_temp_file(path.parent, "." + path.name + ".", ".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as e:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(e, OSError) and not e.filename:  # a failed write() (a full disk) names no file: name it
            raise OSError(e.errno, e.strerror or str(e), str(path)) from e
        raise


def atomic_write_text(path: str | Path, text: str) -> None:
    """:func:`atomic_write_bytes` of ``text`` in UTF-8."""
    atomic_write_bytes(path, text.encode("utf-8"))


__all__ = ["atomic_write_bytes", "atomic_write_text", "ordinary_temp_dir", "ordinary_temp_file"]
