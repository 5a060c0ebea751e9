"""Content-addressed stage caches: keys from resolved configs, atomic writes, file locks.

A cache entry is a file (or folder) under ``<cache_dir>/<stage>/<key>/<house_id>...``.
``key`` is a short hash of the resolved configs of every stage the entry depends on, so
changing an aggregator never invalidates renders or classifier outputs. Writes go to a
temporary name in the same folder and are renamed into place (``os.replace``), so a killed
run never leaves a half-written entry; a per-entry lock keeps concurrent sweep workers
from computing the same entry twice.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from filelock import FileLock

from envs.atomic import atomic_write_bytes, atomic_write_text


def config_key(*parts: Any) -> str:
    """12-hex-digit hash of JSON-serialisable config parts (dict key order does not matter)."""
    blob = json.dumps(parts, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha1(blob.encode("utf-8")).hexdigest()[:12]


@contextlib.contextmanager
def locked(path: Path, timeout: float = 3600.0) -> Iterator[None]:
    """Hold an inter-process lock tied to ``path`` (a ``.lock`` file beside it)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with FileLock(str(path) + ".lock", timeout=timeout):
        yield


def atomic_write_json(path: Path, obj: Any) -> None:
    atomic_write_text(path, json.dumps(obj, indent=1, sort_keys=True, default=_json_default))


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def atomic_save_npz(path: Path, **arrays: np.ndarray) -> None:
    """Save arrays as a compressed ``.npz`` atomically."""
    import io

    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def load_npz(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def read_json(path: Path) -> Mapping[str, Any]:
    with open(path, encoding="utf-8") as f:
        return json.load(f)
