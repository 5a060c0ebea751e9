"""The oracle classifier with controlled noise.

A view's true label is the class that covers most of the floor the camera sees
(``Observation.visible_classes``, from the floorplan renderer; ties -> lower class index),
not the room it stands in. With probability ``1 - accuracy`` the label is replaced by a
wrong class; a noise model (:mod:`benchmark.classifiers.noise`) decides how the errors of
different views are correlated (independent, per room, per house) and a confusion matrix
(given inline or read from a file, e.g. a real classifier's Table I confusion) which wrong
class is drawn. The output is one-hot. Every draw is seeded from ``seed`` and stable ids
(the view's pose, the house and room ids), so results do not depend on batching, order or
caching. A view that sees no floor keeps a uniform probability vector and is flagged in
``last_flags``.

Models that need the house (per room, per house) get it through :meth:`OracleClassifier.set_scene`,
which the pipeline calls before classifying a house's views.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Annotated

import numpy as np

from benchmark.classifiers.noise import (
    Independent,
    NoiseModel,
    load_confusion,
    uniform_confusion,
    wrong_class_rows,
)
from benchmark.interfaces import Classifier
from benchmark.view_accuracy import seen_accuracy, true_labels
from envs.ranges import Share
from envs.world.classes import PAPER_CLASSES


class OracleClassifier(Classifier):
    """Ground-truth labels with a controlled error rate.

    Args:
        accuracy: probability of keeping the true label, in [0, 1].
        seed: random seed.
        confusion: optional (C, C) matrix (rows: true class), or the path of a confusion
            file (:func:`benchmark.classifiers.noise.load_confusion`: ``table1_<model>.json``
            of the ``evaluate`` command, or CSV); row t gives the relative chances of each
            wrong class when true class t is replaced (diagonal ignored). None: uniform.
        noise: the noise model (:class:`benchmark.classifiers.noise.NoiseModel`); None:
            independent errors.
        classes: the ordered class names.

    Attributes:
        last_flags: (N,) bool, views of the last call that saw no floor.
        last_accuracy: share of the last call's views (that saw floor) labelled right.
    """

    def __init__(self, accuracy: Annotated[float, Share()] = 1.0, seed: int = 0,
                 confusion: Sequence[Sequence[float]] | str | Path | None = None,
                 noise: NoiseModel | None = None, classes: Sequence[str] = PAPER_CLASSES):
        if not 0.0 <= accuracy <= 1.0:
            raise ValueError(f"oracle accuracy must be in [0, 1], got {accuracy}")
        self.accuracy, self.seed, self.classes = float(accuracy), int(seed), tuple(classes)
        c = len(self.classes)
        if isinstance(confusion, str | Path):
            confusion = load_confusion(confusion, self.classes)
        self.confusion = uniform_confusion(c) if confusion is None else wrong_class_rows(confusion, c)
        self.noise = Independent() if noise is None else noise
        if not isinstance(self.noise, NoiseModel):
            raise ValueError(f"oracle noise must be a NoiseModel (e.g. benchmark.classifiers.noise.PerRoom), "
                             f"got {type(self.noise).__name__}")
        self.scene = None
        self.last_flags = np.zeros(0, dtype=bool)
        self.last_accuracy = float("nan")

    def setup(self, eval_house_ids: Sequence[str]) -> None:
        """Nothing to prepare."""

    def set_scene(self, scene) -> None:
        """The house whose views the next calls classify (its id and rooms seed the per-room
        and per-house models); the pipeline calls this before each house."""
        self.scene = scene

    def predict_proba(self, observations: Sequence) -> np.ndarray:
        """(N, C) one-hot rows (uniform for a view that saw no floor).

        Raises:
            ValueError: a view has no visible classes, or the noise model needs the house
                and :meth:`set_scene` was not called (or the views lie off its map).
        """
        truth = true_labels(observations)
        c = len(self.classes)
        poses = np.asarray([o.pose for o in observations], dtype=float).reshape(-1, 3)
        scene = None
        if self.noise.needs_scene:
            scene = self.scene
            if scene is None:
                raise ValueError(f"oracle noise {self.noise.describe()} needs the house: call set_scene(scene) first")
            if tuple(scene.classes) != self.classes:
                raise ValueError(f"oracle classes {list(self.classes)} differ from the scene's {list(scene.classes)}")
            r, cc = scene.grid.world_to_cell(poses[:, 0], poses[:, 1])
            if len(poses) and not np.all(scene.grid.in_bounds(r, cc)):
                raise ValueError(f"oracle: views lie off the map of house {scene.house_id!r} given to set_scene")
        labels = self.noise.labels(truth, poses, self.accuracy, self.confusion, self.seed, scene)
        out = np.full((len(truth), c), 1.0 / c)
        seen = truth >= 0
        out[seen] = 0.0
        out[np.nonzero(seen)[0], labels[seen]] = 1.0
        self.last_flags = ~seen
        self.last_accuracy = seen_accuracy(truth, out)
        return out
