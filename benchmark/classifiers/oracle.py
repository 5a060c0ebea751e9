"""The oracle classifier with controlled noise.

A view's true label is the class that covers most of the floor the camera sees
(``Observation.visible_classes``, from the floorplan renderer; ties -> lower class index),
not the room it stands in. With probability ``1 - accuracy`` the label is replaced by a
wrong class: uniformly among the others, or drawn from row ``true`` of a confusion matrix
(diagonal ignored). The output is one-hot. Each view's draw is seeded from ``seed`` and the
view's pose, so results do not depend on batching, order or caching. A view that sees no
floor keeps a uniform probability vector and is flagged in ``last_flags``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import numpy as np

from benchmark.interfaces import Classifier
from envs.world.classes import PAPER_CLASSES


def true_labels(observations: Sequence) -> np.ndarray:
    """The majority visible class of each observation, -1 where nothing was seen."""
    out = np.full(len(observations), -1, dtype=np.int64)
    for i, o in enumerate(observations):
        v = o.visible_classes
        if v is None:
            raise ValueError(f"observation {i} has no visible_classes: the oracle needs the floorplan renderer")
        v = np.asarray(v)
        if v.sum() > 0:
            out[i] = int(np.argmax(v))
    return out


class OracleClassifier(Classifier):
    """Ground-truth labels with a controlled error rate.

    Args:
        accuracy: probability of keeping the true label, in [0, 1].
        seed: random seed.
        confusion: optional (C, C) matrix; row t gives the relative chances of each wrong
            class when true class t is replaced.
        classes: the ordered class names.
    """

    def __init__(self, accuracy: float = 1.0, seed: int = 0, confusion: Sequence[Sequence[float]] | None = None,
                 classes: Sequence[str] = PAPER_CLASSES):
        if not 0.0 <= accuracy <= 1.0:
            raise ValueError(f"oracle accuracy must be in [0, 1], got {accuracy}")
        self.accuracy, self.seed, self.classes = float(accuracy), int(seed), tuple(classes)
        c = len(self.classes)
        if confusion is not None:
            m = np.asarray(confusion, dtype=float)
            if m.shape != (c, c) or (m < 0).any():
                raise ValueError(f"confusion must be a non-negative ({c}, {c}) matrix, got shape {m.shape}")
            np.fill_diagonal(m, 0.0)
            m[m.sum(1) == 0] = 1.0 - np.eye(c)[m.sum(1) == 0]
            self.confusion = m / m.sum(1, keepdims=True)
        else:
            self.confusion = (1.0 - np.eye(c)) / max(c - 1, 1)
        self.last_flags = np.zeros(0, dtype=bool)

    def setup(self, eval_house_ids: Sequence[str]) -> None:
        """Nothing to prepare."""

    def _rng(self, pose) -> np.random.Generator:
        key = np.round(np.asarray(pose, dtype=float) * 1000).astype(np.int64).tobytes()
        h = int.from_bytes(hashlib.blake2b(key, digest_size=8).digest(), "little")
        return np.random.default_rng([self.seed, h])

    def predict_proba(self, observations: Sequence) -> np.ndarray:
        truth = true_labels(observations)
        c = len(self.classes)
        out = np.full((len(truth), c), 1.0 / c)
        for i, (o, t) in enumerate(zip(observations, truth)):
            if t < 0:
                continue
            rng = self._rng(o.pose)
            lab = t if rng.random() < self.accuracy else int(rng.choice(c, p=self.confusion[t]))
            out[i] = 0.0
            out[i, lab] = 1.0
        self.last_flags = truth < 0
        return out
