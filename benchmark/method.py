"""The method as one library function: classify -> aggregate -> post-process, on arrays.

No cache, no config, no files: stages are plain objects (``conf/`` builds them with Hydra's
``_target_``; a user can build them by hand), inputs are arrays and observations. The
harness (:mod:`benchmark.harness.pipeline`) wraps each step in its cache; ``roomseg-segment``
(:mod:`benchmark.commands.segment`) calls them directly. Shapes: N views, C classes, an (H, W)
map; poses are (N, 3) world x, z (metres) and simulator yaw (degrees).

    from benchmark.method import segment_views
    result = segment_views(classifier, aggregator, postprocess, grid, observations)
    result.labels   # (H, W) int32 class index, -1 unlabelled or not walkable
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from benchmark.interfaces import Aggregator, Classifier, PostProcessor
from envs.maps.gridmap import GridMap
from envs.render.observation import Observation, poses_array


def stage_name(stage: object) -> str:
    """A stage's class name, for messages."""
    return type(stage).__name__


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


@dataclass
class MethodResult:
    """What :func:`segment_views` gives: the views' poses and probabilities, the raw and the
    post-processed label maps, all on the input grid."""

    poses: np.ndarray   # (N, 3) world x, z (m), yaw (deg)
    proba: np.ndarray   # (N, C)
    raw: np.ndarray     # (H, W) int32, the aggregator's map
    labels: np.ndarray  # (H, W) int32, after post-processing


def segment_views(classifier: Classifier, aggregator: Aggregator, post: PostProcessor | None, grid: GridMap,
                  observations: Sequence[Observation]) -> MethodResult:
    """The whole method on one map: classify the views, place their classes, clean up.

    Args:
        classifier, aggregator, post: the stages (``post`` None: no post-processing).
        grid: the occupancy map.
        observations: the posed views (their ``pose`` is where the aggregator places them).

    Returns:
        :class:`MethodResult`.
    """
    poses = poses_array([o.pose for o in observations]) if len(observations) else np.zeros((0, 3))
    proba = classify(classifier, observations)
    raw = aggregate(aggregator, grid, poses, proba)
    return MethodResult(poses, proba, raw, postprocess(post, raw, grid))


__all__ = ["classify", "aggregate", "postprocess", "segment_views", "MethodResult"]
