"""Content digests of files (cache keys, render manifests, dataset checksums) and of arrays
(the keys of in-process memos)."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np


def file_digest(path: str | Path) -> str:
    """SHA-256 (hex) of a file's bytes, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def arrays_key(arrays: Sequence[np.ndarray], extra: object = ()) -> bytes:
    """A 20-byte BLAKE2b digest of ``arrays`` (each one's dtype, shape and bytes, in order) and
    of ``repr(extra)``: the key of what an in-process memo's computation read (not a file format:
    it may change between versions)."""
    h = hashlib.blake2b(digest_size=20)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(repr((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    h.update(repr(extra).encode())
    return h.digest()


__all__ = ["arrays_key", "file_digest"]
