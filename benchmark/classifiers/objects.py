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
from pathlib import Path
from typing import Annotated

import numpy as np

from benchmark.interfaces import Classifier
from envs.datasets.house_files import iter_house_file
from envs.maps.scene import ObjectFootprint, rasterise_house
from envs.ranges import Integer, Positive
from envs.world.classes import PAPER_CLASSES
from envs.world.house import House


def room_object_counts(houses: Sequence[House], classes: Sequence[str], resolution: float = 0.1):
    """(C,) room counts per class and {object type: (C,) counts} over the houses' rooms."""
    room_counts = np.zeros(len(classes))
    type_counts: dict[str, np.ndarray] = {}
    for h in houses:
        scene = rasterise_house(h, resolution=resolution, classes=classes, layers="rooms")
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


#: :meth:`ObjectsClassifier.training_key` per settings and training file, in this process
_TRAINING_KEYS: dict[tuple, str] = {}
#: the training houses' ids per process, by the same key (:attr:`ObjectsClassifier.train_ids`).
_TRAIN_IDS: dict[tuple, tuple[str, ...]] = {}


def _file_identity(path: str | None) -> tuple | None:
    """(real path, device, inode, size, modification time in ns) of a file, None without one."""
    if not path:
        return None
    import os

    try:
        st = os.stat(path)
    except OSError:
        return None  # a missing file: training_houses() says so when the key is computed
    return os.path.realpath(path), st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns


class ObjectsClassifier(Classifier):
    """Naive Bayes over visible object types.

    Building one reads nothing; :meth:`fit` trains it (about 3 s on the 200 default
    generated houses), :meth:`save` / :meth:`load` keep a fitted model in an ``.npz``, and
    :meth:`training_key` names the content of the training set, so a harness can cache the
    fitted model by what it was trained on (:mod:`benchmark.harness.pipeline` does). Asking
    for predictions before :meth:`fit` or :meth:`load` fits first.

    Args:
        train_path: house file (.json/.jsonl/.jsonl.gz) with training houses, or None.
        train_start, train_stop: index range of the training houses in that file.
        train_synthetic: [first, last) seeds of generated training houses (envs.datasets.synthetic),
            or None. At least one source must be given; both are combined.
        alpha: Laplace smoothing.
        classes: the ordered class names.
    """

    #: bump when the fitted tables change meaning (invalidates saved models).
    MODEL_VERSION = 1
    #: metres per pixel of the rasterisation that places objects in rooms during training.
    TRAIN_RESOLUTION = 0.1

    def __init__(self, train_path: str | None = None, train_start: Annotated[int, Integer(0)] = 0,
                 train_stop: Annotated[int | None, Integer(0)] = None,
                 train_synthetic: Sequence[int] | None = None, alpha: Annotated[float, Positive()] = 1.0,
                 classes: Sequence[str] = PAPER_CLASSES):
        self.classes = tuple(classes)
        self.alpha = float(alpha)
        self.train_path, self.train_start, self.train_stop = train_path, int(train_start), train_stop
        self.train_synthetic = None if not train_synthetic else (int(train_synthetic[0]), int(train_synthetic[1]))
        if not train_path and not self.train_synthetic:
            raise ValueError(f"objects classifier: no training houses (train_path={train_path!r} "
                             f"[{train_start}:{train_stop}], train_synthetic={train_synthetic})")
        self._houses: list[House] | None = None
        self._types: list[str] | None = None
        self.last_flags = np.zeros(0, dtype=bool)

    # ---- the training set
    def training_houses(self) -> list[House]:
        """The training houses (read or generated once, then kept).

        Raises:
            ValueError: the sources give no house."""
        if self._houses is None:
            houses = []
            if self.train_path:
                for i, h in enumerate(iter_house_file(self.train_path)):
                    if self.train_stop is not None and i >= self.train_stop:
                        break
                    if i >= self.train_start:
                        houses.append(h)
            if self.train_synthetic:
                from envs.datasets.synthetic import generate_house

                houses += [generate_house(s) for s in range(*self.train_synthetic)]
            if not houses:
                raise ValueError(f"objects classifier: no training houses (train_path={self.train_path!r} "
                                 f"[{self.train_start}:{self.train_stop}], train_synthetic={self.train_synthetic})")
            self._houses = houses
        return self._houses

    @property
    def fitted(self) -> bool:
        return self._types is not None

    @property
    def types(self) -> list[str]:
        """Object types seen in training, in table order (fits first if needed)."""
        if self._types is None:
            self.fit()
        return self._types  # type: ignore[return-value]

    @property
    def train_ids(self) -> list[str]:
        """The training houses' ids, kept per process as :meth:`training_key` is (a job's
        :meth:`setup` needs only them, not the houses)."""
        memo = self._memo_key()
        if memo not in _TRAIN_IDS:
            _TRAIN_IDS[memo] = tuple(h.id for h in self.training_houses())
        return list(_TRAIN_IDS[memo])

    def _memo_key(self) -> tuple:
        """What the training houses, their ids and key depend on (the training file by its path,
        inode, size and modification time)."""
        return (self.MODEL_VERSION, self.alpha, self.classes, self.TRAIN_RESOLUTION, self.train_path,
                self.train_start, self.train_stop, self.train_synthetic, _file_identity(self.train_path))

    def training_key(self) -> str:
        """16 hex digits over the training houses' JSON, alpha, classes and the model version:
        equal keys mean equal fitted tables.

        Kept per process for the same settings and the same training file (its path, inode,
        size and modification time): every job of a sweep builds its own classifier, and
        reading or generating the training houses again only to hash them cost each job
        0.2-0.3 s (the robustness grid has 156 jobs with this classifier)."""
        memo = self._memo_key()
        if memo not in _TRAINING_KEYS:
            _TRAINING_KEYS[memo] = self._training_key()
        return _TRAINING_KEYS[memo]

    def _training_key(self) -> str:
        import hashlib
        import json

        h = hashlib.sha1()
        h.update(json.dumps([self.MODEL_VERSION, self.alpha, list(self.classes), self.TRAIN_RESOLUTION]).encode())
        for house in self.training_houses():
            h.update(json.dumps([house.id, house.data], sort_keys=True, separators=(",", ":")).encode())
        return h.hexdigest()[:16]

    # ---- fit / save / load
    def fit(self) -> ObjectsClassifier:
        """Count object types per class over the training houses. Returns self."""
        rooms, types = room_object_counts(self.training_houses(), self.classes, self.TRAIN_RESOLUTION)
        self._set_tables(sorted(types), rooms, np.array([types[t] for t in sorted(types)]).T)
        return self

    def _set_tables(self, types: list[str], rooms: np.ndarray, counts: np.ndarray) -> None:
        """``rooms`` (C,) room counts per class, ``counts`` (C, T) object counts per class and type."""
        self._types = list(types)
        self._rooms, self._counts = np.asarray(rooms, dtype=np.float64), np.asarray(counts, dtype=np.float64)
        self.log_prior = np.log((self._rooms + self.alpha) / (self._rooms.sum() + self.alpha * len(self.classes)))
        self.log_lik = np.log((self._counts + self.alpha)
                              / (self._counts.sum(1, keepdims=True) + self.alpha * len(self.types)))
        self._index = {t: i for i, t in enumerate(self.types)}

    def save(self, path: str | Path) -> Path:
        """Write the fitted counts to ``path`` (``.npz`` with a checksum, atomically). Returns the path."""
        from envs.npz import save_npz

        if self._types is None:
            raise ValueError("objects classifier: save() before fit()")
        save_npz(path, types=np.array(self.types, dtype=str), rooms=self._rooms, counts=self._counts,
                 classes=np.array(self.classes, dtype=str), key=np.array(self.training_key()),
                 train_ids=np.array(self.train_ids, dtype=str))
        return Path(path)

    def load(self, path: str | Path) -> ObjectsClassifier:
        """Read counts written by :meth:`save`, checked against this classifier. Returns self.

        Raises:
            ValueError: unreadable or damaged file (its checksum), other classes or training
                set, or bad shapes (the message names the file)."""
        from envs.npz import load_npz

        d = load_npz(path)  # checked against the checksum written with it (one line naming the file)
        try:
            types, rooms, counts = [str(t) for t in d["types"]], d["rooms"], d["counts"]
            classes, key = tuple(str(c) for c in d["classes"]), str(d["key"])
        except KeyError as e:
            raise ValueError(f"{path}: saved objects classifier lacks {e}") from None
        if classes != self.classes or key != self.training_key():
            raise ValueError(f"{path}: fitted for other classes or another training set")
        if rooms.shape != (len(classes),) or counts.shape != (len(classes), len(types)) or not (
                np.isfinite(rooms).all() and np.isfinite(counts).all() and (counts >= 0).all()):
            raise ValueError(f"{path}: counts of shape {counts.shape} / rooms {rooms.shape} do not fit "
                             f"{len(classes)} classes x {len(types)} types")
        self._set_tables(types, rooms, counts)
        return self

    def setup(self, eval_house_ids: Sequence[str]) -> None:
        """Refuse to run when a training house is also evaluated."""
        overlap = sorted(set(self.train_ids) & set(map(str, eval_house_ids)))
        if overlap:
            raise ValueError(f"objects classifier: {len(overlap)} training house(s) are also evaluated "
                             f"(e.g. {overlap[:3]}); choose disjoint training houses (train_start/train_stop)")

    def predict_proba(self, observations: Sequence) -> np.ndarray:
        """(N, C) class probabilities of N observations (fits first if not fitted or loaded)."""
        if self._types is None:
            self.fit()
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
