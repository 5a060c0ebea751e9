"""The stage contracts, as :class:`typing.Protocol` classes: a stage is a plain class built
from ``conf/`` with Hydra's ``_target_``; a user's own stage plugs in by pointing
``_target_`` at any class with the same methods (subclassing is optional; the bundled
stages subclass to state the contract). The renderer and environment contracts live with
their implementations in ``envs`` (:mod:`envs.render.base`, :mod:`envs.datasets.base`) and
are re-exported here.

Shapes: N views, C classes, an (H, W) map. Poses are (N, 3) float arrays of world x, z
(metres) and simulator yaw (degrees). Label maps are (H, W) int32 class indices, -1 for
unlabelled; instance maps are (H, W) int32 segment ids, -1 for none.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from envs.datasets.base import Environment
from envs.maps.gridmap import GridMap
from envs.maps.scene import Scene
from envs.render.base import Renderer
from envs.render.observation import Observation


@runtime_checkable
class Viewpoints(Protocol):
    """Where the robot takes its pictures."""

    def generate(self, scene: Scene) -> np.ndarray:
        """(N, 3) poses on walkable cells of ``scene.grid``."""
        ...


@runtime_checkable
class Classifier(Protocol):
    """N observations -> (N, C) class probabilities over ``classes`` (in that order; the
    runner checks it equals the environment's class list)."""

    classes: tuple[str, ...]

    def predict_proba(self, observations: Sequence[Observation]) -> np.ndarray:
        """(N, C) float, rows sum to 1."""
        ...


@runtime_checkable
class Aggregator(Protocol):
    """Views + probabilities -> label map."""

    def __call__(self, grid: GridMap, poses: np.ndarray, proba: np.ndarray) -> np.ndarray:
        """(H, W) int32 label map: class index on walkable cells, -1 unlabelled/elsewhere."""
        ...


@runtime_checkable
class PostProcessor(Protocol):
    """Label map -> cleaned label map on the same grid."""

    def __call__(self, labels: np.ndarray, grid: GridMap) -> np.ndarray:
        """(H, W) int32 label map on ``grid``."""
        ...


@runtime_checkable
class Segmenter(Protocol):
    """Geometry-only segmentation (baselines): map -> instance map, no classes."""

    def __call__(self, grid: GridMap) -> np.ndarray:
        """(H, W) int32 instance ids on walkable cells, -1 elsewhere."""
        ...


__all__ = ["Environment", "Renderer", "Viewpoints", "Classifier", "Aggregator", "PostProcessor", "Segmenter"]
