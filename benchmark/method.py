"""The method as one object: classify -> view transforms -> aggregate -> post-process.

A :class:`Method` holds the stages of the paper's pipeline (classifier, aggregator,
post-processing) and the *view transforms* a robot condition puts between the classifier and
the aggregator (pose error, label noise, the ``roomseg-segment`` rule for views off the map).
It is built once from a config by :func:`benchmark.config.build_method` and run by everything
that segments a map: the harness (:mod:`benchmark.harness.pipeline`, which only wraps the
cached steps in its cache through a :class:`StageCache`), ``roomseg-segment``, the figures and
the confusion command. No cache, no config, no files here: stages are plain objects (a user can
build a Method by hand), inputs are arrays and observations.

Shapes: N views, C classes, an (H, W) map; poses are (N, 3) world x, z (metres) and simulator
yaw (degrees).

    from benchmark.method import Method
    result = Method(classifier, aggregator, postprocess).run(observations, grid)
    result.labels   # (H, W) int32 class index, -1 unlabelled or not walkable
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from benchmark.interfaces import Aggregator, Classifier, PostProcessor
from envs.maps.gridmap import GridMap
from envs.render.observation import Observation, poses_array


def stage_name(stage: object) -> str:
    """A stage's class name, for messages."""
    return type(stage).__name__


class Lazy:
    """A stage built on first use (``factory()``, once): a fully cached harness job builds no
    classifier. :class:`Method` and its view transforms resolve it when they first need it."""

    _UNBUILT = object()

    def __init__(self, factory: Callable[[], Any]):
        self.factory = factory
        self._value = Lazy._UNBUILT

    def get(self) -> Any:
        """The stage, built by ``factory`` the first time."""
        if self._value is Lazy._UNBUILT:
            self._value = self.factory()
        return self._value


def classify(classifier: Classifier, observations: Sequence[Observation], name: str | None = None) -> np.ndarray:
    """Class probabilities of the views.

    Args:
        classifier: any object with ``classes`` and ``predict_proba(observations)``.
        observations: N views.
        name: the classifier's name in messages (default: its class name).

    Returns:
        (N, C) float64 probabilities, C = ``len(classifier.classes)``.

    Raises:
        ValueError: the classifier returned another shape (one line naming it and both shapes).
    """
    proba = np.asarray(classifier.predict_proba(observations), dtype=np.float64)
    n_cls = len(getattr(classifier, "classes", proba.shape[1:] or [0]))
    if proba.shape != (len(observations), n_cls):
        raise ValueError(f"classifier {name or stage_name(classifier)} returned shape {proba.shape}, "
                         f"expected ({len(observations)}, {n_cls})")
    return proba


def aggregate(aggregator: Aggregator, grid: GridMap, poses: np.ndarray, proba: np.ndarray,
              name: str | None = None) -> np.ndarray:
    """The raw label map: the views' classes placed on the map by the aggregator.

    Args:
        aggregator: any callable ``(grid, poses, proba) -> (H, W) labels``.
        grid: the occupancy map the robot has.
        poses: (N, 3) view poses.
        proba: (N, C) their class probabilities.
        name: the aggregator's name in messages (default: its class name).

    Returns:
        (H, W) int32 class index, -1 unlabelled (cells off ``grid.walkable`` included).

    Raises:
        ValueError: the aggregator returned another shape.
    """
    raw = np.asarray(aggregator(grid, poses, proba))
    if raw.shape != grid.shape:
        raise ValueError(f"aggregator {name or stage_name(aggregator)} returned shape {raw.shape}, expected {grid.shape}")
    return raw.astype(np.int32, copy=False)


def postprocess(post: PostProcessor | None, raw: np.ndarray, grid: GridMap) -> np.ndarray:
    """The cleaned label map (``post`` None: the raw map), never labelling a cell that is not
    walkable on ``grid``.

    Returns:
        (H, W) int32 class index, -1 unlabelled.
    """
    labels = np.asarray(post(raw, grid)) if post is not None else np.asarray(raw)
    if labels.shape != grid.shape:
        raise ValueError(f"post-processing {stage_name(post)} returned shape {labels.shape}, expected {grid.shape}")
    return np.where(grid.walkable, labels, -1).astype(np.int32)


# --------------------------------------------------------------------------- what flows


@dataclass
class Context:
    """What a run knows beyond the views: the robot's map, and in the benchmark the house.

    Attributes:
        grid: the occupancy map the method works on (the robot's map).
        scene: the house (ground truth; the benchmark's noise models need it), or None.
        house_id: the house's id (seeds the pose-error draws; stamped on the views for
            classifiers that read per-house files), or None.
        route: for a SLAM pose error that estimates the whole route (one estimate for the map
            and the views): a function giving (every view's true pose in capture order (N, 3),
            the map the robot drives on, the scan spacing in metres or None, what the scan plane
            hits (H, W) bool or None: the scans the front end matches, as the map's estimate
            matched them), or None.
    """

    grid: GridMap | None = None
    scene: Any = None
    house_id: str | None = None
    route: Callable[[], tuple[np.ndarray, GridMap, float | None, np.ndarray | None]] | None = None


@dataclass
class Classified:
    """The classifier's output: the views it labelled (those the renderer did not refuse).

    Attributes:
        poses: (N, 3) where the camera was (true poses).
        proba: (N, C) class probabilities.
        n_refused: views the renderer refused (left out before classification).
        observations: the N labelled views (absent when served from a cache).
        seen: (N,) optional per-view annotation a caller keeps with them (the harness: the
            majority visible class, for its view-accuracy columns).
    """

    poses: np.ndarray
    proba: np.ndarray
    n_refused: int = 0
    observations: Sequence[Observation] | None = None
    seen: np.ndarray | None = None


@dataclass
class Views:
    """The views as the aggregator receives them, after the view transforms.

    Attributes:
        poses: (M, 3) the poses the method receives (a robot's estimate).
        proba: (M, C) the class probabilities it receives.
        true_poses: (M, 3) where the camera was (noise models seed their draws on them).
        ids: per view its id, for messages (or None).
    """

    poses: np.ndarray
    proba: np.ndarray
    true_poses: np.ndarray
    ids: list[Any] | None = None


class ViewTransform(Protocol):
    """A step between the classifier and the aggregator: ``(views, context) -> (views,
    row columns it records)``. Pose error, label noise and the off-map rule are ones."""

    def __call__(self, views: Views, ctx: Context) -> tuple[Views, dict[str, Any]]: ...


# --------------------------------------------------------------------------- view transforms


@dataclass
class PoseErrorTransform:
    """The robot's pose estimate: ``stage(true poses, the house's map, house id) -> (noisy
    poses, stats)`` (:class:`benchmark.conditions.pose_error.PoseError`; a SLAM stage with
    ``estimate``, :class:`benchmark.conditions.slam.OdometrySlam`, also gets the whole route from
    the context); records the mean and largest position error (m), the mean heading error
    (degrees) and what a SLAM stage reports (ATE, loop closures, ...)."""

    stage: Any
    KEEP = ("pose_error_mean_m", "pose_error_max_m", "yaw_error_mean_deg", "ate_rmse_m", "odometry_ate_rmse_m",
            "route_m", "loop_closures", "wrong_closures", "kidnapped_m", "slam_converged", "slam_chi2_dof",
            "closures_rejected", "slam_tracking_lost", "slam_relocalised")

    def __call__(self, views: Views, ctx: Context) -> tuple[Views, dict[str, Any]]:
        stage = _resolve(self.stage)
        grid = ctx.scene.grid if ctx.scene is not None else ctx.grid
        if hasattr(stage, "estimate") and ctx.route is not None:  # one SLAM estimate along the route, as the map's
            route_poses, route_grid, spacing, obstacles = ctx.route()
            noisy, stats = stage(views.true_poses, route_grid, ctx.house_id or "", route_poses=route_poses,
                                 spacing=spacing, obstacles=obstacles)
        else:
            noisy, stats = stage(views.true_poses, grid, ctx.house_id or "")
        return replace(views, poses=noisy), {k: float(stats[k]) for k in self.KEEP if k in stats}


@dataclass
class LabelNoiseTransform:
    """Classifier noise: ``stage(proba, true poses, scene, classes) -> (proba, info)``
    (:class:`benchmark.conditions.label_noise.LabelNoise`), seeded by the true poses (what was seen)."""

    stage: Any

    def __call__(self, views: Views, ctx: Context) -> tuple[Views, dict[str, Any]]:
        stage = _resolve(self.stage)
        classes = list(ctx.scene.classes) if ctx.scene is not None else None
        proba, info = stage(views.proba, views.true_poses, ctx.scene, classes=classes)
        return replace(views, proba=proba), dict(info)


@dataclass
class OnMapRule:
    """Views whose received pose is off the walkable map: ``error`` (one line naming the
    first) or ``drop`` (left out; the count is recorded as ``n_off_map``). Every view off the
    map is always an error (a wrong frame, most likely).

    Args:
        policy: ``error`` or ``drop``.
        source: the pose file, for messages.
        map_name: the map, for messages.
        frame: the pose frame, for messages.
    """

    policy: str = "error"
    source: str = "poses"
    map_name: str = "the map"
    frame: str = ""

    def __post_init__(self):
        if self.policy not in ("error", "drop"):
            raise ValueError(f"off_map={self.policy!r}; expected error or drop")

    def __call__(self, views: Views, ctx: Context) -> tuple[Views, dict[str, Any]]:
        poses = views.poses
        ok = on_map(ctx.grid, poses)
        if not ok.any():
            raise ValueError(f"{self.source}: none of the {len(poses)} poses (frame={self.frame}) is on a walkable "
                             f"cell of {self.map_name}; is the frame right?")
        if not ok.all() and self.policy == "error":
            bad = int(np.argmax(~ok))
            name = views.ids[bad] if views.ids is not None and views.ids[bad] is not None else bad
            raise ValueError(f"{self.source}: {int((~ok).sum())} of {len(poses)} poses are off the walkable map, first "
                             f"view {name} at x={poses[bad, 0]:.3f}, y={poses[bad, 1]:.3f} m in the map frame "
                             f"(ROS x, y; world x, z); pass off_map=drop to leave them out")
        ids = None if views.ids is None else [i for i, k in zip(views.ids, ok) if k]
        kept = Views(poses[ok], views.proba[ok], views.true_poses[ok], ids)
        return kept, {"n_off_map": int((~ok).sum())}


def on_map(grid: GridMap, poses: np.ndarray) -> np.ndarray:
    """(N,) bool: the pose stands on a walkable cell of ``grid``."""
    r, c = grid.world_to_cell(poses[:, 0], poses[:, 1])
    return grid.is_walkable(r, c)


# --------------------------------------------------------------------------- caching hook


class StageCache(Protocol):
    """Where a caller keeps the expensive steps' results (the harness: its content-addressed
    cache). Each method returns ``compute()``'s value or an equal one it kept."""

    def classified(self, compute: Callable[[], Classified]) -> Classified: ...

    def aggregated(self, grid: GridMap, views: Views, compute: Callable[[], np.ndarray]) -> np.ndarray: ...


class NoCache:
    """Every step computed (``roomseg-segment``, figures)."""

    def classified(self, compute: Callable[[], Classified]) -> Classified:
        return compute()

    def aggregated(self, grid: GridMap, views: Views, compute: Callable[[], np.ndarray]) -> np.ndarray:
        return compute()


# --------------------------------------------------------------------------- the method


@dataclass
class MethodResult:
    """What :meth:`Method.run` gives, on the robot's map.

    Attributes:
        classified: the classifier's output (true poses, probabilities).
        views: the views the aggregator received (after the view transforms).
        raw: (H, W) int32 the aggregator's label map.
        labels: (H, W) int32 after post-processing.
        grid: the map the method worked on.
        info: the row columns the view transforms record.
    """

    classified: Classified
    views: Views
    raw: np.ndarray
    labels: np.ndarray
    grid: GridMap
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def poses(self) -> np.ndarray:
        """(M, 3) the poses the aggregator received."""
        return self.views.poses

    @property
    def proba(self) -> np.ndarray:
        """(M, C) the probabilities the aggregator received."""
        return self.views.proba


def _resolve(stage: Any) -> Any:
    return stage.get() if isinstance(stage, Lazy) else stage


class Method:
    """Classifier, view transforms, aggregator and post-processing, run as one.

    Args:
        classifier: a :class:`benchmark.interfaces.Classifier` (or :class:`Lazy`).
        aggregator: a :class:`benchmark.interfaces.Aggregator` (or :class:`Lazy`).
        postprocess: a :class:`benchmark.interfaces.PostProcessor`, None for none (or :class:`Lazy`).
        transforms: :class:`ViewTransform` steps in order (pose error before label noise).
        names: stage -> name for messages (default: class names).
    """

    def __init__(self, classifier: Any, aggregator: Any, postprocess: Any = None,
                 transforms: Sequence[ViewTransform] = (), names: dict[str, str] | None = None):
        self._stages = {"classifier": classifier, "aggregator": aggregator, "postprocess": postprocess}
        self.transforms = list(transforms)
        self.names = dict(names or {})

    def _stage(self, name: str) -> Any:
        return _resolve(self._stages[name])

    @property
    def classifier(self) -> Classifier:
        return self._stage("classifier")

    @property
    def aggregator(self) -> Aggregator:
        return self._stage("aggregator")

    @property
    def postprocess(self) -> PostProcessor | None:
        return self._stage("postprocess")

    # ---- the steps
    def classify(self, observations: Sequence[Observation], ctx: Context | None = None) -> Classified:
        """Label the views the renderer did not refuse (``meta["refused"]``).

        Each kept view gets ``meta["house_id"]`` when the context names a house (classifiers
        that read per-house files use it); a classifier with ``set_scene`` gets the house.

        Raises:
            ValueError: every view was refused, or the classifier returned another shape."""
        ctx = ctx or Context()
        kept = [o for o in observations if not o.meta.get("refused", False)]
        if not kept:
            where = f"house {ctx.house_id!r}: " if ctx.house_id is not None else ""
            raise ValueError(f"{where}every one of {len(observations)} views was refused by the renderer")
        if ctx.house_id is not None:
            for o in kept:
                o.meta.setdefault("house_id", ctx.house_id)
        clf = self.classifier
        if ctx.scene is not None and hasattr(clf, "set_scene"):  # the house, for classifiers that need it
            clf.set_scene(ctx.scene)
        proba = classify(clf, kept, self.names.get("classifier"))
        return Classified(poses_array([o.pose for o in kept]), proba, len(observations) - len(kept), kept)

    def receive(self, classified: Classified, ctx: Context) -> tuple[Views, dict[str, Any]]:
        """The views as the aggregator receives them: every view transform in order.

        Returns:
            (views, the row columns the transforms record)."""
        ids = None
        if classified.observations is not None:
            ids = [o.meta.get("id") for o in classified.observations]
        views = Views(classified.poses, classified.proba, classified.poses, ids)
        info: dict[str, Any] = {}
        for step in self.transforms:
            views, more = step(views, ctx)
            info.update(more)
        return views, info

    def aggregate(self, grid: GridMap, views: Views) -> np.ndarray:
        """(H, W) int32 raw label map on ``grid``."""
        return aggregate(self.aggregator, grid, views.poses, views.proba, self.names.get("aggregator"))

    def finish(self, raw: np.ndarray, grid: GridMap) -> np.ndarray:
        """(H, W) int32 post-processed label map (never labelling a cell off ``grid.walkable``)."""
        return postprocess(self.postprocess, raw, grid)

    # ---- the chain, once
    def run(self, observations: Sequence[Observation] | Callable[[], Sequence[Observation]] | Classified,
            grid: GridMap | Callable[[], GridMap], ctx: Context | None = None, cache: StageCache | None = None,
            timings: dict[str, float] | None = None) -> MethodResult:
        """The whole method on one map.

        Args:
            observations: the posed views, or a function giving them (called only when the
                classification is not cached), or views classified already (:class:`Classified`:
                a robot that publishes its own labels, images classified in chunks).
            grid: the map the method works on, or a function giving it, called after the
                classification (a robot's map is built along the views the renderer made).
            ctx: the house and its id, when known (the grid is filled in here).
            cache: where the caller keeps the classification and the raw map (default: none).
            timings: gets ``t_classify``, ``t_transform`` (the view transforms: pose error,
                label noise), ``t_aggregate``, ``t_postprocess`` (seconds) of the steps computed.

        Returns:
            :class:`MethodResult`.
        """
        cache = cache or NoCache()
        timings = timings if timings is not None else {}
        ctx = replace(ctx) if ctx is not None else Context()

        def compute_classified() -> Classified:
            if isinstance(observations, Classified):  # views labelled already (a robot's own labels)
                return observations
            obs = observations() if callable(observations) else observations
            t = time.perf_counter()
            out = self.classify(obs, ctx)
            timings["t_classify"] = time.perf_counter() - t
            return out

        classified = cache.classified(compute_classified)
        grid = grid() if callable(grid) else grid
        ctx.grid = grid
        t, inner = time.perf_counter(), sum(timings.values())
        views, info = self.receive(classified, ctx)
        if self.transforms:  # a stage the transforms cause that times itself (t_slam) is not counted twice
            timings["t_transform"] = time.perf_counter() - t - (sum(timings.values()) - inner)

        def compute_raw() -> np.ndarray:
            t = time.perf_counter()
            out = self.aggregate(grid, views)
            timings["t_aggregate"] = time.perf_counter() - t
            return out

        raw = cache.aggregated(grid, views, compute_raw)
        t = time.perf_counter()
        labels = self.finish(raw, grid)
        timings["t_postprocess"] = time.perf_counter() - t
        return MethodResult(classified, views, raw, labels, grid, info)


__all__ = ["Method", "MethodResult", "Context", "Classified", "Views", "ViewTransform", "StageCache", "NoCache",
           "Lazy", "PoseErrorTransform", "LabelNoiseTransform", "OnMapRule", "on_map", "classify", "aggregate",
           "postprocess"]
