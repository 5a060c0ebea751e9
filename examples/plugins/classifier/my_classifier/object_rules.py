"""A classifier of your own: room classes from the objects a view sees, by rules.

Each rule names an object type and the class it points to (a toilet: a bathroom). A view's
score for a class is ``prior`` plus the amount it sees of that class's rule objects (the
renderer's measure: the floorplan renderer's share of rays, a simulator's share of image
pixels); its probabilities are the scores divided by their sum. A view that sees no rule
object gets the uniform vector.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np


class ObjectRules:
    """Rules from object types to classes.

    Args:
        classes: the run's ordered class names (``${classes}``); column c of the output is
            ``classes[c]``.
        rules: object type -> class name, e.g. ``{"Toilet": "bathroom"}``.
        prior: the score every class starts from (> 0; amounts seen are shares in [0, 1]).
    """

    def __init__(self, classes: Sequence[str], rules: Mapping[str, str], prior: float = 0.01):
        self.classes = tuple(str(c) for c in classes)
        unknown = sorted({str(c) for c in rules.values()} - set(self.classes))
        if unknown:
            raise ValueError(f"classifier.rules: class(es) {unknown} not in classes {list(self.classes)}")
        if isinstance(prior, bool) or not isinstance(prior, int | float) or not prior > 0:
            raise ValueError(f"classifier.prior={prior!r}: expected a number > 0")
        self.rules = {str(obj): self.classes.index(str(c)) for obj, c in rules.items()}
        self.prior = float(prior)

    def predict_proba(self, observations) -> np.ndarray:
        """(N, C) float probabilities, rows summing to 1, from each observation's ``objects``
        ((object type, amount seen) pairs)."""
        scores = np.full((len(observations), len(self.classes)), self.prior)
        for i, obs in enumerate(observations):
            for obj_type, amount in obs.objects:
                c = self.rules.get(obj_type)
                if c is not None:
                    scores[i, c] += float(amount)
        return scores / scores.sum(axis=1, keepdims=True)
