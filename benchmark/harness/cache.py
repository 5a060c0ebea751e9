"""Content-addressed stage caches: keys from resolved configs and input content, atomic
writes, file locks.

A cache entry is a file (or folder) under ``<cache_dir>/<stage>/<key>/<house>@<content>...``
(paths: :mod:`benchmark.harness.store`). ``key`` is a short hash of the resolved configs of
every stage the entry depends on (a score entry's also of the row it holds, its stage names and
dataset, and of ``run.save_maps``: :func:`benchmark.harness.runner.stage_keys`), so changing an
aggregator never invalidates renders or classifier outputs; ``content`` is a short hash of what the entry was computed from: the
house's JSON and every input file the stages read (:func:`content_hash`,
:func:`file_fingerprint`, :func:`config_inputs`), so editing one house or one pose file
recomputes what depends on it and nothing else. Writes go to a temporary name in the same
folder and are renamed into place (``os.replace``), so a killed run never leaves a
half-written entry; a per-entry lock keeps concurrent sweep workers from computing the same
entry twice.
"""

from __future__ import annotations

import contextlib
import contextvars
import hashlib
import json
import os
import stat
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from filelock import FileLock

from envs.atomic import atomic_write_text
from envs.digest import file_digest  # noqa: F401 (re-exported: cache keys of files)
from envs.files import file_kind, link_note
from envs.npz import ChecksumError, load_npz, save_npz  # noqa: F401 - the cache's readers and writers of .npz entries


def config_key(*parts: Any) -> str:
    """12-hex-digit hash of JSON-serialisable config parts (dict key order does not matter)."""
    blob = json.dumps(parts, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha1(blob.encode("utf-8")).hexdigest()[:12]


def content_hash(obj: Any) -> str:
    """16-hex-digit SHA-1 of a JSON-serialisable object (canonical: sorted keys, no spaces).

    Returns:
        The hash; equal objects (dict order aside) give equal hashes."""
    blob = json.dumps(obj, sort_keys=True, default=_json_default, separators=(",", ":"), allow_nan=True)
    return hashlib.sha1(blob.encode("utf-8")).hexdigest()[:16]


#: files larger than this (bytes) are fingerprinted by size + modification time, not hashed.
HASH_LIMIT = 64 * 2**20

_FINGERPRINTS: dict[tuple[str, int, int], str] = {}


def file_fingerprint(path: str | Path) -> str:
    """What a stage read from ``path``, as a short string that changes when the input does.

    A file up to :data:`HASH_LIMIT` bytes: SHA-1 of its bytes. A larger file (model weights):
    ``size:<bytes>:mtime:<ns>`` (copying it without keeping times recomputes; editing it in
    place within the same nanosecond with the same size does not: documented limit). A
    folder: the hash of its files' relative names, sizes and modification times.
    File fingerprints are memoised per (path, size, mtime) for the process (folders are
    listed every time).

    Returns:
        ``sha1:<16 hex>``, ``size:...`` or ``dir:<16 hex>``.

    Raises:
        FileNotFoundError: ``path`` does not exist (the message names it).
    """
    p = Path(path).expanduser()
    try:
        st = p.stat()
    except FileNotFoundError:
        raise FileNotFoundError(f"input file {p} does not exist") from None
    if not (stat.S_ISREG(st.st_mode) or stat.S_ISDIR(st.st_mode)):  # a FIFO blocks, /dev/zero never ends
        raise ValueError(f"input file {p}{link_note(p)} is {file_kind(st.st_mode)}; expected a regular file or a folder")
    if p.is_dir():
        listing = []
        for root, dirs, files in os.walk(p):
            dirs.sort()
            for name in sorted(files):
                f = Path(root) / name
                fs = f.stat()
                listing.append([str(f.relative_to(p)), fs.st_size, fs.st_mtime_ns])
        fp = "dir:" + content_hash(listing)
        return fp
    memo = (str(p.resolve()), st.st_size, st.st_mtime_ns)
    if memo in _FINGERPRINTS:
        return _FINGERPRINTS[memo]
    if st.st_size > HASH_LIMIT:
        fp = f"size:{st.st_size}:mtime:{st.st_mtime_ns}"
    else:
        h = hashlib.sha1()
        with open(p, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        fp = "sha1:" + h.hexdigest()[:16]
    _FINGERPRINTS[memo] = fp
    return fp


def _looks_like_path(value: str) -> bool:
    return value not in (".", "..") and ("/" in value or os.sep in value or Path(value).suffix != "")


def config_inputs(node: Any, house_id: str | None = None, where: str = "") -> dict[str, str]:
    """Fingerprints of the input files a stage's config names.

    Every string value of ``node`` (a plain dict/list tree) that looks like a path (has a
    ``/`` or a file suffix) and exists after ``{house_id}`` is filled in, is fingerprinted
    with :func:`file_fingerprint`. Strings naming nothing that exists (model ids such as
    ``facebook/dinov2-large``, a missing weights file that the stage will report) are skipped.

    Returns:
        {dotted config key: fingerprint}, sorted by key.
    """
    return leaf_inputs(path_leaves(node), house_id, where)


def path_leaves(node: Any) -> tuple[tuple[str, str], ...]:
    """The strings of ``node`` (a plain dict/list tree) that look like paths, with their dotted
    config keys, sorted by key: what :func:`config_inputs` fingerprints. A job's stage configs
    do not change, so a pipeline lists them once (:func:`leaf_inputs` checks the files per house)."""
    out: list[tuple[str, str]] = []

    def walk(v: Any, key: str) -> None:
        if isinstance(v, Mapping):
            for k, x in v.items():
                walk(x, f"{key}.{k}" if key else str(k))
        elif isinstance(v, list | tuple):
            for i, x in enumerate(v):
                walk(x, f"{key}[{i}]")
        elif isinstance(v, str) and _looks_like_path(v):
            out.append((key, v))

    walk(node, "")
    return tuple(sorted(out, key=lambda kv: kv[0]))  # (stable: a repeated key keeps its walk order)


def leaf_inputs(leaves: Sequence[tuple[str, str]], house_id: str | None = None, where: str = "") -> dict[str, str]:
    """{key: fingerprint} of the files ``leaves`` (:func:`path_leaves`) name that exist, with
    ``{house_id}`` filled in: :func:`config_inputs` of the node they came from. ``where``: the
    config group of that node (``env``), for the message naming a file that is no regular file."""
    out: dict[str, str] = {}
    for key, s in leaves:
        if house_id is not None and "{house_id}" in s:
            s = s.replace("{house_id}", str(house_id))
        p = Path(s).expanduser()
        if p.exists():
            try:
                out[key] = file_fingerprint(p)
            except ValueError as e:  # a FIFO or a device: named with the config key that names it
                raise ValueError(f"{where + '.' if where else ''}{key}: {e}") from None
    return out


class EntryBusy(BaseException):
    """Raised by :func:`locked` instead of waiting, inside :func:`defer_when_busy`: another
    process holds the entry's lock (it is computing that entry). A ``BaseException``, so that a
    house's ``except Exception`` (which records the house as failed) lets it through to the
    executor that asked, which runs the house again later."""


#: whether :func:`locked` raises :class:`EntryBusy` rather than wait (see :func:`defer_when_busy`)
_DEFER_WHEN_BUSY: contextvars.ContextVar[bool] = contextvars.ContextVar("roomseg_defer_when_busy", default=False)


@contextlib.contextmanager
def defer_when_busy(on: bool = True) -> Iterator[None]:
    """Within this block (``on``), :func:`locked` raises :class:`EntryBusy` when another process
    holds the lock, instead of waiting for it: a job with other houses to run meanwhile
    comes back to this one when the other process has computed the entry."""
    token = _DEFER_WHEN_BUSY.set(bool(on))
    try:
        yield
    finally:
        _DEFER_WHEN_BUSY.reset(token)


@contextlib.contextmanager
def locked(path: Path, timeout: float = 3600.0) -> Iterator[None]:
    """Hold an inter-process lock tied to ``path`` (a ``.lock`` file beside it, removed when
    the lock is released, so a cache does not fill with empty lock files).

    POSIX: ``flock`` on the lock file; after locking, the file must still be the one at the
    path (same inode), else another holder removed it in between and the lock is taken again
    on the new file; the holder removes the file before unlocking. So at most one process
    holds the lock of a path at a time, and a process killed while holding it leaves a file
    that the next holder takes over and removes. Elsewhere: ``filelock``'s lock (its file stays).

    Raises:
        TimeoutError: not acquired within ``timeout`` seconds."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    lock = str(path) + ".lock"
    try:
        import fcntl
    except ImportError:  # not POSIX
        with FileLock(lock, timeout=timeout):
            yield
        return
    deadline = time.monotonic() + timeout
    delay = 0.001
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            while True:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except BlockingIOError:
                    if _DEFER_WHEN_BUSY.get():
                        raise EntryBusy(lock) from None
                    if time.monotonic() > deadline:
                        raise TimeoutError(f"{lock}: held by another process for over {timeout:g} s") from None
                    time.sleep(delay)
                    delay = min(delay * 2, 0.05)
            try:
                same = os.stat(lock).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
        except BaseException:
            os.close(fd)
            raise
        if same:
            break
        os.close(fd)  # the holder before removed this file: lock the one at the path now
    try:
        yield
    finally:
        try:
            os.unlink(lock)
        except FileNotFoundError:
            pass
        os.close(fd)  # unlocks


def atomic_write_json(path: Path, obj: Any) -> None:
    atomic_write_text(path, json.dumps(obj, indent=1, sort_keys=True, default=_json_default))


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def atomic_save_npz(path: str | Path, **arrays) -> None:
    """A cache ``.npz`` entry: written with a checksum of its content and checked when read
    (:mod:`envs.npz`; a bad entry raises :class:`envs.npz.ChecksumError`, a ``ValueError``), so
    without the fsync (a torn entry is recomputed, not served)."""
    save_npz(path, durable=False, **arrays)


def _canonical(obj: Any) -> bytes:
    return json.dumps(obj, sort_keys=True, default=_json_default, separators=(",", ":"), allow_nan=True).encode("utf-8")


def write_entry(path: Path, obj: Any, files: Mapping[str, str | Path] | None = None) -> None:
    """Write a JSON cache entry with the SHA-256 of its content, atomically.

    Args:
        path: the entry file.
        obj: the entry (JSON-serialisable; NumPy scalars and arrays become numbers and lists).
        files: other files this entry vouches for ({role: path}, e.g. the saved label maps of
            a score row): their SHA-256 is recorded, and :func:`read_entry` checks them.

    The file is ``{"sha256": ..., "entry": obj, "files": {role: {"path": ..., "sha256": ...}}}``
    with file paths relative to ``path``'s folder (a cache moved as a whole stays valid)."""
    obj = json.loads(_canonical(obj))  # what a reader will see (NumPy types made plain)
    recorded = {}
    for role, f in (files or {}).items():
        recorded[role] = {"path": os.path.relpath(f, path.parent), "sha256": file_digest(f)}
    body = {"entry": obj, "files": recorded}
    # one line, written by json's C encoder (an indented dump takes its pure-Python one: a score
    # entry per house and job); the checksum is over the canonical form, whatever the layout, so
    # entries written indented by earlier versions read as before
    atomic_write_text(path, json.dumps({"sha256": hashlib.sha256(_canonical(body)).hexdigest(), **body},
                                       sort_keys=True, allow_nan=True), durable=False)  # verified on read


def read_entry(path: Path, check_files: bool = True, require: Sequence[str] = ()) -> Any:
    """A JSON cache entry written by :func:`write_entry`, after checking its checksum and (with
    ``check_files``) those of the files it vouches for; ``require`` names roles the entry must
    vouch for (e.g. ``maps`` when the run keeps label maps).

    Raises:
        FileNotFoundError: no entry.
        ChecksumError: malformed JSON, no checksum, content that does not match it, or a vouched
            file that is missing or changed (one line naming the file)."""
    try:
        raw = read_json(path)
    except ValueError as e:
        raise ChecksumError(str(e)) from None
    if not isinstance(raw, dict) or "sha256" not in raw or "entry" not in raw:
        raise ChecksumError(f"{path}: no checksum (written by an older version, or not by this project)")
    body = {"entry": raw["entry"], "files": raw.get("files", {})}
    got = hashlib.sha256(_canonical(body)).hexdigest()
    if got != raw["sha256"]:
        raise ChecksumError(f"{path}: content does not match its checksum (sha256 {got[:12]}..., recorded "
                            f"{str(raw['sha256'])[:12]}...): the entry is damaged")
    missing = [r for r in require if r not in body["files"]]
    if missing:
        raise ChecksumError(f"{path}: the entry has no {' or '.join(missing)} file (written by a run that did not keep it)")
    if check_files:
        for role, rec in body["files"].items():
            f = Path(os.path.normpath(path.parent / rec["path"]))
            try:
                ok = file_digest(f) == rec["sha256"]
            except FileNotFoundError:
                raise ChecksumError(f"{path}: its {role} file {f} is missing") from None
            if not ok:
                raise ChecksumError(f"{path}: its {role} file {f} changed since the entry was written")
    return raw["entry"]


def read_json(path: Path) -> Mapping[str, Any]:
    """A JSON file's object.

    Raises:
        ValueError: malformed JSON (the message names the file, line and column)."""
    with open(path, encoding="utf-8") as f:
        try:
            return json.load(f)
        except json.JSONDecodeError as e:
            raise ValueError(f"{path}: malformed JSON ({e})") from None
