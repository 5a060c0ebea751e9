"""How the oracle classifier errs: noise models with stable seeds, confusion files, and the
per-view accuracy measured against what a view sees.

Every model keeps the configured accuracy ``a`` for each view in expectation (a view whose
true class is ``t`` gets ``t`` with probability ``a``); they differ in how the errors of
different views are correlated and which wrong class is drawn:

- :class:`Independent`: each view draws alone (right with probability ``a``; if wrong, a
  class from row ``t`` of the confusion matrix, diagonal ignored).
- :class:`PerRoom`: a view follows its room with probability ``correlation``, else it
  draws like :class:`Independent`. A room draws once whether it is right and, if not, one
  wrong class, so at ``correlation`` 1 every view of a room is right or every view carries
  the same wrong class; at 0 the model is :class:`Independent`, draw for draw.
- :class:`PerHouse`: a systematic bias: each house has one bias class (configured, or drawn
  per house); a wrong view takes the bias class with probability ``strength`` (the "every
  view is a dining room" failure), else a class from the confusion row.

A confusion matrix (rows: true class, columns: predicted; counts or rates) can come from a
file (:func:`load_confusion`): the ``table1_<model>.json`` the ``evaluate`` command writes for
Table I, the same format :func:`view_confusion` writes for a classifier on rendered views,
or a CSV.

Seeds come from stable ids only: a view from the configured seed and its pose (rounded to
millimetres), a room from the house id and the room id, a house from its id. So a result
never depends on batch size, the order of views, caching or the other houses of a run.

The room of a view is the room the view's true class refers to: the nearest room (by the
Euclidean distance between cell centres on the map) whose class is the view's true class;
for a view standing in a room of its true class, that room. See :func:`view_rooms`.
"""

from __future__ import annotations

import csv
import hashlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from benchmark.view_accuracy import true_labels

#: salts that keep the random streams of the different draws apart.
_FOLLOW, _ROOM, _HOUSE, _BIAS = 1, 2, 3, 4


def pose_keys(poses: np.ndarray) -> list[int]:
    """64-bit keys of poses (rows of x, z in metres, yaw in degrees), each rounded to 1/1000.

    Returns:
        One non-negative int per row (the same for equal rounded poses in any process).
    """
    rounded = np.round(np.asarray(poses, dtype=float) * 1000).astype(np.int64)
    return [int.from_bytes(hashlib.blake2b(r.tobytes(), digest_size=8).digest(), "little") for r in rounded]


def pose_key(pose: Sequence[float]) -> int:
    """:func:`pose_keys` of one pose."""
    return pose_keys(np.asarray(pose, dtype=float)[None])[0]


def text_key(*parts: object) -> int:
    """64-bit key of a tuple of ids (house id, room id), from their ``str`` forms.

    Returns:
        The key as a non-negative int.
    """
    blob = "\x1f".join(str(p) for p in parts).encode("utf-8")
    return int.from_bytes(hashlib.blake2b(blob, digest_size=8).digest(), "little")


def view_rng(seed: int, pose: Sequence[float], salt: int | None = None) -> np.random.Generator:
    """The random stream of one view (``salt`` picks a separate stream of the same view).

    Returns:
        A generator seeded from (seed, pose key[, salt]).
    """
    parts = [int(seed), pose_key(pose)] + ([] if salt is None else [int(salt)])
    return np.random.default_rng(parts)


#: numpy's ``SeedSequence`` (O'Neill's seed_seq_fe, pool of 4 words) and ``PCG64`` (XSL RR 128/64)
#: constants, for :func:`view_uniforms`
_INIT_A, _MULT_A, _INIT_B, _MULT_B = 0x43B0D7E5, 0x931E8875, 0x8B51F9DD, 0x58F38DED
_MIX_L, _MIX_R, _M32 = 0xCA01F9DD, 0x4973F715, 0xFFFFFFFF
_PCG_MULT, _M64, _M128 = 0x2360ED051FC65DA44385DF649FCCF645, (1 << 64) - 1, (1 << 128) - 1


def _words(n: int) -> list[int]:
    """The 32-bit words of a non-negative int, least significant first (at least one).

    Raises:
        ValueError: a negative int (a seed must be >= 0, as numpy's generators say too)."""
    if n < 0:
        raise ValueError(f"seed {n}: expected a non-negative integer")
    out = [n & _M32]
    n >>= 32
    while n:
        out.append(n & _M32)
        n >>= 32
    return out


def _stream_uniforms(entropy: np.ndarray, draws: int = 1) -> np.ndarray:
    """(N, draws) float64: the first ``draws`` ``random()`` of ``np.random.default_rng(words)`` for
    each row of ``entropy`` ((N, L) uint32 words of the seed parts): the seed sequence's entropy
    mixing and its 4 state words for all rows at once (uint32 arithmetic wraps), then PCG64's
    seeding, and per draw one step and its 64-bit output, as exact integers."""
    n, length = entropy.shape
    hc = _INIT_A

    def hashmix(v: np.ndarray) -> np.ndarray:
        nonlocal hc
        v = v ^ np.uint32(hc)
        hc = (hc * _MULT_A) & _M32
        v = v * np.uint32(hc)
        return v ^ (v >> np.uint32(16))

    def mix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        r = np.uint32(_MIX_L) * x - np.uint32(_MIX_R) * y
        return r ^ (r >> np.uint32(16))

    zero = np.zeros(n, np.uint32)
    pool = [hashmix(entropy[:, i] if i < length else zero) for i in range(4)]
    for src in range(4):
        for dst in range(4):
            if src != dst:
                pool[dst] = mix(pool[dst], hashmix(pool[src]))
    for src in range(4, length):
        for dst in range(4):
            pool[dst] = mix(pool[dst], hashmix(entropy[:, src]))
    hb, state = _INIT_B, []
    for i in range(8):  # 4 uint64 words, from the pool's words in turn
        v = pool[i % 4] ^ np.uint32(hb)
        hb = (hb * _MULT_B) & _M32
        v = v * np.uint32(hb)
        state.append((v ^ (v >> np.uint32(16))).astype(np.uint64))
    w = [(state[2 * i] | (state[2 * i + 1] << np.uint64(32))).tolist() for i in range(4)]
    out = np.empty((n, draws))
    for j in range(n):
        inc = (((w[2][j] << 64 | w[3][j]) << 1) | 1) & _M128
        x = (((inc + (w[0][j] << 64 | w[1][j])) & _M128) * _PCG_MULT + inc) & _M128  # seeded
        for d in range(draws):
            x = (x * _PCG_MULT + inc) & _M128  # a step
            hi = x >> 64
            y, rot = hi ^ (x & _M64), hi >> 58
            out[j, d] = (((y >> rot) | (y << (-rot & 63))) & _M64) >> 11
    return out * (1.0 / 9007199254740992.0)


def view_draws(seed: int, poses: np.ndarray, draws: int, salt: int | None = None) -> np.ndarray:
    """(N, draws) float64 in [0, 1): the first ``draws`` ``view_rng(seed, pose, salt).random()``
    of each pose, bit for bit, without making a generator per view.

    Args:
        seed: the run's seed (>= 0).
        poses: (N, 3) x, z (metres), yaw (degrees).
        draws: how many draws of each view's stream (>= 1).
        salt: as in :func:`view_rng`.
    """
    keys = pose_keys(poses)
    out = np.empty((len(keys), draws))
    if not keys:
        return out
    tail = [] if salt is None else _words(int(salt))
    rows = [_words(int(seed)) + _words(k) + tail for k in keys]  # a key below 2**32 is one word
    lengths = np.array([len(r) for r in rows])
    for n in np.unique(lengths):
        idx = np.flatnonzero(lengths == n)
        out[idx] = _stream_uniforms(np.array([rows[i] for i in idx], np.uint32), draws)
    return out


def view_uniforms(seed: int, poses: np.ndarray, salt: int | None = None) -> np.ndarray:
    """(N,) float64 in [0, 1): ``view_rng(seed, pose, salt).random()`` of each pose, bit for bit
    (the first of :func:`view_draws`).

    Args:
        seed: the run's seed (>= 0).
        poses: (N, 3) x, z (metres), yaw (degrees).
        salt: as in :func:`view_rng`.
    """
    return view_draws(seed, poses, 1, salt)[:, 0]


def wrong_classes(u: np.ndarray, truth: np.ndarray, wrong: np.ndarray) -> np.ndarray:
    """(N,) int64: the class ``rng.choice(len(wrong), p=wrong[t])`` draws for a view of true
    class ``t`` when its generator's next ``random()`` is ``u`` (numpy's choice with ``p``:
    the row's running sum divided by its last value, searched at ``u`` from the right).

    Args:
        u: (N,) float64 in [0, 1), each view's draw.
        truth: (N,) int true classes (>= 0).
        wrong: (C, C) wrong-class rows (:func:`wrong_class_rows`).
    """
    u, truth = np.asarray(u, np.float64), np.asarray(truth, np.int64)
    out = np.empty(len(truth), np.int64)
    for t in np.unique(truth):
        cdf = np.array(wrong[t], np.float64).cumsum()
        cdf /= cdf[-1]
        at = truth == t
        out[at] = cdf.searchsorted(u[at], side="right")
    return out


def uniform_confusion(n_classes: int) -> np.ndarray:
    """(C, C) wrong-class distribution with every other class equally likely.

    Returns:
        Rows sum to 1, zero diagonal (a single class gives [[1.0]]: nothing else to draw).
    """
    if n_classes == 1:
        return np.ones((1, 1))
    return (1.0 - np.eye(n_classes)) / (n_classes - 1)


def wrong_class_rows(confusion: Any, n_classes: int) -> np.ndarray:
    """A confusion matrix -> (C, C) wrong-class distributions: diagonal dropped, rows
    normalised; a row with no errors becomes uniform over the other classes.

    Args:
        confusion: (C, C) non-negative counts or rates, rows = true class.
        n_classes: C.

    Returns:
        (C, C) float, zero diagonal (C > 1), rows sum to 1.

    Raises:
        ValueError: wrong shape, negative or non-finite entries.
    """
    m = np.array(confusion, dtype=float)
    if m.shape != (n_classes, n_classes) or not np.isfinite(m).all() or (m < 0).any():
        raise ValueError(f"confusion must be a finite non-negative ({n_classes}, {n_classes}) matrix, "
                         f"got shape {m.shape}")
    if n_classes == 1:
        return np.ones((1, 1))
    np.fill_diagonal(m, 0.0)
    empty = m.sum(1) == 0
    m[empty] = uniform_confusion(n_classes)[empty]
    return m / m.sum(1, keepdims=True)


def _resolve(path: str | Path) -> Path:
    p = Path(path).expanduser()
    if p.exists() or p.is_absolute():
        return p
    root = Path(__file__).resolve().parents[2]
    return root / p if (root / p).exists() else p


def load_confusion(path: str | Path, classes: Sequence[str]) -> np.ndarray:
    """Read a confusion matrix (rows: true class, columns: predicted) onto ``classes``.

    Formats: JSON with ``confusion`` (C', C') and optional ``classes`` (C' names; the format
    of ``table1_<model>.json`` from the ``evaluate`` command and of :func:`view_confusion`);
    or CSV, a (C', C') table of numbers with an optional first row of class names. Named
    classes are matched by name (file classes that are not in ``classes`` are dropped; a
    class missing from the file gets an empty row, i.e. uniform wrong classes); without
    names C' must equal C. A relative path is read from the working directory, else from
    the repository root.

    Returns:
        (C, C) float counts/rates in the order of ``classes``.

    Raises:
        FileNotFoundError, ValueError: the file is missing, unreadable or does not fit.
    """
    p = _resolve(path)
    if not p.exists():
        raise FileNotFoundError(f"confusion file {path} does not exist")
    names: list[str] | None
    if p.suffix.lower() == ".json":
        rec = json.loads(p.read_text())
        if not isinstance(rec, dict) or "confusion" not in rec:
            raise ValueError(f"confusion file {p}: expected a JSON object with a 'confusion' matrix")
        m = np.asarray(rec["confusion"], dtype=float)
        names = [str(c) for c in rec["classes"]] if rec.get("classes") is not None else None
    else:
        rows = [r for r in csv.reader(p.read_text().splitlines()) if r]
        names = None
        try:
            float(rows[0][0])
        except (ValueError, IndexError):
            names, rows = [c.strip() for c in rows[0]], rows[1:]
        try:
            m = np.asarray([[float(x) for x in r] for r in rows], dtype=float)
        except ValueError:
            raise ValueError(f"confusion file {p}: expected a table of numbers (CSV)") from None
    if m.ndim != 2 or m.shape[0] != m.shape[1]:
        raise ValueError(f"confusion file {p}: expected a square matrix, got shape {m.shape}")
    if names is None:
        if m.shape[0] != len(classes):
            raise ValueError(f"confusion file {p}: {m.shape[0]} classes without names, expected {len(classes)}")
        return m
    if len(names) != m.shape[0]:
        raise ValueError(f"confusion file {p}: {len(names)} class names for a {m.shape} matrix")
    common = [c for c in classes if c in names]
    if not common:
        raise ValueError(f"confusion file {p}: none of its classes {names} is one of {list(classes)}")
    out = np.zeros((len(classes), len(classes)))
    src = [names.index(c) for c in common]
    dst = [list(classes).index(c) for c in common]
    out[np.ix_(dst, dst)] = m[np.ix_(src, src)]
    return out


def view_rooms(scene, poses: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """The room each view's true class refers to.

    Args:
        scene: the house's :class:`envs.maps.scene.Scene` (``rooms``, ``instance_classes``, grid).
        poses: (N, 3) world x, z (metres), yaw (degrees).
        truth: (N,) true class index per view, -1 for a view that saw no floor.

    Returns:
        (N,) int room index (into ``scene.room_ids``): the nearest room of class ``truth``
        to the view's cell (Euclidean, cell centres; the room it stands in when that room
        has the class); -1 where ``truth`` is -1 or the house has no room of that class.
    """
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    truth = np.asarray(truth)
    out = np.full(len(truth), -1, dtype=np.int64)
    if len(truth) == 0:
        return out
    from scipy import ndimage  # noqa: PLC0415

    rooms = np.asarray(scene.rooms)
    h, w = rooms.shape
    r, c = scene.grid.world_to_cell(poses[:, 0], poses[:, 1])
    r, c = np.clip(r, 0, h - 1), np.clip(c, 0, w - 1)
    cls = np.asarray(scene.instance_classes)
    room_cls = np.where(rooms >= 0, cls[np.maximum(rooms, 0)], -1)
    for t in np.unique(truth[truth >= 0]):
        mask = room_cls == t
        if not mask.any():
            continue
        sel = truth == t
        _, (ir, ic) = ndimage.distance_transform_edt(~mask, return_indices=True)
        out[sel] = rooms[ir[r[sel], c[sel]], ic[r[sel], c[sel]]]
    return out


class NoiseModel:
    """How an oracle's labels go wrong; subclasses implement :meth:`labels`.

    ``needs_scene``: the model needs the house (its id, rooms) to draw.
    """

    name = "noise"
    needs_scene = False

    def labels(self, truth: np.ndarray, poses: np.ndarray, accuracy: float, wrong: np.ndarray, seed: int,
               scene=None) -> np.ndarray:
        """Noisy labels of N views.

        Args:
            truth: (N,) true class per view, -1 where the view saw no floor.
            poses: (N, 3) world x, z (metres), yaw (degrees).
            accuracy: chance of a view keeping its true class, in [0, 1].
            wrong: (C, C) wrong-class distributions (:func:`wrong_class_rows`).
            seed: the oracle's seed.
            scene: the house (needed when ``needs_scene``).

        Returns:
            (N,) int labels, -1 where ``truth`` is -1.
        """
        raise NotImplementedError

    def describe(self) -> str:
        """Short text of the model and its parameters (for logs and rows)."""
        return self.name


def _independent_labels(truth: np.ndarray, poses: np.ndarray, accuracy: float, wrong: np.ndarray,
                        seed: int) -> np.ndarray:
    """(N,) labels of views of true classes ``truth`` (>= 0) erring independently: a view is
    right when its stream's first draw is below ``accuracy``, else its second draw picks a class
    from the confusion row (:func:`wrong_classes`)."""
    truth = np.asarray(truth, np.int64)
    u = view_draws(seed, np.asarray(poses, float).reshape(-1, 3), 2)
    right = u[:, 0] < accuracy
    out = truth.copy()
    out[~right] = wrong_classes(u[~right, 1], truth[~right], wrong)
    return out


class Independent(NoiseModel):
    """Each view is right with probability ``accuracy``, independently of every other view;
    a wrong view draws its class from the confusion row of its true class."""

    name = "independent"

    def labels(self, truth, poses, accuracy, wrong, seed, scene=None):
        truth = np.asarray(truth)
        out = np.full(len(truth), -1, dtype=np.int64)
        idx = np.flatnonzero(truth >= 0)
        out[idx] = _independent_labels(truth[idx], np.asarray(poses, float)[idx], accuracy, wrong, seed)
        return out


class PerRoom(NoiseModel):
    """Errors shared by the views of a room.

    Args:
        correlation: in [0, 1], the chance that a view follows its room's draw (1: every
            view of a room is right, or all carry the room's one wrong class; 0: independent).
    """

    name = "per_room"
    needs_scene = True

    def __init__(self, correlation: float = 1.0):
        if not 0.0 <= float(correlation) <= 1.0:
            raise ValueError(f"per-room noise: correlation must be in [0, 1], got {correlation}")
        self.correlation = float(correlation)

    def describe(self) -> str:
        return f"{self.name}(correlation={self.correlation:g})"

    def room_label(self, house_id: str, room_id: str, t: int, accuracy: float, wrong: np.ndarray, seed: int) -> int:
        """The label a room gives its following views: ``t`` with probability ``accuracy``,
        else one wrong class from row ``t``.

        Returns:
            The class index.
        """
        rng = np.random.default_rng([int(seed), text_key(house_id, room_id), _ROOM])
        if rng.random() < accuracy:
            return int(t)
        return int(rng.choice(len(wrong), p=wrong[t]))

    def labels(self, truth, poses, accuracy, wrong, seed, scene=None):
        truth = np.asarray(truth)
        rooms = view_rooms(scene, poses, truth)
        out = np.full(len(truth), -1, dtype=np.int64)
        memo: dict[tuple[int, int], int] = {}
        follows = view_uniforms(seed, poses, _FOLLOW) < self.correlation
        alone = np.flatnonzero((truth >= 0) & ~follows)
        out[alone] = _independent_labels(truth[alone], np.asarray(poses, float)[alone], accuracy, wrong, seed)
        for i, t in enumerate(truth):
            if t < 0 or not follows[i]:
                continue
            t = int(t)
            k = int(rooms[i])
            if (k, t) not in memo:
                rid = scene.room_ids[k] if k >= 0 else f"no-room-of-class-{t}"
                memo[(k, t)] = self.room_label(str(scene.house_id), str(rid), t, accuracy, wrong, seed)
            out[i] = memo[(k, t)]
        return out


class PerHouse(NoiseModel):
    """A systematic bias towards one class per house.

    Args:
        bias_class: the class wrong views lean to (a name), or None to draw it per house
            (uniformly over the classes, seeded by the house id).
        strength: in [0, 1], the chance that a wrong view takes the bias class (else a class
            from its confusion row). A view whose true class is the bias class errs like
            :class:`Independent`.
    """

    name = "per_house"
    needs_scene = True

    def __init__(self, bias_class: str | None = None, strength: float = 1.0):
        if not 0.0 <= float(strength) <= 1.0:
            raise ValueError(f"per-house noise: strength must be in [0, 1], got {strength}")
        self.bias_class = None if bias_class is None else str(bias_class)
        self.strength = float(strength)

    def describe(self) -> str:
        return f"{self.name}(bias_class={self.bias_class or 'per house'}, strength={self.strength:g})"

    def bias(self, house_id: str, classes: Sequence[str], seed: int) -> int:
        """The bias class index of a house.

        Returns:
            The index of ``bias_class`` in ``classes``, or one drawn from the house id.

        Raises:
            ValueError: ``bias_class`` is not one of ``classes``.
        """
        if self.bias_class is not None:
            if self.bias_class not in classes:
                raise ValueError(f"per-house noise: bias_class {self.bias_class!r} is not one of {list(classes)}")
            return list(classes).index(self.bias_class)
        return int(np.random.default_rng([int(seed), text_key(house_id), _HOUSE]).integers(len(classes)))

    def labels(self, truth, poses, accuracy, wrong, seed, scene=None):
        truth = np.asarray(truth)
        b = self.bias(str(scene.house_id), tuple(scene.classes), seed)
        out = np.full(len(truth), -1, dtype=np.int64)
        idx = np.flatnonzero(truth >= 0)
        t, at = truth[idx].astype(np.int64), np.asarray(poses, float).reshape(-1, 3)[idx]
        u = view_draws(seed, at, 2)  # right or not, then the wrong class, from the view's stream
        leans = (t != b) & (view_uniforms(seed, at, _BIAS) < self.strength)  # a stream of its own
        out[idx] = np.where(u[:, 0] < accuracy, t, np.where(leans, b, wrong_classes(u[:, 1], t, wrong)))
        return out


def view_confusion(truth: np.ndarray, pred: np.ndarray, n_classes: int) -> np.ndarray:
    """(C, C) counts of (true, predicted) classes over views with a true class.

    Args:
        truth: (N,) true class, -1 to leave a view out.
        pred: (N,) predicted class.
        n_classes: C.

    Returns:
        (C, C) int64 counts, rows = true class.
    """
    t, p = np.asarray(truth, int), np.asarray(pred, int)
    m = t >= 0
    return np.bincount(t[m] * n_classes + p[m], minlength=n_classes * n_classes).reshape(n_classes, n_classes)


def classifier_confusion(env, viewpoints, renderer, method, house_ids: Sequence[str],
                         progress: bool = False) -> tuple[np.ndarray, int]:
    """A classifier's confusion on rendered views against the oracle's truth (the majority
    visible class): the matrix that drives the oracle's wrong classes in the ``confusion``
    noise setting. Needs a renderer that gives visible classes (the floorplan renderer).

    Args:
        env, viewpoints, renderer: stages built from ``conf/`` (the runner's).
        method: the :class:`benchmark.method.Method` whose classifier is measured (its
            ``classify`` step: refused views left out, the house given to the classifier).
        house_ids: the houses to render and classify (keep them apart from the classifier's
            training houses and from the houses the oracle is later run on).
        progress: show a progress bar.

    Returns:
        ((C, C) int64 counts, rows = true class, columns = predicted; number of views that
        saw no floor and were left out).
    """
    from benchmark.method import Context  # noqa: PLC0415
    from envs.render.observation import poses_array  # noqa: PLC0415

    classifier = method.classifier
    n = len(classifier.classes)
    counts = np.zeros((n, n), dtype=np.int64)
    blind = 0
    it = house_ids
    if progress:
        from tqdm.auto import tqdm  # noqa: PLC0415

        it = tqdm(house_ids, unit="house")
    if hasattr(classifier, "setup"):
        classifier.setup(list(house_ids))
    for hid in it:
        scene = env.scene(hid)
        obs = renderer.render(env.house(hid), scene, poses_array(viewpoints.generate(scene)))
        classified = method.classify(obs, Context(scene=scene, house_id=hid))
        truth = true_labels(classified.observations)
        pred = classified.proba.argmax(axis=1)
        counts += view_confusion(truth, pred, n)
        blind += int((truth < 0).sum())
    return counts, blind


__all__ = ["NoiseModel", "Independent", "PerRoom", "PerHouse", "load_confusion", "wrong_class_rows",
           "view_rooms", "view_confusion", "classifier_confusion", "pose_key", "pose_keys", "text_key", "view_rng", "view_draws", "view_uniforms", "wrong_classes", "uniform_confusion"]
