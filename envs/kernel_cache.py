"""numba's on-disk cache of the project's kernels, kept only while every kernel module is as it was.

numba keeps a kernel's machine code on disk (``cache=True``) under a stamp of the content of
the one file that defines it. A kernel also holds the code of the kernels it calls or
inlines from other modules (the ray walks of :mod:`envs.maps.rays` and
:mod:`envs.maps.ray_paths` in the vision cone, the renderer and the scan maps) and the
constants it reads from them, so after a change to one of those modules alone (an edit, a
``git pull``) numba would go on loading the old code: results from code that is no longer
there. Here the stamp of every kernel of the project's packages also covers the content of
all their kernel modules (the modules that import :func:`njit` from here): a change to any
of them makes every kernel compile again, once (``make setup`` does it ahead of a run:
:mod:`benchmark.commands.compile_kernels`). Kernels of other packages keep numba's own stamp.

A kernel may call only kernels, and read only constants of kernel modules (the test suite
checks both), so nothing a kernel's code depends on lies outside the stamp.

Usage, in every module that defines kernels::

    from envs.kernel_cache import njit  # numba's njit; importing this module keys the cache
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
from pathlib import Path

from numba import njit
from numba.core import caching

#: the packages whose kernels the stamp covers (found without importing them)
KERNEL_PACKAGES = ("envs", "benchmark")
#: the line that makes a module a kernel module
MARKER = "from envs.kernel_cache import njit"


@functools.lru_cache(maxsize=1)
def package_dirs() -> tuple[Path, ...]:
    """The directories of :data:`KERNEL_PACKAGES` (those found)."""
    out = []
    for name in KERNEL_PACKAGES:
        spec = importlib.util.find_spec(name)
        for loc in (spec.submodule_search_locations or []) if spec is not None else []:
            out.append(Path(loc).resolve())
    return tuple(out)


def _kernel_sources() -> list[tuple[str, Path, bytes]]:
    """(path within its package, path, content) of every kernel module of :data:`KERNEL_PACKAGES`
    (files holding :data:`MARKER`), sorted by path; each file read once."""
    marker = MARKER.encode()
    out = []
    for d in package_dirs():
        for p in d.rglob("*.py"):
            if "__pycache__" not in p.parts and marker in (data := p.read_bytes()):
                out.append((f"{d.name}/{p.relative_to(d).as_posix()}", p, data))
    return sorted(out, key=lambda t: t[1])


def kernel_modules() -> list[Path]:
    """The kernel modules of :data:`KERNEL_PACKAGES` (files holding :data:`MARKER`), sorted."""
    return [p for _, p, _ in _kernel_sources()]


@functools.lru_cache(maxsize=1)
def kernel_sources_digest() -> str:
    """SHA-256 of every kernel module's path (within its package) and content, read once per
    process (when the first kernel module is imported)."""
    h = hashlib.sha256()
    for name, _, data in _kernel_sources():
        h.update(f"{name}\0".encode())
        h.update(data)
        h.update(b"\0")
    return h.hexdigest()


def in_packages(py_file: str) -> bool:
    """Whether ``py_file`` lies in one of :data:`KERNEL_PACKAGES`."""
    try:
        path = Path(py_file).resolve()
    except (OSError, RuntimeError):
        return False
    return any(path.is_relative_to(d) for d in package_dirs())


class _AllKernelModules:
    """A numba cache locator for the kernels of :data:`KERNEL_PACKAGES`: numba's own place and
    stamp (the defining file's content), with the digest of every kernel module added to the
    stamp; None for any other function (numba's locators take it)."""

    def get_source_stamp(self):
        return super().get_source_stamp(), kernel_sources_digest()

    @classmethod
    def from_function(cls, py_func, py_file):
        if not in_packages(py_file):
            return None
        return super().from_function(py_func, py_file)


def _numba_class(name: str):
    """numba's class ``name`` of :mod:`numba.core.caching` (``_name`` in older numba versions)."""
    return getattr(caching, name, None) or getattr(caching, "_" + name)


class UserProvidedLocator(_AllKernelModules, _numba_class("UserProvidedCacheLocator")):
    """``NUMBA_CACHE_DIR``, when set."""


class InTreeLocator(_AllKernelModules, _numba_class("InTreeCacheLocator")):
    """``__pycache__`` beside the module."""


class UserWideLocator(_AllKernelModules, _numba_class("UserWideCacheLocator")):
    """The user's cache directory, where ``__pycache__`` is not writable."""


LOCATORS = (UserProvidedLocator, InTreeLocator, UserWideLocator)


def install() -> None:
    """Put :data:`LOCATORS` ahead of numba's own (idempotent: those of an earlier load of this
    module are taken out first)."""
    classes = _numba_class("CacheImpl")._locator_classes
    classes[:] = [c for c in classes if c.__module__ != __name__]
    classes[:0] = LOCATORS


install()

__all__ = ["KERNEL_PACKAGES", "LOCATORS", "MARKER", "install", "in_packages", "kernel_modules", "kernel_sources_digest",
           "njit", "package_dirs"]
