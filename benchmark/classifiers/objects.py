"""Room type from the objects a view sees: multinomial naive Bayes with Laplace smoothing.

Training counts, for every room of the training houses, the object types whose centre lies
in the room (children on top of an object count too): P(type | class) =
(count + alpha) / (total + alpha * n_types); the prior P(class) = (rooms of the class +
alpha) / (rooms + alpha * C). A view scores log P(class) + sum over the distinct object
types it sees of log P(type | class); types never seen in training are ignored. A view
that sees no known object gets the prior and is flagged in ``last_flags``.

The training houses are named in the config and must not overlap the evaluated houses:
:meth:`ObjectsClassifier.setup` refuses to run when they do.

``python -m benchmark.commands.objects_accuracy --train 0:75 --eval 75:150`` reports per-view
accuracy against the oracle's true label on the shared ProcTHOR houses.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from benchmark.interfaces import Classifier
from envs.datasets.house_files import iter_house_file
from envs.maps.scene import ObjectFootprint, rasterise_house
from envs.world.classes import PAPER_CLASSES
from envs.world.house import House


def room_object_counts(houses: Sequence[House], classes: Sequence[str], resolution: float = 0.1):
    """(C,) room counts per class and {object type: (C,) counts} over the houses' rooms."""
    room_counts = np.zeros(len(classes))
    type_counts: dict[str, np.ndarray] = {}
    for h in houses:
        scene = rasterise_house(h, resolution=resolution, classes=classes)
        for k in scene.instance_classes:
            room_counts[k] += 1
        grid = scene.grid
        for o in scene.objects:
            r, c = grid.world_to_cell(*o.center)
            if not grid.in_bounds(r, c) or scene.rooms[r, c] < 0:
                continue
            k = int(scene.instance_classes[scene.rooms[r, c]])
            for t in _types(o):
                type_counts.setdefault(t, np.zeros(len(classes)))[k] += 1
    return room_counts, type_counts


def _types(o: ObjectFootprint) -> tuple[str, ...]:
    return (o.object_type, *o.children)


class ObjectsClassifier(Classifier):
    """Naive Bayes over visible object types.

    Args:
        train_path: house file (.json/.jsonl/.jsonl.gz) with training houses, or None.
        train_start, train_stop: index range of the training houses in that file.
        train_synthetic: [first, last) seeds of generated training houses (envs.datasets.synthetic),
            or None. At least one source must be given; both are combined.
        alpha: Laplace smoothing.
        classes: the ordered class names.
    """

    def __init__(self, train_path: str | None = None, train_start: int = 0, train_stop: int | None = None,
                 train_synthetic: Sequence[int] | None = None, alpha: float = 1.0,
                 classes: Sequence[str] = PAPER_CLASSES):
        self.classes = tuple(classes)
        self.alpha = float(alpha)
        houses = []
        if train_path:
            for i, h in enumerate(iter_house_file(train_path)):
                if train_stop is not None and i >= train_stop:
                    break
                if i >= train_start:
                    houses.append(h)
        if train_synthetic:
            from envs.datasets.synthetic import generate_house

            houses += [generate_house(s) for s in range(int(train_synthetic[0]), int(train_synthetic[1]))]
        if not houses:
            raise ValueError(f"objects classifier: no training houses (train_path={train_path!r} "
                             f"[{train_start}:{train_stop}], train_synthetic={train_synthetic})")
        self.train_ids = [h.id for h in houses]
        rooms, types = room_object_counts(houses, self.classes)
        self.types = sorted(types)
        counts = np.array([types[t] for t in self.types]).T  # (C, T)
        self.log_prior = np.log((rooms + self.alpha) / (rooms.sum() + self.alpha * len(self.classes)))
        self.log_lik = np.log((counts + self.alpha) / (counts.sum(1, keepdims=True) + self.alpha * len(self.types)))
        self._index = {t: i for i, t in enumerate(self.types)}
        self.last_flags = np.zeros(0, dtype=bool)

    def setup(self, eval_house_ids: Sequence[str]) -> None:
        """Refuse to run when a training house is also evaluated."""
        overlap = sorted(set(self.train_ids) & set(map(str, eval_house_ids)))
        if overlap:
            raise ValueError(f"objects classifier: {len(overlap)} training house(s) are also evaluated "
                             f"(e.g. {overlap[:3]}); choose disjoint training houses (train_start/train_stop)")

    def predict_proba(self, observations: Sequence) -> np.ndarray:
        scores = np.tile(self.log_prior, (len(observations), 1))
        flags = np.ones(len(observations), dtype=bool)
        for i, o in enumerate(observations):
            idx = [self._index[t] for t, _ in o.objects if t in self._index]
            if idx:
                scores[i] += self.log_lik[:, np.unique(idx)].sum(axis=1)
                flags[i] = False
        self.last_flags = flags
        scores -= scores.max(axis=1, keepdims=True)
        p = np.exp(scores)
        return p / p.sum(axis=1, keepdims=True)


__all__ = ["ObjectsClassifier", "room_object_counts"]
