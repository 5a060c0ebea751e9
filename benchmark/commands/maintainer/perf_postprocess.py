"""``python -m benchmark.commands.maintainer.perf_postprocess``: post-processing time per house, on noisy
ground truth of the shared ProcTHOR houses or on a runner job's cached raw maps."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from benchmark.commands import cli
from benchmark.paths import procthor_houses
from benchmark.postprocess import PostProcess, noisy_ground_truth


def time_postprocess(path: str | Path, houses: int = 150, noise: float = 0.2, resolution: float = 0.05,
                     repeat: int = 3) -> list[dict]:
    """Time :class:`PostProcess` (defaults) on the first ``houses`` houses of ``path``: input
    = ground truth rasterised at ``resolution`` m/px with ``noise`` salt-and-pepper. One row
    per house: id, pixels, best-of-``repeat`` milliseconds, agreement with ground truth
    before/after (fraction of walkable pixels)."""
    from envs.datasets.house_files import load_houses
    from envs.maps.scene import rasterise_house

    pp = PostProcess()
    rows = []
    for i, h in enumerate(load_houses(path, 0, houses)):
        s = rasterise_house(h, resolution=resolution)
        walk = s.grid.walkable
        lab = noisy_ground_truth(s.semantic, walk, len(s.classes), noise, i)
        best = float("inf")
        for _ in range(repeat):
            t = time.perf_counter()
            out = pp(lab, s.grid)
            best = min(best, time.perf_counter() - t)
        rows.append({"house": h.id, "pixels": walk.size, "ms": 1e3 * best,
                     "agree_before": float(np.mean(lab[walk] == s.semantic[walk])),
                     "agree_after": float(np.mean(out[walk] == s.semantic[walk]))})
    return rows


def time_postprocess_job(job_dir: str | Path, repeat: int = 3) -> list[dict]:
    """Time :class:`PostProcess` (defaults) on the raw label maps a finished runner job cached
    (``run.save_maps``; e.g. a ``postprocess=none`` job of ``benchmark.harness.runner``). One row per
    house: id, pixels, best-of-``repeat`` milliseconds."""
    from hydra.utils import instantiate

    from benchmark.harness.cache import load_npz
    from benchmark.harness.store import Job

    job = Job(Path(job_dir))
    if not job.summary_path.exists() or not job.config_path.exists():
        raise FileNotFoundError(f"{job_dir} is not a finished runner job (summary.json + resolved_config.yaml)")
    cfg = job.config()
    env, pp, rows = instantiate(cfg.env), PostProcess(classes=list(cfg.classes)), []
    for hid in job.house_ids():
        path = job.maps_path(hid)
        if not path.exists():
            continue
        raw, grid = load_npz(path)["raw"].astype(np.int32), env.scene(hid).grid
        best = float("inf")
        for _ in range(repeat):
            t = time.perf_counter()
            pp(raw, grid)
            best = min(best, time.perf_counter() - t)
        rows.append({"house": hid, "pixels": grid.walkable.size, "ms": 1e3 * best})
    if not rows:
        raise FileNotFoundError(f"no cached label maps of the {len(job.house_ids())} houses of {job_dir} "
                                f"(run.save_maps=false, or the cache under {job.cache().root} was removed)")
    return rows


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmark.commands.maintainer.perf_postprocess``: post-processing time per house."""
    default = procthor_houses()
    ap = cli.ArgumentParser(from_root=True, description="time the default post-processing per house: on noisy ground truth "
                                 "of the shared ProcTHOR houses, or on a runner job's cached raw maps (--job)")
    ap.add_argument("--data", type=Path, default=default)
    ap.add_argument("--houses", type=int, default=150)
    ap.add_argument("--noise", type=float, default=0.2, help="fraction of walkable pixels set to a random label")
    ap.add_argument("--resolution", type=float, default=0.05, help="input map metres per pixel")
    ap.add_argument("--job", type=Path, default=None, help="a finished runner job folder: time on its raw maps")
    a = ap.parse_args(argv)
    if a.job is not None:
        rows = time_postprocess_job(a.job)
        what = f"cached raw maps of {a.job}"
    else:
        if not a.data.exists():
            print(f"error: shared ProcTHOR houses not found at {a.data} (set ROOMSEG_SHARED_DATA or --data)")
            return 2
        rows = time_postprocess(a.data, a.houses, a.noise, a.resolution)
        before = np.mean([r["agree_before"] for r in rows])
        after = np.mean([r["agree_after"] for r in rows])
        what = (f"ground truth at {a.resolution:g} m/px with {a.noise:.0%} noise (agreement with ground truth "
                f"{before:.1%} -> {after:.1%})")
    ms = np.array([r["ms"] for r in rows])
    px = np.array([r["pixels"] for r in rows])
    print(f"{len(rows)} houses (median {np.median(px):.0f} px), {what}: post-process median "
          f"{np.median(ms):.1f} ms, p90 {np.percentile(ms, 90):.1f} ms, max {ms.max():.1f} ms (best of 3 per house)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
