"""The datasets the harness knows (``envs/datasets/catalogue.yaml``) and their download.

A dataset of kind ``files`` is a folder under the data root (``$ROOMSEG_SHARED_DATA``, default
``../shared/data``) whose every file has a size and SHA-256 in the catalogue. :func:`fetch_files`
downloads them over HTTP(S):

* **resumable**: each file is written to ``<name>.part`` in a staging folder
  ``<root>/.<folder>.fetch/`` that survives an interrupted run; the next run asks the server
  for the rest (an HTTP ``Range`` request) and starts over only when the server ignores it;
* **verified**: a file whose size or SHA-256 differs from the catalogue's is removed and named in
  one line (expected and got); a file that ended early keeps its ``.part`` for the next run;
* **atomic**: the staging folder becomes ``<root>/<folder>`` by one rename, only once every file
  is verified, so a failed or interrupted fetch leaves nothing that looks complete.

Kinds ``prior`` and ``ai2thor`` are downloaded by those packages into their own caches.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urljoin

from envs.digest import file_digest

CATALOGUE = Path(__file__).with_name("catalogue.yaml")
#: bytes per read while downloading.
CHUNK = 1 << 16
KINDS = ("files", "prior", "ai2thor")


class DownloadError(RuntimeError):
    """A fetch that did not give a verified dataset (one line saying which file and why)."""


@dataclass(frozen=True)
class DataFile:
    """One file of a dataset: its path in the dataset folder, URL, size (bytes) and SHA-256."""

    path: str
    url: str
    size: int
    sha256: str


@dataclass(frozen=True)
class Dataset:
    """A catalogue entry (see ``catalogue.yaml`` for the fields)."""

    name: str
    title: str
    kind: str
    source: str
    licence: str
    used_by: str
    folder: str = ""
    files: tuple[DataFile, ...] = ()
    size_note: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def size(self) -> int:
        """Total bytes of the files (kind ``files``)."""
        return sum(f.size for f in self.files)


def _yaml_kind(v: Any) -> str:
    return {list: "list", str: "string", int: "number", float: "number", bool: "boolean"}.get(type(v), type(v).__name__)


def _plain_name(folder: str) -> bool:
    """``folder`` is one folder name inside the data root: not empty, no separator, not ``.``
    or ``..``, not hidden (``.<folder>.fetch`` is its staging folder), not absolute."""
    return (bool(folder) and folder == folder.strip() and "/" not in folder and "\\" not in folder
            and not folder.startswith(".") and not Path(folder).is_absolute() and ":" not in folder)


def load_catalogue(path: str | Path = CATALOGUE) -> dict[str, Dataset]:
    """The catalogue's datasets by name.

    Raises:
        ValueError: a catalogue that is not a mapping, an entry that is not one, an entry without
            a required field, an unknown kind, a ``folder`` that is not one plain folder name
            inside the data root, or a file entry without path, size or a 64-hex-digit sha256
            (one line naming the entry)."""
    import yaml

    try:
        raw = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
    except yaml.YAMLError as e:
        raise ValueError(f"{path}: not valid YAML ({str(e).splitlines()[0]})") from None
    if not isinstance(raw, dict):
        raise ValueError(f"{path}: expected a mapping of dataset names to entries, got a {_yaml_kind(raw)}")
    out = {}
    for name, e in raw.items():
        if not isinstance(e, dict):
            raise ValueError(f"{path}: dataset {name!r}: expected a mapping of fields, got a {_yaml_kind(e)}")
        missing = [k for k in ("title", "kind", "source", "licence", "used_by") if k not in e]
        if missing:
            raise ValueError(f"{path}: dataset {name!r} has no {', '.join(missing)}")
        if e["kind"] not in KINDS:
            raise ValueError(f"{path}: dataset {name!r} has kind {e['kind']!r}; expected one of {', '.join(KINDS)}")
        files = []
        if e["kind"] == "files":
            if not e.get("folder") or not e.get("base_url") or not e.get("files"):
                raise ValueError(f"{path}: dataset {name!r} (kind files) needs folder, base_url and files")
            folder = e["folder"]
            if not isinstance(folder, str) or not _plain_name(folder):
                raise ValueError(f"{path}: dataset {name!r}: folder {folder!r} is not one plain folder name inside "
                                 f"the data root (no '/', '\\', '..', leading '.' or absolute path)")
            if not isinstance(e["files"], list) or not all(isinstance(f, dict) for f in e["files"]):
                raise ValueError(f"{path}: dataset {name!r}: files must be a list of entries (path, size, sha256)")
            for f in e["files"]:
                sha = str(f.get("sha256", ""))
                if not f.get("path") or not isinstance(f.get("size"), int) or len(sha) != 64 or \
                        any(c not in "0123456789abcdef" for c in sha):
                    raise ValueError(f"{path}: dataset {name!r}: file entry {f} needs path, size (bytes) and a "
                                     f"64-hex-digit sha256")
                if not isinstance(f["path"], str) or Path(f["path"]).is_absolute() or ".." in Path(f["path"]).parts:
                    raise ValueError(f"{path}: dataset {name!r}: file path {f['path']!r} leaves the dataset folder")
                files.append(DataFile(f["path"], urljoin(e["base_url"], f.get("url", f["path"])), f["size"], sha))
        known = {"title", "kind", "source", "licence", "used_by", "folder", "files", "size", "base_url"}
        out[name] = Dataset(name, e["title"], e["kind"], e["source"], e["licence"], e["used_by"], e.get("folder", ""),
                            tuple(files), str(e.get("size", "")), {k: v for k, v in e.items() if k not in known})
    return out


def status(ds: Dataset, root: str | Path, verify: bool = False) -> str:
    """``present``, ``absent``, ``partial (k of n files)`` or, with ``verify``, ``damaged (FILE)``
    for a ``files`` dataset under ``root`` (sizes are compared; ``verify`` also hashes); for
    ``prior`` / ``ai2thor``: where the package keeps it, and whether it is installed."""
    if ds.kind == "prior":
        return _package_status("prior", "~/.prior (prior's cache)")
    if ds.kind == "ai2thor":
        return _package_status("ai2thor", "~/.ai2thor (ai2thor's cache)")
    folder = Path(root) / ds.folder
    if not folder.is_dir():
        return "absent"
    have = [f for f in ds.files if (folder / f.path).is_file() and (folder / f.path).stat().st_size == f.size]
    if len(have) < len(ds.files):
        return f"partial ({len(have)} of {len(ds.files)} files)"
    if verify:
        for f in ds.files:
            if file_digest(folder / f.path) != f.sha256:
                return f"damaged ({f.path}: checksum differs)"
    return "present"


def _package_status(module: str, where: str) -> str:
    import importlib.util

    return f"via {module}: {where}" + ("" if importlib.util.find_spec(module) else f" ({module} not installed)")


def _download(url: str, part: Path, size: int, progress: Callable[[int], None], timeout: float) -> None:
    """Append the rest of ``url`` to ``part`` (a Range request from its current length).

    Raises:
        DownloadError: the server answered with an error or the transfer ended early (``part``
            keeps what arrived, for the next run)."""
    import http.client
    import urllib.error
    import urllib.request

    start = part.stat().st_size if part.exists() else 0
    if start > size:  # longer than the file can be: not a prefix of it
        part.unlink()
        start = 0
    if start == size:
        return
    req = urllib.request.Request(url, headers={"Range": f"bytes={start}-"} if start else {})
    try:
        with urllib.request.urlopen(req, timeout=timeout) as r:  # noqa: S310 (URLs from the catalogue)
            if start and r.status != 206:  # the server sent the whole file: start over
                start = 0
            with open(part, "ab" if start else "wb") as out:
                if start:
                    progress(start)
                while True:
                    try:
                        block = r.read(CHUNK)
                    except (OSError, ValueError, http.client.HTTPException) as e:  # the connection dropped mid-file
                        raise DownloadError(f"{url}: transfer broke off ({e}); {out.tell()} of {size} bytes "
                                            f"kept in {part}: run the fetch again to resume") from None
                    if not block:
                        break
                    out.write(block)
                    progress(len(block))
                    if out.tell() > size:
                        break
                out.flush()
                os.fsync(out.fileno())
    except urllib.error.HTTPError as e:
        raise DownloadError(f"{url}: HTTP {e.code} {e.reason}") from None
    except urllib.error.URLError as e:
        raise DownloadError(f"{url}: {e.reason} (no network? the fetch needs internet access)") from None
    except TimeoutError:
        raise DownloadError(f"{url}: no answer in {timeout:g} s; {part.stat().st_size} of {size} bytes kept in "
                            f"{part}: run the fetch again to resume") from None


def fetch_files(ds: Dataset, root: str | Path, progress: bool = True,
                timeout: float = 60.0) -> tuple[Path, bool]:
    """Download a ``files`` dataset into ``root/<folder>`` (see the module doc): resumable,
    checked against the catalogue's sizes and SHA-256, and moved into place as a whole.

    Returns:
        The dataset folder, and whether it was fetched (False: already present and verified).

    Raises:
        DownloadError: a file that could not be fetched, ended early (kept for a resume) or
            differs from the catalogue (removed); the dataset folder is then left as it was."""
    from tqdm import tqdm

    root = Path(root)
    folder = root / ds.folder
    if status(ds, root, verify=True) == "present":
        return folder, False
    stage = root / f".{ds.folder}.fetch"
    stage.mkdir(parents=True, exist_ok=True)
    done_bytes = 0
    todo = []
    for f in ds.files:  # verified files of an earlier run (in the stage, or in an old folder) are kept
        dest = stage / f.path
        old = folder / f.path
        if not dest.is_file() and old.is_file() and old.stat().st_size == f.size and file_digest(old) == f.sha256:
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(old, dest)
        if dest.is_file() and dest.stat().st_size == f.size and file_digest(dest) == f.sha256:
            done_bytes += f.size
        else:
            todo.append(f)
    with tqdm(total=ds.size, initial=done_bytes, unit="B", unit_scale=True, unit_divisor=1024, desc=ds.name,
              disable=not progress, leave=False) as bar:
        for f in todo:
            dest = stage / f.path
            dest.parent.mkdir(parents=True, exist_ok=True)
            if dest.exists():
                dest.unlink()
            part = dest.with_name(dest.name + ".part")
            _download(f.url, part, f.size, bar.update, timeout)
            got = part.stat().st_size
            if got < f.size:
                raise DownloadError(f"{f.url}: the transfer ended after {got} of {f.size} bytes (kept in {part}: "
                                    f"run the fetch again to resume)")
            digest = file_digest(part)
            if got != f.size or digest != f.sha256:
                part.unlink()
                raise DownloadError(f"{f.url}: {got} bytes, sha256 {digest}; expected {f.size} bytes, sha256 "
                                    f"{f.sha256} (removed: the source differs from the release the harness knows)")
            os.replace(part, dest)
    _move_into_place(stage, folder)
    return folder, True


def _move_into_place(stage: Path, folder: Path) -> None:
    """``stage`` becomes ``folder`` by one rename (an old ``folder`` is moved aside first and
    then removed, its files not in the dataset carried over)."""
    if folder.exists():
        for entry in folder.rglob("*"):
            rel = entry.relative_to(folder)
            if entry.is_file() and not (stage / rel).exists():
                (stage / rel).parent.mkdir(parents=True, exist_ok=True)
                os.replace(entry, stage / rel)
        old = folder.with_name(f".{folder.name}.old-{os.getpid()}")
        os.replace(folder, old)
        os.replace(stage, folder)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(stage, folder)


def fetch_with_package(ds: Dataset) -> str:
    """Ask ``prior`` or ``ai2thor`` to download a dataset into its own cache; returns where.

    Raises:
        DownloadError: the package is not installed or its download failed (its message)."""
    try:
        if ds.kind == "prior":
            import prior

            prior.load_dataset(ds.extra.get("dataset", ds.name))
            return "prior's cache (~/.prior)"
        if ds.kind == "ai2thor":
            from ai2thor.controller import Controller

            Controller(download_only=True)
            return "ai2thor's cache (~/.ai2thor)"
    except ImportError as e:
        extra = "thor"
        raise DownloadError(f"{ds.name}: the {e.name} package is not installed (pip install -e '.[{extra}]')") from None
    except Exception as e:  # the package's own failure, in its words
        raise DownloadError(f"{ds.name}: {type(e).__name__}: {e}") from None
    raise DownloadError(f"{ds.name}: kind {ds.kind!r} is not fetched by a package")


__all__ = ["CATALOGUE", "DataFile", "Dataset", "DownloadError", "fetch_files", "fetch_with_package",
           "load_catalogue", "status"]
