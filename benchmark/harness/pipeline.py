"""One house through the stages, with caches. Two paths:

- :class:`MethodPipeline` (the method): scene -> viewpoints -> render -> classify ->
  aggregate -> post-process -> score;
- :class:`SegmenterPipeline` (geometric baselines): scene -> segmenter -> score.

Every cached stage goes through one helper, :meth:`Pipeline._cached`: lock the entry, load
it if present and valid (a bad entry is recomputed with one warning naming the file),
otherwise compute, time and save it atomically. Stages are built from their factories only
when a house needs them, so a fully cached job builds no renderer and no classifier.
Failures are not cached as results: a failed house is retried on the next run (its last
failure is logged under ``failures/`` beside the cache); ``cache_failures=True`` serves the
logged failure instead (for expensive deterministic failures).

Independent of Hydra: :mod:`benchmark.harness.runner` builds a pipeline from the config.
Cache layout: :mod:`benchmark.harness.store`; keys and content hashes:
:mod:`benchmark.harness.cache`.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np

from benchmark import method
from benchmark.harness.cache import (
    atomic_save_npz,
    content_hash,
    file_fingerprint,
    leaf_inputs,
    load_npz,
    locked,
    path_leaves,
    read_entry,
    write_entry,
)
from benchmark.harness.entries import (
    BadEntry,
    check_classified,
    check_labels_entry,
    check_poses,
    check_render,
    check_seen,
    seen_from_render,
)
from benchmark.harness.robot_stages import RobotStages, _read_only
from benchmark.harness.run_settings import STAGES
from benchmark.harness.store import CacheStore
from benchmark.interfaces import Aggregator, Classifier, PostProcessor, Segmenter, Viewpoints
from benchmark.view_accuracy import seen_accuracy, true_labels, view_accuracy
from envs.atomic import file_identity
from envs.datasets.base import Environment
from envs.memo import ByteLRU
from envs.render.base import Renderer
from envs.render.observation import poses_array

log = logging.getLogger("roomseg-bench")
T = TypeVar("T")

#: scenes kept per process (see :meth:`Pipeline.scene`): (env key, house id) -> Scene.
_SCENES = ByteLRU()
#: the most memory (MiB) one process's scenes hold, the least recently used dropped first:
#: ``$ROOMSEG_SCENE_CACHE_MB``, else 512 in a job of a multirun (a shared ProcTHOR house at
#: 0.05 m/px holds under 1 MB by :func:`scene_bytes`, so a grid's workers keep both datasets'
#: houses and rasterise each once per sweep) and 64 in a single run (which reads each house
#: once: its memory stays flat in the number of houses).
SCENE_CACHE_MB = 512
SCENE_CACHE_MB_SINGLE = 64


def scene_bytes(scene: Any) -> int:
    """Memory a scene's arrays hold (its grid's, ground truth's, walls', objects' and doors'), in bytes."""
    total, seen = 0, set()

    def add(v: Any) -> None:
        nonlocal total
        if isinstance(v, np.ndarray) and id(v) not in seen:
            seen.add(id(v))
            total += v.nbytes
    for v in vars(scene).values() if hasattr(scene, "__dict__") else ():
        add(v)
        if isinstance(v, dict):
            for x in v.values():
                add(x)
        elif isinstance(v, list | tuple):
            total += 1024 * len(v)  # an object's footprint and fields
        elif hasattr(v, "__dict__"):
            for x in vars(v).values():
                add(x)
    return total


def scene_cache_limit() -> int:
    """Bytes the scenes of this process may hold (:data:`SCENE_CACHE_MB`).

    Raises:
        ValueError: ``ROOMSEG_SCENE_CACHE_MB`` is not a number >= 0 (one line)."""
    from benchmark.harness.sweep import current_sweep

    raw = os.environ.get("ROOMSEG_SCENE_CACHE_MB", "")
    try:
        mb = float(raw) if raw else SCENE_CACHE_MB if current_sweep() else SCENE_CACHE_MB_SINGLE
    except ValueError:
        raise ValueError(f"ROOMSEG_SCENE_CACHE_MB={raw!r}: expected a number of MiB >= 0") from None
    if not mb >= 0:
        raise ValueError(f"ROOMSEG_SCENE_CACHE_MB={raw!r}: expected a number of MiB >= 0")
    return int(mb * 2**20)


#: bytes of classify entries one process keeps (:data:`_CLASSIFIED_MEMO`; a house's views and
#: their class probabilities: about 25 kB)
CLASSIFIED_MEMO_BYTES = 32 * 2**20
#: kept per process, read-only: (classify entry path, identity of the file) -> its arrays as
#: read (:func:`classify_arrays`). Every method of every robot condition on one render and
#: classifier uses the same entry; each job still checks what it gets against its classes and
#: its render's views. A rewritten entry (atomic renames: another file) has another identity.
_CLASSIFIED_MEMO = ByteLRU()


def classify_arrays(path: Path) -> dict[str, np.ndarray]:
    """The arrays of the classify entry at ``path`` (:func:`benchmark.harness.cache.load_npz`:
    its checksum checked), read once per process and file (:data:`_CLASSIFIED_MEMO`): read-only.

    Raises:
        FileNotFoundError, ChecksumError: as :func:`load_npz`."""
    ident = file_identity(path)  # the file as it is before the read (see _render_table)
    key = (str(path), ident)
    kept = _CLASSIFIED_MEMO.get(key) if ident is not None else None
    if kept is not None:
        return kept
    z = load_npz(path)
    if ident is not None:
        _CLASSIFIED_MEMO.put(key, z, _read_only(*z.values()) + 1024, CLASSIFIED_MEMO_BYTES)
    return z


#: house content hashes kept per process, like scenes: (env key, house id) -> hex string.
_HOUSE_CONTENTS: dict[tuple[str, str], str] = {}

#: metrics every successful row carries, each in [0, 1] (accuracy may be NaN: segmenters).
ROW_METRICS = ("iou", "precision", "recall")



class StageError(RuntimeError):
    """A stage that cannot be built, or does not fit the environment (e.g. another class
    order): no house's fault, so the run stops with this one-line message."""


def expand_force(force: Sequence[str] | str | None) -> set[str]:
    """``force`` option -> the set of stages to redo (a stage implies the ones after it).

    Raises:
        ValueError: an unknown stage name (one line naming it and the allowed ones)."""
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


def house_content(env: Environment, house_id: str) -> str:
    """Content hash of one house: what every cache entry of the house depends on.

    An environment may define ``content_key(house_id) -> str`` (used as is); otherwise the
    hash covers the house's JSON (``env.house(id).data``) and, when the environment defines
    ``input_files(house_id) -> list of paths``, those files' fingerprints
    (:func:`benchmark.harness.cache.file_fingerprint`).

    A house that ``env.house`` refuses (malformed) gets the hash of that error instead: its
    failure is logged under that content, and a repaired house has new content.

    Returns:
        A hex string (16 digits for the default rule).
    """
    own = getattr(env, "content_key", None)
    if callable(own):
        return str(own(house_id))
    try:
        house = env.house(house_id)
    except Exception as e:  # noqa: BLE001 - the house fails alone when its scene is built
        return content_hash(["unreadable house", _one_line(e)])
    parts: list[Any] = [getattr(house, "data", house)]
    files = getattr(env, "input_files", None)
    if callable(files):
        parts.append({str(p): file_fingerprint(p) for p in files(house_id)})
    return content_hash(parts)


@dataclass
class Pipeline(RobotStages):
    """The stages of one configuration, built on first use, and where their caches live.

    Args:
        env: the houses.
        cache_dir: ``run.cache_dir``.
        keys: the stages' config keys (``render``, ``classify``, ``score``).
        names: short stage names written into every row (``env``, ``viewpoints``, ...).
        metric_params: :class:`benchmark.metrics.MetricParams`.
        builders: stage name -> zero-argument factory (``None``: the stage is absent).
        inputs: stage name -> the stage's plain config, searched for input files whose
            content goes into the house's cache entries (:func:`config_inputs`).
        force: stages to recompute (see :func:`expand_force`).
        save_maps: keep label maps for figures.
        cache_aggregates: keep each house's aggregated label map in the cache (``run.cache_aggregates``).
        extra: more columns for every row.
        cache_failures: serve a house's logged failure instead of retrying it.
        classes: the environment's ordered class names; a classifier with other names or
            another order stops the run (:class:`StageError`).
        eval_ids: the houses of this run (a classifier's ``setup`` refuses training houses).
        env_key: a key that names ``env``'s config and input files (set by the runner, which
            reuses environments across jobs): scenes are then cached per process.
    """

    env: Environment
    cache_dir: Path
    keys: dict[str, str]
    names: dict[str, str]
    metric_params: Any
    builders: Mapping[str, Callable[[], Any] | None] = field(default_factory=dict)
    inputs: Mapping[str, Any] = field(default_factory=dict)
    force: set[str] = field(default_factory=set)
    save_maps: bool = True
    cache_aggregates: bool = True
    extra: dict[str, Any] = field(default_factory=dict)
    cache_failures: bool = False
    classes: tuple[str, ...] | None = None
    eval_ids: Sequence[str] = ()
    env_key: str | None = None
    _stages: dict[str, Any] = field(default_factory=dict, repr=False)
    _contents: dict[str, dict[str, str]] = field(default_factory=dict, repr=False)
    _leaves: dict[str, tuple[tuple[str, str], ...]] = field(default_factory=dict, repr=False)
    _frames: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict, repr=False)
    _entries: dict[tuple[str, str, str], Path] = field(default_factory=dict, repr=False)

    #: the stage groups whose input files feed each cached stage, in order.
    CONTENT_STAGES: ClassVar[tuple[tuple[str, tuple[str, ...]], ...]] = ()

    # ---- stages, built on first use
    def stage(self, name: str) -> Any:
        """The stage ``name``, built by its factory the first time it is asked for.

        Raises:
            StageError: the factory fails, or a classifier's classes differ from ``classes``."""
        if name not in self._stages:
            build = self.builders.get(name)
            if build is None:
                self._stages[name] = None
                return None
            try:
                obj = build()
            except Exception as e:
                raise StageError(f"{name} {self.names.get(name, '')!r} could not be built: "
                                 f"{type(e).__name__}: {e}") from e
            if name == "classifier":
                self._check_classes(obj)
                self._fit_cached(obj)
                if hasattr(obj, "setup"):
                    try:
                        obj.setup(list(self.eval_ids))
                    except ValueError as e:
                        raise StageError(str(e)) from e
            self._stages[name] = obj
        return self._stages[name]

    def built(self) -> list[str]:
        """Names of the stages built so far (a fully cached job builds none)."""
        return [k for k, v in self._stages.items() if v is not None]

    def _fit_cached(self, clf: Any) -> None:
        """Fit a classifier that offers ``training_key/fit/save/load`` (the objects classifier),
        or load its fitted model from ``models/`` in the cache, keyed by its training set's
        content. ``force`` of ``classify`` refits."""
        if not all(callable(getattr(clf, m, None)) for m in ("training_key", "fit", "save", "load")):
            return
        if getattr(clf, "fitted", False):
            return
        path = self.store.model_path(type(clf).__name__, clf.training_key())
        self._cached("classify", path, clf.load, clf.fit, lambda p, c: c.save(p))

    def _check_classes(self, clf: Any) -> None:
        got = tuple(getattr(clf, "classes", ()) or ())
        if self.classes is not None and got != tuple(self.classes):
            raise StageError(f"classifier {self.names.get('classifier', '')!r} has classes {list(got)}, but the "
                             f"environment has {list(self.classes)}: names and order must be equal "
                             f"(set the classifier's `classes` to ${{classes}})")

    # ---- content of a house's entries
    def contents(self, hid: str) -> dict[str, str]:
        """Per cached stage, the content hash of house ``hid``'s entry: the house's content
        and the input files of every stage up to that one. Memoised per house; with
        ``env_key`` set and no per-house ``input_files``, the house's own hash is kept per
        process as scenes are."""
        if hid not in self._contents:
            if self.env_key is None or callable(getattr(self.env, "input_files", None)):
                house = house_content(self.env, hid)  # (per-house files are fingerprinted each time)
            else:  # a shared environment, whose key names its config and input files
                key = (self.env_key, hid)
                if key not in _HOUSE_CONTENTS:
                    _HOUSE_CONTENTS[key] = house_content(self.env, hid)
                house = _HOUSE_CONTENTS[key]
            out, acc = {}, house
            for stage, groups in self.CONTENT_STAGES:
                # groups that are not set (no robot map, no pose error, ...) add nothing
                files = {g: self._inputs_of(g, hid) for g in groups if self.inputs.get(g) is not None}
                acc = content_hash([acc, stage, files])
                out[stage] = acc
            if self.inputs.get("mapping") is not None:  # the robot's map: the house, its views, the mapping
                files = {g: self._inputs_of(g, hid) for g in ("viewpoints", "mapping")}
                out["map"] = content_hash([house, "map", files])
            self._contents[hid] = out
        return self._contents[hid]

    def _inputs_of(self, group: str, hid: str) -> dict[str, str]:
        """:func:`benchmark.harness.cache.config_inputs` of stage ``group``'s config for house
        ``hid``: its path-like strings listed once per pipeline (the configs do not change), the
        files they name checked for each house."""
        if group not in self._leaves:
            self._leaves[group] = path_leaves(self.inputs.get(group))
        return leaf_inputs(self._leaves[group], hid, group)

    def scene(self, hid: str):
        """``env.scene(hid)``; with ``env_key`` set (the runner's key of a shared environment),
        kept in a per-process cache of at most :data:`SCENE_CACHE_MB` so that the jobs of a sweep
        in one worker rasterise each house once. Scenes are read-only to every stage."""
        if self.env_key is None:
            return self.env.scene(hid)
        key = (self.env_key, hid)
        scene = _SCENES.get(key)
        if scene is None:
            scene = self.env.scene(hid)
            _SCENES.put(key, scene, scene_bytes(scene), scene_cache_limit())
        return scene

    @property
    def store(self) -> CacheStore:
        return CacheStore(Path(self.cache_dir))

    def entry(self, kind: str, hid: str) -> Path:
        """Where house ``hid``'s cache entry of ``kind`` lives (:meth:`CacheStore.entry`: render,
        classify, aggregate, score, failure, maps, robot_map, coverage). Kept per pipeline, as the
        house's contents are (a house's stages ask for its entries again and again)."""
        key = (kind, hid, str(self.cache_dir))
        path = self._entries.get(key)
        if path is None:
            path = self._entries[key] = self.store.entry(kind, self.keys, self.contents(hid), hid)
        return path

    # ---- the one cached-stage helper
    def _cached(self, stage: str, path: Path, load: Callable[[Path], T], compute: Callable[[], T],
                save: Callable[[Path, T], None], exists: Callable[[Path], bool] = Path.exists) -> T:
        """Lock ``path``; return its validated entry, or compute, save and return it.

        ``load`` raises on a bad entry (any exception): the entry is recomputed and one
        warning names the file. ``stage`` in ``force`` skips the load. An entry that exists is
        read without the lock first (entries are written by renaming them into place, so a
        reader sees a whole one); a failed read takes the locked path, which says why."""
        if stage not in self.force and exists(path):
            with contextlib.suppress(Exception):
                return load(path)
        with locked(path):
            if stage not in self.force and exists(path):
                try:
                    return load(path)
                except Exception as e:  # noqa: BLE001 - an unreadable entry never aborts a job
                    why = _one_line(e).replace(f"{path}/", "").replace(f"{path}: ", "")
                    log.warning("%s: bad cache entry, recomputing it (%s)", path, why)
            value = compute()
            save(path, value)
            return value

    # ---- one house
    def run_house(self, hid: str) -> dict[str, Any]:
        """The metrics row of one house: from a valid cache entry, or computed (and cached
        when it succeeds). An exception in a house becomes a failed row with its reason;
        :class:`StageError` (a configuration problem) propagates."""
        row = self._row_base(hid)
        timings: dict[str, float] = {}
        try:
            path = self.entry("score", hid)
        except Exception as e:  # noqa: BLE001 - the house itself is unreadable: it fails alone
            return self._failed(row, e, timings)
        if "score" not in self.force:
            with contextlib.suppress(Exception):  # fast path without the lock; checked again under it
                return self._load_row(path, hid)
            if self.cache_failures and self.entry("failure", hid).exists():
                with contextlib.suppress(Exception):
                    failed = dict(read_entry(self.entry("failure", hid)))
                    if failed.get("house_id") == hid and failed.get("status") == "failed":
                        failed.pop("failed_at", None)
                        return failed

        def compute() -> dict[str, Any]:
            try:
                out = dict(row)
                out.update(self._compute(hid, timings))
                out["status"], out["error"] = "ok", ""
            except StageError:
                raise
            except Exception as e:  # noqa: BLE001 - one bad house fails alone; its reason is recorded
                out = self._failed(dict(row), e, timings)
            out.update({k: round(v, 6) for k, v in timings.items()})
            return out

        def save(p: Path, r: dict[str, Any]) -> None:
            if r["status"] == "ok":
                maps = self.entry("maps", hid)
                write_entry(p, r, {"maps": maps} if self.save_maps and maps.exists() else None)
                with contextlib.suppress(FileNotFoundError):
                    self.entry("failure", hid).unlink()
            else:
                write_entry(self.entry("failure", hid), {**r, "failed_at": time.strftime("%Y-%m-%dT%H:%M:%S")})

        try:
            return self._cached("score", path, lambda p: self._load_row(p, hid), compute, save)
        except OSError as e:  # a cache entry of this house cannot be written (name, disk): it fails alone
            where = f" {e.filename}" if e.filename else ""
            err = OSError(e.errno, f"cannot write{where} ({e.strerror or e})")
            return self._failed(self._row_base(hid), err, timings)

    def _failed(self, row: dict[str, Any], e: BaseException, timings: dict[str, float]) -> dict[str, Any]:
        row["status"] = "failed"
        row["error"] = _one_line(e)[:500]
        row["traceback"] = traceback.format_exc(limit=6)[-2000:]
        row.update({k: round(v, 6) for k, v in timings.items()})
        return row

    def _load_row(self, path: Path, hid: str) -> dict[str, Any]:
        """A cached row, checked: its checksum, and that of the saved label maps it vouches for
        (required when the run keeps maps), a JSON object of this house and score key, status
        ok, the stage names of this configuration, and metrics that are numbers in [0, 1]."""
        row = read_entry(path, require=("maps",) if self.save_maps else ())
        if not isinstance(row, dict):
            raise BadEntry(f"expected a JSON object, got {type(row).__name__}")
        want = {"house_id": hid, "status": "ok", "score_key": self.keys["score"], **self.names}
        for k, v in want.items():
            if row.get(k) != v:
                raise BadEntry(f"{k} is {row.get(k)!r}, expected {v!r}")
        for m in (*ROW_METRICS, "accuracy"):
            v = row.get(m)
            if m == "accuracy" and isinstance(v, float) and math.isnan(v):
                continue
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0.0 <= v <= 1.0:
                raise BadEntry(f"{m} is {v!r}, expected a number in [0, 1]")
        # descriptive columns of this run (run.label, ...) are not in the cache key: this run's
        return {**row, **self.extra}

    def _row_base(self, hid: str) -> dict[str, Any]:
        row: dict[str, Any] = {"house_id": hid, "dataset": getattr(self.env, "name", "env")}
        row.update(self.names)
        row.update(self.extra)
        row["score_key"] = self.keys["score"]
        return row

    def _compute(self, hid: str, timings: dict[str, float]) -> dict[str, Any]:
        raise NotImplementedError

    def run(self, house_ids: Sequence[str], progress: Callable | None = None) -> list[dict[str, Any]]:
        """Rows for ``house_ids`` in order; ``progress`` wraps the iterable (e.g. tqdm)."""
        if not self.eval_ids:
            self.eval_ids = tuple(house_ids)
        it = progress(house_ids) if progress else house_ids
        return [self.run_house(h) for h in it]


@dataclass
class MethodPipeline(Pipeline):
    """The method: viewpoints -> render -> classify -> aggregate -> post-process -> score."""

    CONTENT_STAGES: ClassVar[tuple[tuple[str, tuple[str, ...]], ...]] = (
        ("render", ("viewpoints", "renderer")), ("classify", ("classifier",)),
        ("aggregate", ("aggregator", "mapping", "pose_error", "label_noise")), ("score", ("postprocess", "metrics")))
    _method: Any = field(default=None, repr=False)

    @property
    def viewpoints(self) -> Viewpoints:
        return self.stage("viewpoints")

    @property
    def renderer(self) -> Renderer:
        return self.stage("renderer")

    @property
    def classifier(self) -> Classifier:
        return self.stage("classifier")

    @property
    def aggregator(self) -> Aggregator:
        return self.stage("aggregator")

    @property
    def postprocess(self) -> PostProcessor | None:
        return self.stage("postprocess")

    def _observations(self, hid: str, scene, timings: dict) -> list:
        from envs.render import cache as render_cache

        def load(folder: Path) -> list:
            t = time.perf_counter()
            obs = render_cache.read_observations(folder)
            check_render(obs, scene)
            timings["t_render_load"] = time.perf_counter() - t
            return obs

        def compute() -> list:
            t = time.perf_counter()
            poses = poses_array(self.viewpoints.generate(scene))
            timings["t_viewpoints"] = time.perf_counter() - t
            if len(poses) == 0:
                raise ValueError(f"viewpoints {self.names.get('viewpoints')!r} produced no poses for house {hid!r}")
            t = time.perf_counter()
            obs = self.renderer.render(self.env.house(hid), scene, poses)
            timings["t_render"] = time.perf_counter() - t
            return obs

        path = self.entry("render", hid)
        obs = self._cached("render", path, load, compute, render_cache.write_observations, exists=render_cache.is_complete)
        self._keep_render_table(path, render_cache.poses_table(obs))  # the map, route and coverage need no read
        return obs

    @property
    def method(self) -> method.Method:
        """The configuration's :class:`benchmark.method.Method`, its stages built on first use
        (:func:`benchmark.config.build_method` over this pipeline's stages)."""
        if self._method is None:
            from benchmark.config import build_method

            names = {"classifier": repr(self.names.get("classifier")), "aggregator": self.names.get("aggregator")}
            self._method = build_method(self.inputs, stage=self.stage, names=names)
        return self._method

    def _compute(self, hid: str, timings: dict[str, float]) -> dict[str, Any]:
        from benchmark.metrics import score_semantic

        t = time.perf_counter()
        scene = self.scene(hid)
        timings["t_scene"] = time.perf_counter() - t
        unclassed = int((np.asarray(scene.instance_classes) < 0).sum())
        if unclassed:
            raise ValueError(f"house {hid!r}: {unclassed} of {len(scene.instance_classes)} ground-truth rooms have no "
                             f"class, so the method's class scores would be meaningless; give a label ground truth "
                             f"(env.gt_format=label) or score geometry only with a segmenter")
        robot: dict[str, Any] = {}

        def robot_grid():  # after the views exist: the robot's map is built along them
            grid, info = self._robot_grid(hid, scene, self._render_poses(hid) if self.inputs.get("mapping") else None,
                                          timings)
            robot.update(info)
            return grid

        # the camera saw from the true poses; the method receives the poses as the robot's SLAM
        # gives them and the classes as its classifier (and the classifier-noise stage) gives them
        def route():  # a SLAM pose error's route: every view's true pose, the cells it can drive, the scan
            # spacing and what the scan plane hits (the scans its front end matched): the map's estimate's key
            poses, seen = self._render_poses(hid), self._scan_plane(hid, scene)
            if self._slam_shapes_map():  # the estimate the map is built at, from its shared cache entry
                self._slam_estimate(hid, scene, poses, timings, seen)
            return poses, self._route_grid(scene), self._scan_spacing(), seen

        result = self.method.run(lambda: self._observations(hid, scene, timings), robot_grid,
                                 method.Context(scene=scene, house_id=hid, route=route), _HouseCache(self, hid, scene),
                                 timings)
        grid, poses, proba_in, seen = result.grid, result.classified.poses, result.proba, result.classified.seen
        t = time.perf_counter()
        # scored on the ground truth's walkable area: cells the robot's map calls free beyond it
        # are not scored; walkable cells it leaves unknown or occupied are unlabelled (-1)
        gt_instances, gt_walkable = self._ground_truth(hid, scene)  # in the robot map's frame
        scored = np.where(gt_walkable, result.labels, -1)
        out: dict[str, Any] = score_semantic(scored, gt_instances, scene.instance_classes, self.metric_params,
                                             classes=list(scene.classes), resolution=scene.grid.resolution)
        timings["t_score"] = time.perf_counter() - t
        out["n_views"] = int(len(poses))
        out["n_refused"] = int(result.classified.n_refused)
        out["view_accuracy"] = view_accuracy(scene.grid, scene.semantic, poses, proba_in)
        if seen is None:  # a classification cached before it kept what the views see: from the render
            seen = seen_from_render(self.entry("render", hid), poses)
        out["view_accuracy_seen"] = seen_accuracy(seen, proba_in) if seen is not None else float("nan")
        out.update(self._coverage(hid, scene, timings))
        out.update({**ROBOT_VIEW_DEFAULTS, **result.info})
        out.update(robot)
        if self.save_maps:
            extra = {} if grid is scene.grid else {"free": grid.walkable}
            if result.poses is not poses:
                extra["true_poses"] = poses
            atomic_save_npz(self.entry("maps", hid), raw=result.raw.astype(np.int16), post=result.labels.astype(np.int16),
                            poses=result.poses, proba=proba_in.astype(np.float32), **extra)
        return out


#: the view-transform columns of a row when no transform records them (the perfect robot).
ROBOT_VIEW_DEFAULTS = {"pose_error_mean_m": 0.0, "pose_error_max_m": 0.0, "yaw_error_mean_deg": 0.0,
                       "label_noise_share": 0.0}


@dataclass
class _HouseCache:
    """The harness's :class:`benchmark.method.StageCache` for one house: the classification
    (with the views' majority visible class, for the view-accuracy columns) cached per render
    and classifier; the raw label map per views, classifier, robot conditions and aggregator
    (the jobs that differ only in post-processing or metrics aggregate once)."""

    pipe: MethodPipeline
    hid: str
    scene: Any

    def classified(self, compute: Callable[[], method.Classified]) -> method.Classified:
        from envs.render import cache as render_cache

        pipe, hid = self.pipe, self.hid

        def load(path: Path) -> method.Classified:
            z = classify_arrays(path)
            render = pipe.entry("render", hid)
            views = pipe._render_table(hid) if render_cache.is_complete(render) else None
            poses, proba, n_refused = check_classified(z, len(pipe.classes) if pipe.classes is not None else None,
                                                       views)
            check_poses(poses, self.scene)
            seen = check_seen(z, len(poses), proba.shape[1])
            # the job's own arrays (those kept per process are read-only)
            return method.Classified(poses.copy(), proba, n_refused, seen=None if seen is None else seen.copy())

        def compute_seen() -> method.Classified:
            c = compute()
            kept = c.observations or []
            c.seen = true_labels(kept) if kept and all(o.visible_classes is not None for o in kept) else None
            return c

        def save(path: Path, c: method.Classified) -> None:
            extra = {} if c.seen is None else {"seen": np.asarray(c.seen, np.int64)}
            atomic_save_npz(path, poses=c.poses, proba=c.proba, n_refused=np.array(c.n_refused), **extra)

        return pipe._cached("classify", pipe.entry("classify", hid), load, compute_seen, save)

    def aggregated(self, grid, views: method.Views, compute: Callable[[], np.ndarray]) -> np.ndarray:
        if not self.pipe.cache_aggregates:  # run.cache_aggregates=false: no entry read or written
            return compute()
        n_classes = views.proba.shape[1]

        def load(path: Path) -> np.ndarray:
            return check_labels_entry(load_npz(path), grid.shape, n_classes)

        def save(path: Path, raw: np.ndarray) -> None:
            atomic_save_npz(path, raw=raw.astype(np.int16))

        return self.pipe._cached("aggregate", self.pipe.entry("aggregate", self.hid), load, compute, save)


@dataclass
class SegmenterPipeline(Pipeline):
    """A geometric baseline: scene -> segmenter -> score (no views, no classes)."""

    CONTENT_STAGES: ClassVar[tuple[tuple[str, tuple[str, ...]], ...]] = (
        ("score", ("segmenter", "metrics", "viewpoints", "mapping")),)

    @property
    def segmenter(self) -> Segmenter:
        return self.stage("segmenter")

    def _compute(self, hid: str, timings: dict[str, float]) -> dict[str, Any]:
        from benchmark.metrics import score_instances

        t = time.perf_counter()
        scene = self.scene(hid)
        timings["t_scene"] = time.perf_counter() - t
        grid, robot = self._robot_grid(hid, scene, None, timings)
        t = time.perf_counter()
        # sanity rows that need the ground truth (segmenter=gt_geometry) say so with uses_scene;
        # every segmenter sees the robot's map only
        inst = (self.segmenter(grid, scene=scene) if getattr(self.segmenter, "uses_scene", False)
                else self.segmenter(grid))
        gt_instances, gt_walkable = self._ground_truth(hid, scene)  # in the robot map's frame
        inst = np.where(grid.walkable & gt_walkable, inst, -1)
        # a segmenter that runs elsewhere (ROSE² in its own environment) says how long it took
        timings.update({k: float(v) for k, v in (getattr(self.segmenter, "last_info", None) or {}).items()
                        if k.startswith("t_")})
        timings["t_segment"] = time.perf_counter() - t
        t = time.perf_counter()
        out = dict(score_instances(inst, gt_instances, self.metric_params, resolution=scene.grid.resolution))
        timings["t_score"] = time.perf_counter() - t
        out.update(robot)
        if self.save_maps:
            extra = {} if grid is scene.grid else {"free": grid.walkable}
            atomic_save_npz(self.entry("maps", hid), instances=inst.astype(np.int32), **extra)
        return out


def _one_line(e: BaseException) -> str:
    return " ".join(f"{type(e).__name__}: {e}".split())


__all__ = ["Pipeline", "MethodPipeline", "SegmenterPipeline", "StageError", "STAGES", "expand_force", "house_content", "scene_bytes", "scene_cache_limit", "SCENE_CACHE_MB",
           "SCENE_CACHE_MB_SINGLE"]
