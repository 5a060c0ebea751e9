"""One house through the stages, with caches: scene -> viewpoints -> render -> classify ->
aggregate -> post-process -> score (or scene -> segmenter -> score for geometric baselines).

Independent of Hydra: :mod:`benchmark.harness.runner` builds a :class:`Pipeline` from the config.
Cache layout: :mod:`benchmark.harness.store` (keys: :func:`benchmark.harness.cache.config_key`).
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from benchmark.harness.cache import (
    atomic_save_npz,
    atomic_write_json,
    load_npz,
    locked,
    read_json,
)
from benchmark.harness.store import CacheStore
from envs.datasets.base import Environment
from envs.render.observation import poses_array

#: Stages that ``force`` can name, in pipeline order; forcing one forces those after it.
STAGES = ("render", "classify", "score")


def expand_force(force: Sequence[str] | str | None) -> set[str]:
    """``force`` option -> the set of stages to redo (a stage implies the ones after it)."""
    if force is None:
        return set()
    if isinstance(force, str):
        force = [force]
    items = [str(f) for f in force]
    if "all" in items:
        return set(STAGES)
    unknown = sorted(set(items) - set(STAGES))
    if unknown:
        raise ValueError(f"run.force: unknown stage(s) {unknown}; expected a list of {list(STAGES)} or 'all'")
    first = min(STAGES.index(f) for f in items) if items else len(STAGES)
    return set(STAGES[first:])


@dataclass
class Pipeline:
    """The stages of one configuration and where their caches live.

    ``names`` are the short stage names written into every row (``env``, ``viewpoints``,
    ``renderer``, ``classifier``, ``aggregator``, ``postprocess``, ``segmenter``);
    ``keys`` the cache keys (``render``, ``classify``, ``score``); ``extra`` more columns.
    """

    env: Environment
    cache_dir: Path
    keys: dict[str, str]
    names: dict[str, str]
    metric_params: Any
    viewpoints: Any = None
    renderer: Any = None
    classifier: Any = None
    aggregator: Any = None
    postprocess: Any = None
    segmenter: Any = None
    force: set[str] = field(default_factory=set)
    save_maps: bool = True
    extra: dict[str, Any] = field(default_factory=dict)

    # ---- paths (the run store knows the layout)
    @property
    def store(self) -> CacheStore:
        return CacheStore(Path(self.cache_dir))

    def _render_dir(self, hid: str) -> Path:
        return self.store.render_dir(self.keys["render"], hid)

    def _classify_path(self, hid: str) -> Path:
        return self.store.classify_path(self.keys["classify"], hid)

    def score_path(self, hid: str) -> Path:
        return self.store.score_path(self.keys["score"], hid)

    def maps_path(self, hid: str) -> Path:
        return self.store.maps_path(self.keys["score"], hid)

    # ---- stages
    def _observations(self, hid: str, scene, timings: dict) -> list:
        from envs.render import cache as render_cache

        folder = self._render_dir(hid)
        with locked(folder):
            if "render" not in self.force and render_cache.is_complete(folder):
                t = time.perf_counter()
                obs = render_cache.read_observations(folder)
                timings["t_render_load"] = time.perf_counter() - t
                return obs
            t = time.perf_counter()
            poses = poses_array(self.viewpoints.generate(scene))
            timings["t_viewpoints"] = time.perf_counter() - t
            if len(poses) == 0:
                raise ValueError(f"viewpoints {self.names.get('viewpoints')!r} produced no poses for house {hid!r}")
            t = time.perf_counter()
            obs = self.renderer.render(self.env.house(hid), scene, poses)
            timings["t_render"] = time.perf_counter() - t
            render_cache.write_observations(folder, obs)
            return obs

    def _classified(self, hid: str, scene, timings: dict) -> tuple[np.ndarray, np.ndarray, int]:
        path = self._classify_path(hid)
        with locked(path):
            if "classify" not in self.force and path.exists():
                z = load_npz(path)
                return z["poses"], z["proba"], int(z["n_refused"])
            obs = self._observations(hid, scene, timings)
            kept = [o for o in obs if not o.meta.get("refused", False)]
            n_refused = len(obs) - len(kept)
            if not kept:
                raise ValueError(f"house {hid!r}: every one of {len(obs)} views was refused by the renderer")
            t = time.perf_counter()
            proba = np.asarray(self.classifier.predict_proba(kept), dtype=np.float64)
            timings["t_classify"] = time.perf_counter() - t
            n_cls = len(getattr(self.classifier, "classes", proba.shape[1:] or [0]))
            if proba.shape != (len(kept), n_cls):
                raise ValueError(
                    f"classifier {self.names.get('classifier')!r} returned shape {proba.shape}, "
                    f"expected ({len(kept)}, {n_cls})")
            poses = poses_array([o.pose for o in kept])
            atomic_save_npz(path, poses=poses, proba=proba, n_refused=np.array(n_refused))
            return poses, proba, n_refused

    def run_house(self, hid: str) -> dict[str, Any]:
        """Compute (or load) the metrics row of one house. Exceptions become a failed row."""
        path = self.score_path(hid)
        if "score" not in self.force and path.exists():
            return dict(read_json(path))
        with locked(path):
            if "score" not in self.force and path.exists():
                return dict(read_json(path))
            row = self._row_base(hid)
            timings: dict[str, float] = {}
            try:
                row.update(self._compute(hid, timings))
                row["status"] = "ok"
                row["error"] = ""
            except Exception as e:  # one bad house fails alone; its reason is recorded
                row["status"] = "failed"
                row["error"] = f"{type(e).__name__}: {e}".strip()[:500]
                row["traceback"] = traceback.format_exc(limit=6)[-2000:]
            row.update({k: round(v, 6) for k, v in timings.items()})
            atomic_write_json(path, row)
            return row

    def _row_base(self, hid: str) -> dict[str, Any]:
        row: dict[str, Any] = {"house_id": hid, "dataset": getattr(self.env, "name", "env")}
        row.update(self.names)
        row.update(self.extra)
        row["score_key"] = self.keys["score"]
        return row

    def _compute(self, hid: str, timings: dict) -> dict[str, Any]:
        from benchmark.metrics import score_instances, score_semantic

        t = time.perf_counter()
        scene = self.env.scene(hid)
        timings["t_scene"] = time.perf_counter() - t
        out: dict[str, Any] = {}
        if self.segmenter is not None:
            t = time.perf_counter()
            inst = self.segmenter(scene.grid)
            timings["t_segment"] = time.perf_counter() - t
            t = time.perf_counter()
            out.update(score_instances(inst, scene.instances, self.metric_params))
            timings["t_score"] = time.perf_counter() - t
            if self.save_maps:
                atomic_save_npz(self.maps_path(hid), instances=inst.astype(np.int32))
            return out
        poses, proba, n_refused = self._classified(hid, scene, timings)
        t = time.perf_counter()
        raw = self.aggregator(scene.grid, poses, proba)
        timings["t_aggregate"] = time.perf_counter() - t
        t = time.perf_counter()
        post = self.postprocess(raw, scene.grid) if self.postprocess is not None else raw
        timings["t_postprocess"] = time.perf_counter() - t
        t = time.perf_counter()
        out.update(score_semantic(post, scene.instances, scene.instance_classes, self.metric_params,
                                  classes=list(scene.classes)))
        timings["t_score"] = time.perf_counter() - t
        out["n_views"] = int(len(poses))
        out["n_refused"] = int(n_refused)
        out["view_accuracy"] = _view_accuracy(scene, poses, proba)
        if self.save_maps:
            atomic_save_npz(self.maps_path(hid), raw=raw.astype(np.int16), post=post.astype(np.int16),
                            poses=poses, proba=proba.astype(np.float32))
        return out

    def run(self, house_ids: Sequence[str], progress: Callable | None = None) -> list[dict[str, Any]]:
        """Rows for ``house_ids`` in order; ``progress`` wraps the iterable (e.g. tqdm)."""
        it = progress(house_ids) if progress else house_ids
        return [self.run_house(h) for h in it]


def _view_accuracy(scene, poses: np.ndarray, proba: np.ndarray) -> float:
    """Share of views whose top class equals the ground-truth class of the cell they stand on
    (views on unlabelled cells are left out); NaN when no view stands on a room."""
    r, c = scene.grid.world_to_cell(poses[:, 0], poses[:, 1])
    ok = scene.grid.in_bounds(r, c)
    sem = scene.semantic
    truth = np.full(len(poses), -1)
    truth[ok] = sem[r[ok], c[ok]]
    m = truth >= 0
    if not m.any():
        return float("nan")
    return float(np.mean(proba[m].argmax(axis=1) == truth[m]))
