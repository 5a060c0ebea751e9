"""The stage interfaces. A stage is a plain class built from ``conf/`` with Hydra's
``_target_``; a user's own stage plugs in by pointing ``_target_`` at a class with the
same methods (these ABCs document the contract; subclassing them is optional).

Shapes: N views, C classes, an (H, W) map. Poses are (N, 3) float arrays of world x, z
(metres) and simulator yaw (degrees). Label maps are (H, W) int32 class indices, -1 for
unlabelled; instance maps are (H, W) int32 segment ids, -1 for none.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence

import numpy as np

from envs.gridmap import GridMap
from envs.house import House
from envs.observation import Observation
from envs.scene import Scene


class Viewpoints(ABC):
    """Where the robot takes its pictures."""

    @abstractmethod
    def generate(self, scene: Scene) -> np.ndarray:
        """(N, 3) poses on walkable cells of ``scene.grid``."""


class Renderer(ABC):
    """What the camera sees at each pose."""

    @abstractmethod
    def render(self, house: House, scene: Scene, poses: np.ndarray) -> list[Observation]:
        """One :class:`Observation` per pose, in pose order."""


class Classifier(ABC):
    """N observations -> (N, C) class probabilities over ``classes``."""

    classes: tuple[str, ...]

    def setup(self, eval_house_ids: Sequence[str]) -> None:  # noqa: B027
        """Called once before a run with the evaluated house ids (e.g. to refuse a training
        set that overlaps them). Default: nothing."""

    @abstractmethod
    def predict_proba(self, observations: Sequence[Observation]) -> np.ndarray:
        """(N, C) float, rows sum to 1."""


class Aggregator(ABC):
    """Views + probabilities -> label map."""

    @abstractmethod
    def __call__(self, grid: GridMap, poses: np.ndarray, proba: np.ndarray) -> np.ndarray:
        """(H, W) int32 label map: class index on walkable cells, -1 unlabelled/elsewhere."""


class PostProcessor(ABC):
    """Label map -> cleaned label map on the same grid."""

    @abstractmethod
    def __call__(self, labels: np.ndarray, grid: GridMap) -> np.ndarray:
        """(H, W) int32 label map on ``grid``."""


class Segmenter(ABC):
    """Geometry-only segmentation (baselines): map -> instance map, no classes."""

    @abstractmethod
    def __call__(self, grid: GridMap) -> np.ndarray:
        """(H, W) int32 instance ids on walkable cells, -1 elsewhere."""
