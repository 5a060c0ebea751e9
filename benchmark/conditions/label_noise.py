"""Classifier noise on top of any classifier: a share of the views get a wrong label.

The robustness benchmark's "classifier noise" family degrades whatever classifier a method
uses (the objects classifier, the oracle, a CNN...) the same way, with the oracle's noise models
(:mod:`benchmark.classifiers.noise`): each view keeps the class its classifier gave it with
probability ``1 - share``; otherwise it takes a wrong class drawn from the confusion row of that
class (uniform by default, or a real classifier's confusion file), independently per view
(:class:`~benchmark.classifiers.noise.Independent`), shared by the views of a room
(:class:`~benchmark.classifiers.noise.PerRoom`) or biased per house
(:class:`~benchmark.classifiers.noise.PerHouse`). A relabelled view's probabilities become the
one-hot row of its new class; the others are unchanged. ``share`` 0 returns the probabilities
unchanged, bit for bit.

What it models: a classifier that is wrong more often than the one measured (domain shift,
motion blur, lighting), with errors as correlated as the chosen noise model says. What it
leaves out: confidence (a wrong view is as confident as a right one), and errors that depend
on what the view sees beyond its class.

Draws are seeded by the view's pose and this stage's ``seed`` (a salt keeps them apart from the
oracle classifier's own draws), so results never depend on batch size, view order or caching.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Annotated, Any

import numpy as np

from benchmark.classifiers.noise import (
    Independent,
    NoiseModel,
    load_confusion,
    uniform_confusion,
    wrong_class_rows,
)
from envs.ranges import Share


class LabelNoise:
    """Relabel a share of the views (see the module doc).

    Args:
        share: chance that a view's label is replaced by a wrong one, in [0, 1].
        noise: how errors are correlated (a :class:`~benchmark.classifiers.noise.NoiseModel`);
            None: independent.
        confusion: (C, C) matrix or a confusion file (rows: true class) giving the relative
            chances of each wrong class; None: uniform.
        seed: the stage's seed (its draws are salted apart from the oracle's).
    """

    #: salt of this stage's draws (the oracle classifier draws with its own seed, unsalted).
    SALT = 7919

    def __init__(self, share: Annotated[float, Share()] = 0.0, noise: NoiseModel | None = None,
                 confusion: Sequence[Sequence[float]] | str | Path | None = None, seed: int = 0):
        if isinstance(share, bool) or not isinstance(share, int | float) or not 0.0 <= float(share) <= 1.0:
            raise ValueError(f"label_noise.share={share!r}: expected a share of views in [0, 1]")
        self.share, self.seed = float(share), int(seed)
        self.noise = Independent() if noise is None else noise
        if not isinstance(self.noise, NoiseModel):
            raise ValueError(f"label_noise.noise: expected a NoiseModel (e.g. benchmark.classifiers.noise.PerRoom), "
                             f"got {type(self.noise).__name__}")
        self.confusion = confusion

    def __call__(self, proba: np.ndarray, poses: np.ndarray, scene=None,
                 classes: Sequence[str] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        """Noisy probabilities of N views.

        Args:
            proba: (N, C) class probabilities from the classifier.
            poses: (N, 3) the views' poses, world x, z (m), yaw (deg) (they seed the draws).
            scene: the house (the per-room and per-house models need it).
            classes: the C class names (a confusion file is read onto them).

        Returns:
            ((N, C) probabilities, {"label_noise_share": share of views relabelled}).
        """
        proba = np.asarray(proba, dtype=np.float64)
        if self.share == 0.0 or len(proba) == 0:
            return proba, {"label_noise_share": 0.0}
        n_cls = proba.shape[1]
        if isinstance(self.confusion, str | Path):
            if classes is None:
                raise ValueError("label_noise: a confusion file needs the class names")
            conf = load_confusion(self.confusion, classes)
        else:
            conf = uniform_confusion(n_cls) if self.confusion is None else self.confusion
        wrong = wrong_class_rows(conf, n_cls)
        own = proba.argmax(axis=1)
        labels = self.noise.labels(own, np.asarray(poses, dtype=float), 1.0 - self.share, wrong,
                                   self.seed * 1_000_003 + self.SALT, scene)
        flipped = labels != own
        out = proba.copy()
        out[flipped] = 0.0
        out[np.nonzero(flipped)[0], labels[flipped]] = 1.0
        return out, {"label_noise_share": float(flipped.mean())}

    def describe(self) -> str:
        return f"share={self.share:g}, {self.noise.describe()}"


__all__ = ["LabelNoise"]
