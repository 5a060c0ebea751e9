"""numba's cache of the project's kernels follows the content of every kernel module
(:mod:`envs.kernel_cache`): a kernel that inlines a helper of another module is compiled
again when only that module changed, instead of numba loading its old machine code."""

from __future__ import annotations

import hashlib
import inspect
import os
import re
import shutil
import subprocess
import sys
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_every_kernel_module_takes_njit_from_the_kernel_cache():
    """No module of the packages takes numba's njit (or jit) itself, and every kernel the
    warm-up compiles lives in a module the stamp covers."""
    from benchmark.commands.compile_kernels import kernels
    from envs.kernel_cache import kernel_modules

    direct = []
    for pkg in ("envs", "benchmark"):
        for p in (ROOT / pkg).rglob("*.py"):
            if p.name == "kernel_cache.py" or "__pycache__" in p.parts:
                continue
            text = p.read_text(encoding="utf-8")
            if re.search(r"^\s*from numba import .*\b(njit|jit)\b|numba\.(njit|jit)\(", text, re.M):
                direct.append(str(p.relative_to(ROOT)))
    assert direct == []
    covered = {p.resolve() for p in kernel_modules()}
    files = {Path(inspect.getfile(d.py_func)).resolve() for d in kernels().values()}
    assert len(files) >= 15 and files <= covered


def test_kernels_read_only_constants_defined_in_kernel_modules():
    """Every global constant a kernel reads (numba freezes it into the machine code) is
    assigned at the top of a kernel module, so a change to it changes the stamp."""
    from benchmark.commands.compile_kernels import kernels
    from envs.kernel_cache import kernel_modules

    sources = "\n".join(p.read_text(encoding="utf-8") for p in kernel_modules())

    def names(code: types.CodeType) -> set[str]:
        out = set(code.co_names)
        for c in code.co_consts:
            if isinstance(c, types.CodeType):
                out |= names(c)
        return out

    read = set()
    for d in kernels().values():
        f = d.py_func
        for n in names(f.__code__):
            v = f.__globals__.get(n)
            if v is not None and not isinstance(v, types.ModuleType) and not callable(v):
                read.add(n)
    assert read >= {"FREE", "CONE_END_TOL"}  # (the check sees them)
    for n in read:  # NAME = ..., NAME: type = ..., or A, NAME, B = ...
        assigned = rf"^(?:\w+\s*,\s*)*{n}\b(?:\s*,\s*\w+)*\s*(?::[^=\n]*)?=[^=]"
        assert re.search(assigned, sources, re.M), f"{n}, read by a kernel, is not assigned in a kernel module"


def test_the_stamp_is_numbas_own_and_the_digest_of_every_kernel_module():
    """A kernel's stamp pairs numba's own stamp of its file with the digest; the digest is
    that of the kernel modules' paths and contents, written out here."""
    import benchmark.aggregators.vision_cone as vc
    from envs.kernel_cache import (
        InTreeLocator,
        UserProvidedLocator,
        kernel_modules,
        kernel_sources_digest,
    )

    locator = vc._cone_votes._cache._impl.locator
    assert isinstance(locator, (InTreeLocator, UserProvidedLocator))
    own, digest = locator.get_source_stamp()
    numbas = type(locator).__mro__[2]  # numba's locator class the project's one extends
    assert numbas.__module__ == "numba.core.caching" and own == numbas.get_source_stamp(locator)
    h = hashlib.sha256()
    for p in kernel_modules():
        rel = p.resolve().relative_to(ROOT).as_posix()
        h.update(f"{rel}\0".encode() + p.read_bytes() + b"\0")
    assert digest == kernel_sources_digest() == h.hexdigest()
    assert "envs/maps/ray_paths.py" in {p.resolve().relative_to(ROOT).as_posix() for p in kernel_modules()}


#: a subprocess's vision-cone votes on a fixed map, as a hash
VOTES = """
import hashlib, numpy as np
from benchmark.aggregators.vision_cone import VisionCone
from envs.maps.gridmap import GridMap
walk = np.ones((60, 80), bool)
walk[:, 40] = False
walk[20:26, 40] = True  # two rooms and a door
grid = GridMap(walk, 0.1, (0.0, 6.0))
rng = np.random.default_rng(3)
rr, cc = np.nonzero(walk)
pick = rng.choice(len(rr), 12, replace=False)
poses = np.array([[*grid.pixel_to_world(rr[i], cc[i]), rng.uniform(0, 360)] for i in pick], float)
counts = VisionCone(max_range_m=3.0, blocked_ray_m=0.0).votes(grid, poses, rng.dirichlet(np.ones(4), 12))
print(hashlib.sha256(counts.tobytes()).hexdigest(), int(counts.sum()))
"""


def _votes(root: Path, cache: Path) -> str:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(PYTHONPATH=str(root), NUMBA_CACHE_DIR=str(cache))
    p = subprocess.run([sys.executable, "-c", VOTES], cwd=root, env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    return p.stdout.strip()


def _cache_files(cache: Path) -> dict[str, int]:
    return {str(p.relative_to(cache)): p.stat().st_mtime_ns for p in cache.rglob("*") if p.is_file()}


@pytest.mark.slow
def test_a_change_to_an_inlined_helpers_module_alone_compiles_the_kernel_again(tmp_path):
    """A copy of the packages: the cone's votes, then the same from numba's cache (nothing
    written), then with a helper the cone's kernel inlines changed in envs/maps/ray_paths.py
    only: the votes are those of the changed code (as from an empty cache), not the old
    machine code's."""
    from benchmark.aggregators.vision_cone import VisionCone  # noqa: F401 - (the module this test is about)

    copy = tmp_path / "src"
    for pkg in ("envs", "benchmark"):
        shutil.copytree(ROOT / pkg, copy / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    cache = tmp_path / "numba-cache"
    first = _votes(copy, cache)
    files = _cache_files(cache)
    assert files and _votes(copy, cache) == first and _cache_files(cache) == files  # loaded, not compiled
    helper = copy / "envs" / "maps" / "ray_paths.py"
    text = helper.read_text(encoding="utf-8")
    # a ray after one that saw its whole path sees nothing beyond its camera, nor do the rays after it
    changed = text.replace("return 0 if seen else (pstop if on else 0), n if seen else",
                           "return 0 if seen else (pstop if on else 0), 0 if seen else")
    assert changed != text
    helper.write_text(changed, encoding="utf-8")
    after = _votes(copy, cache)
    assert after == _votes(copy, tmp_path / "empty-cache") and after != first
