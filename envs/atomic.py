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
from collections.abc import Iterable, Iterator
from pathlib import Path

#: tries before giving up on a free random name (each name has 48 random bits).
_TRIES = 100


def file_identity(path: str | Path) -> tuple[int, int, int] | None:
    """(inode, modification time ns, size) of the file at ``path``, None when there is none: what
    changes when the file is replaced (an atomic write renames another file into place) or
    written over in place. Readers that keep what they read key it by this.
    """
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_ino, st.st_mtime_ns, st.st_size


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


def atomic_write_bytes(path: str | Path, data: bytes, durable: bool = True) -> None:
    """Write ``data`` to ``path`` so that readers see the old file or the whole new one; the
    new file has the mode of an ordinary new file (0o666 less the umask).

    ``durable``: flush the data to the disk (``fsync``) before the rename, so that the file is
    whole after a power failure too. A killed process never needs it (the kernel keeps what was
    written); cache entries skip it (``durable=False``) because they are verified on read and a
    torn one is recomputed, not served (100 generated houses: 5 % less wall time on this
    machine's disk)."""
    atomic_write_chunks(path, (data,), durable)


def atomic_write_chunks(path: str | Path, chunks: Iterable[bytes], durable: bool = True) -> None:
    """:func:`atomic_write_bytes` of the concatenation of ``chunks``, written one at a time as
    they come (a file larger than the memory one chunk takes: a map image by bands of rows);
    a chunk that raises leaves no file and the old one in place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = ordinary_temp_file(path.parent, "." + path.name + ".", ".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            for data in chunks:
                f.write(data)
            f.flush()
            if durable:
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as e:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(e, OSError) and not e.filename:  # a failed write() (a full disk) names no file: name it
            raise OSError(e.errno, e.strerror or str(e), str(path)) from e
        raise


def atomic_write_text(path: str | Path, text: str, durable: bool = True) -> None:
    """:func:`atomic_write_bytes` of ``text`` in UTF-8."""
    atomic_write_bytes(path, text.encode("utf-8"), durable)


def leftover_prefix(out: Path, kind: str) -> str:
    """Name prefix of a temporary sibling of ``out`` (``kind``: ``tmp`` for a set being
    written, ``old`` for the set being replaced), holding this process's id so that a later
    run can tell a killed writer's leftovers from a running writer's folders."""
    return f".{out.name}.{kind}-{os.getpid()}-"


def clean_leftovers(out: str | Path) -> list[Path]:
    """Remove the temporary siblings of ``out`` left by writers that were killed (their
    process is gone); folders of a writer still running are kept.

    Returns:
        The folders removed."""
    import re
    import shutil

    out = Path(out)
    removed = []
    pattern = re.compile(rf"^\.{re.escape(out.name)}\.(?:tmp|old)-(\d+)-")
    if not out.parent.is_dir():
        return removed
    for p in out.parent.iterdir():
        m = pattern.match(p.name)
        if not m or pid_alive(int(m.group(1))):
            continue
        shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
        removed.append(p)
    return removed


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


@contextlib.contextmanager
def atomic_folder(out: str | Path) -> Iterator[Path]:
    """Write a set of files as a whole: yield a temporary sibling folder to fill; on success it
    replaces ``out`` (entries of the old ``out`` that the new set does not have, e.g. a
    ``figures/`` folder, are carried over); on an exception it is removed and ``out`` is
    untouched. A process killed at any moment leaves ``out`` as it was, or whole and new
    (or, killed between the two renames, absent with the old set kept beside it as
    ``.<name>.old-<pid>-0``), never a part of the new set. Leftovers of a writer that was
    killed (its process is gone) are removed first (:func:`clean_leftovers`).

    Yields:
        The temporary folder (same parent as ``out``, so the final rename is atomic)."""
    import shutil

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    clean_leftovers(out)
    tmp = ordinary_temp_dir(out.parent, leftover_prefix(out, "tmp"))  # not private: the set is an ordinary folder
    try:
        yield tmp
        if out.exists():
            for entry in out.iterdir():
                if not (tmp / entry.name).exists():
                    os.replace(entry, tmp / entry.name)
            old = out.parent / f"{leftover_prefix(out, 'old')}0"
            os.replace(out, old)
            os.replace(tmp, out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


__all__ = ["atomic_write_bytes", "atomic_write_text", "atomic_folder", "clean_leftovers", "leftover_prefix",
           "ordinary_temp_dir", "ordinary_temp_file"]
