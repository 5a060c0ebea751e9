"""Per-view labels from a file: a robot's own labels (or another model's probabilities)
as the classifier stage (``classifier=labels``).

The file is a CSV with a header row, or JSON (a list of objects, or ``{"labels": [...]}``
or ``{"views": [...]}``); column names are case-insensitive. Two layouts:

* **Names**: a ``label`` column (``label_column``) with one class name per view; the
  probability row is one-hot.
* **Probabilities**: no ``label`` column; one numeric column per class, named after the
  class (non-negative; each row is divided by its sum, which must be > 0).

Columns ``id``, ``image``, ``house_id`` and the pose columns (``x, y, z, yaw, theta, row,
col``) are never classes.

**Class list.** ``classes`` from the config, in that order; a name in the file that is not
in it, or (probabilities) a column that is neither a class nor one of the columns above, is
an error naming them and the file. With ``classes=None`` (open label sets: any number of
classes) they come from the file: the sorted distinct names, or the probability columns in
file order. Class names are kept as written (case and spaces stripped at the ends only).

**Matching rows to views** (``match``):

* ``order``: row i is view i; the file must have exactly one row per view.
* ``id``: the file's ``id`` column equals the view's ``Observation.meta["id"]`` (the image
  folder renderer and ``roomseg-segment`` set it from the pose file's ``id`` column, or the
  image name); every view needs a row, ids must be unique.
* ``pose``: the file's pose columns in ``frame`` (``sim``: x, z, yaw degrees; ``ros``: x, y,
  theta radians) equal the view's pose within ``tolerance_m`` metres (each of x and z) and
  ``tolerance_deg`` degrees; every view needs exactly one such row.
* ``auto`` (default): ``id`` when the file has an ``id`` column and every view an id,
  else ``pose`` when the file has the frame's pose columns, else ``order``.

``path`` may hold ``{house_id}``, filled from the views' ``meta["house_id"]`` (then
``classes`` must be given, since the class list is needed before any view is seen).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.interfaces import Classifier
from envs.maps.pose_files import FRAME_COLUMNS, poses_from_table, read_table
from envs.render.image_folder import match_poses

MATCHES = ("auto", "order", "id", "pose")
#: Columns that are never read as class probabilities.
RESERVED = frozenset({"id", "image", "house_id", "x", "y", "z", "yaw", "theta", "row", "col"})


def read_label_table(path: str | Path) -> pd.DataFrame:
    """A labels file as a table with lower-cased, stripped column names.

    Args:
        path: ``.csv`` (header row) or ``.json`` (list of objects, ``{"labels": [...]}`` or
            ``{"views": [...]}``).

    Returns:
        The DataFrame, one row per view in file order.
    """
    path = Path(path).expanduser()
    if not path.is_file():
        raise FileNotFoundError(f"labels file not found: {path}")
    df = read_table(path, what="labels", as_text=True)
    df.columns = [str(c).strip().lower() for c in df.columns]
    dup = sorted({c for c in df.columns if list(df.columns).count(c) > 1})
    if dup:
        raise ValueError(f"{path}: column(s) {dup} appear more than once")
    if len(df) == 0:
        raise ValueError(f"{path}: no rows; expected one row per view")
    return df


def _names(df: pd.DataFrame, col: str, path: Path) -> list[str]:
    out = []
    for i, v in enumerate(df[col].tolist()):
        s = "" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v).strip()
        if not s:
            raise ValueError(f"{path}: column {col!r} is empty at row {i}; expected a class name per view")
        out.append(s)
    return out


def _numeric(df: pd.DataFrame, col: str, path: Path, what: str) -> np.ndarray:
    raw = df[col]
    vals = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
    bad = ~np.isfinite(vals)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{path}: column {col!r} has {raw.iloc[i]!r} at row {i}; expected {what}")
    return vals


def table_probabilities(df: pd.DataFrame, path: Path, classes: Sequence[str] | None,
                        label_column: str = "label") -> tuple[np.ndarray, tuple[str, ...]]:
    """The (R, C) probability rows of a labels table and the class list.

    Args:
        df: the table (:func:`read_label_table`).
        path: the file, for messages.
        classes: the configured class list, or None to take it from the file.
        label_column: the column of class names.

    Returns:
        ((R, C) float64 rows summing to 1, classes). ValueError naming the file and the
        names or columns that do not fit.
    """
    label_column = label_column.strip().lower()
    if label_column in df.columns:
        names = _names(df, label_column, path)
        if classes is None:
            classes = tuple(sorted(set(names)))
        classes = tuple(classes)
        index = {c: k for k, c in enumerate(classes)}
        unknown = sorted({n for n in names if n not in index})
        if unknown:
            rows = [i for i, n in enumerate(names) if n not in index][:5]
            raise ValueError(f"{path}: column {label_column!r} has name(s) {unknown} not in the class list "
                             f"{list(classes)} (rows {rows}); add them to classes or fix the file")
        proba = np.zeros((len(names), len(classes)))
        proba[np.arange(len(names)), [index[n] for n in names]] = 1.0
        return proba, classes
    cand = [c for c in df.columns if c not in RESERVED]
    if classes is None:
        classes = tuple(cand)
    classes = tuple(classes)
    if not cand:
        raise ValueError(f"{path}: no {label_column!r} column and no probability columns; expected a class name "
                         f"per view in {label_column!r}, or one column per class, found columns {list(df.columns)}")
    lower = {c.strip().lower(): c for c in classes}
    extra = [c for c in cand if c not in lower]
    if extra:
        raise ValueError(f"{path}: probability column(s) {extra} are not in the class list {list(classes)}")
    missing = [c for c in classes if c.strip().lower() not in df.columns]
    if missing:
        raise ValueError(f"{path}: lacks probability column(s) {missing}; expected one column per class "
                         f"{list(classes)} (or a {label_column!r} column)")
    proba = np.column_stack([_numeric(df, c.strip().lower(), path, "a probability >= 0") for c in classes])
    neg = np.argwhere(proba < 0)
    if len(neg):
        i, k = neg[0]
        raise ValueError(f"{path}: column {classes[k]!r} has {float(proba[i, k])!r} at row {i}; expected a probability >= 0")
    total = proba.sum(axis=1)
    if (total <= 0).any():
        i = int(np.argmax(total <= 0))
        raise ValueError(f"{path}: row {i} has probabilities summing to {float(total[i])!r}; expected a positive sum")
    return proba / total[:, None], classes


class LabelsFileClassifier(Classifier):
    """Per-view class probabilities read from a file (see the module doc for the layouts).

    Args:
        path: the CSV / JSON labels file (may hold ``{house_id}``).
        classes: ordered class names, or None to take them from the file.
        match: ``auto`` | ``order`` | ``id`` | ``pose``: how rows pair with views.
        label_column: the column of class names.
        frame: ``sim`` (x, z, yaw degrees) or ``ros`` (x, y, theta radians): the pose columns
            used by ``match=pose``.
        tolerance_m: largest difference in x and in z (metres) of a pose match.
        tolerance_deg: largest heading difference (degrees) of a pose match.
    """

    def __init__(self, path: str, classes: Sequence[str] | None = None, match: str = "auto",
                 label_column: str = "label", frame: str = "sim", tolerance_m: float = 1e-3,
                 tolerance_deg: float = 0.5):
        if match not in MATCHES:
            raise ValueError(f"classifier.match is {match!r}; expected one of {list(MATCHES)}")
        if frame not in ("sim", "ros"):
            raise ValueError(f"classifier.frame is {frame!r}; expected 'sim' (x, z, yaw) or 'ros' (x, y, theta)")
        if not (tolerance_m >= 0 and tolerance_deg >= 0):
            raise ValueError(f"classifier tolerances must be >= 0, got {tolerance_m} m, {tolerance_deg} degrees")
        if path is None or not str(path).strip():
            raise ValueError("classifier.path is not set; expected the labels file (CSV or JSON)")
        self.path, self.match, self.label_column, self.frame = str(path), match, label_column, frame
        self.tolerance_m, self.tolerance_deg = float(tolerance_m), float(tolerance_deg)
        self.templated = "{house_id}" in self.path
        if classes is not None:
            classes = tuple(str(c) for c in classes)
            if not classes or len(set(classes)) != len(classes):
                raise ValueError(f"classifier.classes must be a non-empty list of distinct names, got {list(classes)}")
            self.classes = classes
        elif self.templated:
            raise ValueError(f"classifier.path {self.path!r} depends on the house; give classifier.classes too")
        else:
            self.classes = self.read()[1]

    def setup(self, eval_house_ids: Sequence[str]) -> None:
        """Nothing to prepare."""

    def file_for(self, observations: Sequence) -> Path:
        """The labels file of these views (``{house_id}`` filled from their meta)."""
        if not self.templated:
            return Path(self.path).expanduser()
        ids = {o.meta.get("house_id") for o in observations}
        if None in ids or len(ids) != 1:
            raise ValueError(f"classifier.path {self.path!r} needs every view's meta['house_id'] (one house), "
                             f"got {sorted(map(str, ids))}")
        return Path(self.path.format(house_id=ids.pop())).expanduser()

    def read(self, path: Path | None = None) -> tuple[pd.DataFrame, tuple[str, ...], np.ndarray]:
        """(table, classes, (R, C) probabilities) of the labels file."""
        path = path or Path(self.path).expanduser()
        df = read_label_table(path)
        proba, classes = table_probabilities(df, path, getattr(self, "classes", None), self.label_column)
        return df, classes, proba

    def predict_proba(self, observations: Sequence) -> np.ndarray:
        """(N, C) float64 probabilities of the N views, rows summing to 1."""
        path = self.file_for(observations)
        df, _, proba = self.read(path)
        rows = self.rows_for(df, path, observations)
        return proba[rows]

    def match_mode(self, df: pd.DataFrame, observations: Sequence) -> str:
        """The matching rule ``auto`` resolves to for this file and these views."""
        if self.match != "auto":
            return self.match
        if "id" in df.columns and all(o.meta.get("id") is not None for o in observations):
            return "id"
        if all(c in df.columns for c in FRAME_COLUMNS[self.frame]):
            return "pose"
        return "order"

    def rows_for(self, df: pd.DataFrame, path: Path, observations: Sequence) -> np.ndarray:
        """(N,) int row of the file for each view."""
        mode = self.match_mode(df, observations)
        n = len(observations)
        if mode == "order":
            if len(df) != n:
                raise ValueError(f"{path}: {len(df)} rows for {n} views (match=order pairs row i with view i); "
                                 f"give one row per view, or ids / poses to match by")
            return np.arange(n)
        if mode == "id":
            return self._rows_by_id(df, path, observations)
        return self._rows_by_pose(df, path, observations)

    def _rows_by_id(self, df: pd.DataFrame, path: Path, observations: Sequence) -> np.ndarray:
        if "id" not in df.columns:
            raise ValueError(f"{path}: match=id needs an 'id' column, found columns {list(df.columns)}")
        ids = [str(v).strip() for v in df["id"].tolist()]
        dup = sorted(k for k, n in Counter(ids).items() if n > 1)
        if dup:
            raise ValueError(f"{path}: column 'id' repeats {dup[:5]}; expected one row per view")
        where = {v: k for k, v in enumerate(ids)}
        want = []
        for i, o in enumerate(observations):
            if o.meta.get("id") is None:
                raise ValueError(f"view {i} has no id (Observation.meta['id']) to match with {path}")
            want.append(str(o.meta["id"]).strip())
        missing = [w for w in want if w not in where]
        if missing:
            raise ValueError(f"{path}: column 'id' has no row for view id(s) {missing[:5]}"
                             f"{' and more' if len(missing) > 5 else ''}")
        return np.array([where[w] for w in want], dtype=np.int64)

    def _rows_by_pose(self, df: pd.DataFrame, path: Path, observations: Sequence) -> np.ndarray:
        cols = FRAME_COLUMNS[self.frame]
        missing = [c for c in cols if c not in df.columns]
        if missing:
            raise ValueError(f"{path}: match=pose in frame {self.frame!r} needs column(s) {missing}, found "
                             f"{list(df.columns)}")
        listed = poses_from_table(df, path, self.frame)
        poses = np.array([o.pose for o in observations], dtype=float).reshape(-1, 3)
        rows = np.empty(len(poses), np.int64)
        for i, near in enumerate(match_poses(listed, poses, self.tolerance_m, self.tolerance_deg)):
            if len(near) != 1:
                x, z, yaw = poses[i]
                what = "no row" if not near else f"{len(near)} rows (e.g. {near[:3]})"
                raise ValueError(f"{path}: {what} within {self.tolerance_m} m and {self.tolerance_deg} degrees of "
                                 f"view {i} at x={x:.4f}, z={z:.4f}, yaw={yaw:.2f} (frame {self.frame!r}); "
                                 f"expected exactly one")
            rows[i] = near[0]
        return rows


__all__ = ["LabelsFileClassifier", "MATCHES", "read_label_table", "table_probabilities"]
