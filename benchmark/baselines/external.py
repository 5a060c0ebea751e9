"""Score another method's output maps against matching ground-truth maps.

**Pairing.** Either a naming rule: both file patterns contain ``{id}`` (e.g. ground truth
``NN_ground_truth.png`` and predictions ``NN_output.png``, see :func:`pairs_by_pattern`), or
a manifest: a CSV with columns ``id, ground_truth, prediction`` (paths relative to the
manifest's folder; an empty prediction means the method gave no map, see
:func:`pairs_from_manifest`). Every ground-truth map gets a row; a missing or unreadable
prediction gives a ``failed`` row naming the file, so no map is silently dropped, and
predictions with no ground truth are reported as unpaired.

**Formats.** ``"instance"``: one colour per room, black not walkable, read with
:func:`envs.maps.label_png.read_instance_png` (the SeLRoS release, VRF, ROSE²); ``"label"``: a
class-coloured label PNG with its sidecar, read with :func:`envs.maps.label_png.read_label_png` (its
segments are the connected regions of one class, as for our own label maps).

**Reading colours.** Colours in ``params.not_room_colours`` (black and white by default: the
SeLRoS and VRF outputs have 1-px white lines along the image border) are never rooms; a colour
on less than ``params.min_colour_m2`` is anti-aliasing and joins the nearest room
(:func:`envs.maps.label_png.read_instance_png`). Every row says what the reader did:
``gt_rooms`` / ``pred_rooms`` (colours that became rooms), ``*_antialias_px`` and
``*_unassigned_px`` (pixels of not-a-room colours other than black), so a misread shows.

**Sanity rows.** :func:`sanity_rows` scores, on the same ground truth, the whole walkable map
as one segment (``one_room``), the ground truth's own rooms (``gt_geometry``) and 3 m squares
(``grid``): the segmenters of :mod:`benchmark.segmenters.sanity`.

**Resolution.** ``resolution`` is the ground truth's metres per pixel (needed: areas are in
m²). A prediction at
``pred_resolution`` (when given and different) is scaled by nearest neighbour onto the
ground-truth grid with both maps' top-left corners at the same place, then cropped or
padded (-1); with ``pred_resolution=None`` a prediction of another size is taken to cover
the same extent and is resampled onto the ground-truth shape.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.metrics import (
    METRIC_COLUMNS,
    MetricParams,
    describe,
    resample_nearest,
    score_instances,
    score_semantic,
    segments,
)
from envs.maps.label_png import read_instance_png, read_label_png

#: What the PNG reader did, per row (NaN for label maps and failed rows).
READ_COLUMNS = ("gt_rooms", "gt_antialias_px", "gt_unassigned_px", "pred_rooms", "pred_antialias_px",
                "pred_unassigned_px")

#: Names of the sanity rows (as the runner's segmenter options).
SANITY_METHODS = ("one_room", "gt_geometry", "grid")

#: Map formats :func:`read_map` understands.
FORMATS = ("instance", "label")


@dataclass(frozen=True)
class Pair:
    """One map to score: its id, ground-truth file and prediction file (None: missing)."""

    map_id: str
    gt: Path
    pred: Path | None


@dataclass
class MapSample:
    """The maps of a few ids kept while scoring, to be drawn (``baselines table5``'s page):
    ``gt[id]`` the ground truth's room ids and ``pred[(method, id)]`` each method's segments,
    both (H, W) int, -1 none, on the ground truth's grid."""

    ids: frozenset
    gt: dict = field(default_factory=dict)
    pred: dict = field(default_factory=dict)

    def add(self, method: str, map_id: str, pred: np.ndarray, gt: np.ndarray) -> None:
        if map_id in self.ids:
            self.gt.setdefault(map_id, gt)
            self.pred[(method, map_id)] = pred


def _glob_ids(folder: Path, pattern: str) -> dict[str, Path]:
    if "{id}" not in pattern:
        raise ValueError(f"file pattern {pattern!r} must contain '{{id}}'")
    rx = re.compile("^" + re.escape(pattern).replace(r"\{id\}", "(?P<id>.+?)") + "$")
    out = {}
    for p in sorted(folder.iterdir()) if folder.is_dir() else []:
        m = rx.match(p.name)
        if m:
            out[m.group("id")] = p
    return out


def pairs_by_pattern(gt_dir: str | Path, gt_pattern: str, pred_dir: str | Path,
                     pred_pattern: str) -> tuple[list[Pair], list[Path]]:
    """Pair files by the ``{id}`` in their names -> (one pair per ground-truth map, predictions
    whose id has no ground truth)."""
    gt_dir, pred_dir = Path(gt_dir), Path(pred_dir)
    for what, d in (("ground-truth", gt_dir), ("prediction", pred_dir)):
        if not d.is_dir():
            raise FileNotFoundError(f"{what} folder not found: {d}")
    gts = _glob_ids(gt_dir, gt_pattern)
    if not gts:
        raise FileNotFoundError(f"no ground-truth map matching {gt_pattern!r} in {gt_dir}")
    preds = _glob_ids(pred_dir, pred_pattern)
    # a missing prediction keeps the file name it should have had, for the error message
    pairs = [Pair(mid, g, preds.get(mid, pred_dir / pred_pattern.replace("{id}", mid))) for mid, g in gts.items()]
    return pairs, [p for mid, p in preds.items() if mid not in gts]


def pairs_from_manifest(path: str | Path) -> list[Pair]:
    """Pairs listed in a CSV manifest with columns ``id, ground_truth, prediction``; relative
    paths are taken from the manifest's folder; an empty prediction is a missing map."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"manifest not found: {path}")
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        need = {"id", "ground_truth", "prediction"}
        if reader.fieldnames is None or not need <= set(reader.fieldnames):
            raise ValueError(f"manifest {path} must have columns {sorted(need)}, got {reader.fieldnames}")
        rows = list(reader)
    if not rows:
        raise ValueError(f"manifest {path} lists no map")
    ids = [r["id"] for r in rows]
    if len(set(ids)) != len(ids):
        raise ValueError(f"manifest {path} repeats ids: {sorted({i for i in ids if ids.count(i) > 1})}")

    def resolve(p: str) -> Path | None:
        p = (p or "").strip()
        return None if not p else (Path(p) if Path(p).is_absolute() else path.parent / p)

    return [Pair(r["id"], resolve(r["ground_truth"]), resolve(r["prediction"])) for r in rows]


def read_map(path: str | Path, fmt: str, params: MetricParams, resolution: float) -> tuple[np.ndarray, dict]:
    """A map file -> ((H, W) int32 ids: room instances or class labels, -1 none; reader info).

    Args:
        path: the PNG.
        fmt: ``"instance"`` (colour per room) or ``"label"`` (class colours with sidecar).
        params: colour rules (``min_colour_m2``, ``not_room_colours``).
        resolution: metres per pixel of this image (turns ``min_colour_m2`` into pixels).
    Returns: (ids, info) with info ``rooms``, ``antialias_px``, ``unassigned_px`` (instance
        maps; empty for label maps).
    """
    if fmt == "instance":
        inst, info = read_instance_png(path, min_pixels=params.min_colour_px(resolution),
                                       not_room=params.not_room_colours, return_info=True)
        return inst, info
    if fmt == "label":
        labels, classes = read_label_png(path)
        return labels, {"classes": list(classes)}
    raise ValueError(f"map format must be one of {FORMATS}, got {fmt!r}")


def onto_grid(pred: np.ndarray, shape: tuple[int, int], resolution: float | None = None,
              pred_resolution: float | None = None) -> np.ndarray:
    """Bring a prediction onto the ground-truth grid of ``shape`` (see module doc).

    Args:
        pred: (h, w) int ids.
        shape: (H, W) of the ground truth.
        resolution, pred_resolution: metres per pixel of the ground truth and of ``pred``;
            both given and different -> scale about the top-left corner, crop/pad with -1.
    Returns: (H, W) int ids.
    """
    if pred_resolution is None or resolution is None or np.isclose(pred_resolution, resolution):
        return pred if pred.shape == tuple(shape) else resample_nearest(pred, shape)
    if pred_resolution <= 0 or resolution <= 0:
        raise ValueError(f"resolutions must be positive metres/pixel, got {resolution}, {pred_resolution}")
    f = pred_resolution / resolution
    scaled = resample_nearest(pred, (max(int(round(pred.shape[0] * f)), 1), max(int(round(pred.shape[1] * f)), 1)))
    out = np.full(shape, -1, dtype=np.int32)
    h, w = min(shape[0], scaled.shape[0]), min(shape[1], scaled.shape[1])
    out[:h, :w] = scaled[:h, :w]
    return out


def _check_resolution(resolution) -> float:
    if resolution is None or isinstance(resolution, bool) or not isinstance(resolution, (int, float)) \
            or not resolution > 0:
        raise ValueError(f"resolution (metres per pixel of the ground truth) must be a positive number, got "
                         f"{resolution!r}: areas in m² are turned into pixels with it")
    return float(resolution)


def _base_row(map_id: str, dataset: str, method: str, resolution: float, params: MetricParams) -> dict:
    row: dict = dict.fromkeys(METRIC_COLUMNS, np.nan) | dict.fromkeys(READ_COLUMNS, np.nan)
    row |= {"house_id": map_id, "dataset": dataset, "method": method, "resolution": resolution,
            "metric_params": describe(params, resolution, colours=True), "prediction": "", "status": "ok",
            "error": ""}
    return row


def read_gt(path: str | Path, fmt: str, params: MetricParams, resolution: float) -> tuple[np.ndarray, dict]:
    """A ground-truth map -> ((H, W) int32 room ids, -1 none; reader info). Label-format ground
    truth: rooms are the connected regions of one class."""
    gt, info = read_map(path, fmt, params, resolution)
    if fmt == "label":
        gt = segments(gt, params.connectivity)
    return gt, info


def _score(pred: np.ndarray, pi: dict, gt: np.ndarray, gi: dict, pair: Pair, gt_format: str, pred_format: str,
           params: MetricParams, resolution: float) -> dict:
    """A prediction against its ground truth. A label map (classes, no ids) is split into
    connected segments as the method's own label maps are (``metrics.connectivity``); when both
    maps carry classes it is scored semantically (accuracy and class IoU by class name)."""
    if pred_format != "label":
        return score_instances(pred, gt, params, resolution=resolution)
    if gt_format != "label":  # no classes to compare: the label map's connected segments
        return score_instances(segments(pred, params.connectivity), gt, params, resolution=resolution)
    labels, gt_classes = read_label_png(pair.gt)  # the ground truth's classes, by name
    names = list(pi["classes"]) + [c for c in gt_classes if c not in pi["classes"]]
    remap = np.array([names.index(c) for c in gt_classes] + [-1], np.int64)
    sem = remap[labels]  # -1 -> the trailing -1
    inst_cls = np.array([int(np.bincount(sem[gt == k][sem[gt == k] >= 0]).argmax()) if (sem[gt == k] >= 0).any()
                         else -1 for k in range(int(gt.max()) + 1)], np.int64)
    return score_semantic(pred, gt, inst_cls, params, classes=names, resolution=resolution)


def score_pairs(pairs: list[Pair], method: str, params: MetricParams = MetricParams(), dataset: str = "external",
                gt_format: str = "instance", pred_format: str = "instance", *, resolution: float,
                pred_resolution: float | None = None, keep: MapSample | None = None) -> pd.DataFrame:
    """One row per pair: ``method``'s map scored against the ground truth (see module doc).

    Args:
        pairs: maps to score.
        method: value of the ``method`` column.
        params: metric and colour rules.
        dataset: value of the ``dataset`` column.
        gt_format, pred_format: ``"instance"`` or ``"label"``.
        resolution: metres per pixel of the ground truth.
        pred_resolution: metres per pixel of the predictions (None: same extent).
        keep: where to keep the maps of a few ids (label maps as their connected segments).
    Returns: DataFrame with columns house_id, dataset, method, resolution, metric_params,
        prediction, status ("ok" / "failed"), error, every metric of
        :data:`benchmark.metrics.METRIC_COLUMNS` (NaN on a failed row) and :data:`READ_COLUMNS`.
    """
    for f in (gt_format, pred_format):
        if f not in FORMATS:
            raise ValueError(f"map format must be one of {FORMATS}, got {f!r}")
    resolution = _check_resolution(resolution)
    rows = []
    for pair in pairs:
        row = _base_row(pair.map_id, dataset, method, resolution, params)
        row["prediction"] = str(pair.pred or "")
        try:
            if pair.pred is None:
                raise FileNotFoundError(f"no prediction listed for map {pair.map_id!r}")
            if not Path(pair.pred).is_file():
                raise FileNotFoundError(f"no prediction for map {pair.map_id!r}: {pair.pred} not found")
            gt, gi = read_gt(pair.gt, gt_format, params, resolution)
            pred, pi = read_map(pair.pred, pred_format, params, pred_resolution or resolution)
            pred = onto_grid(pred, gt.shape, resolution, pred_resolution)
            row.update(_score(pred, pi, gt, gi, pair, gt_format, pred_format, params, resolution))
            if keep is not None:
                keep.add(method, pair.map_id, segments(pred, params.connectivity) if pred_format == "label" else pred,
                         gt)
            gi, pi = ({k: v for k, v in i.items() if k != "classes"} for i in (gi, pi))
            row.update({f"gt_{k}": v for k, v in gi.items()} | {f"pred_{k}": v for k, v in pi.items()})
        except Exception as e:  # one missing or bad map fails alone, with its reason
            row["status"] = "failed"
            row["error"] = f"{type(e).__name__}: {e}"
        rows.append(row)
    return pd.DataFrame(rows)


def sanity_rows(gt_paths: dict[str, Path], params: MetricParams = MetricParams(), dataset: str = "external",
                gt_format: str = "instance", *, resolution: float, grid_size: float = 3.0,
                keep: MapSample | None = None) -> pd.DataFrame:
    """The sanity rows on each ground-truth map: ``one_room`` (the walkable map as one segment),
    ``gt_geometry`` (the ground truth's own rooms) and ``grid`` (``grid_size`` m squares).

    Args:
        gt_paths: map id -> ground-truth file.
        params, dataset, gt_format, resolution: as :func:`score_pairs`.
        grid_size: side of the grid's squares, metres.
    Returns: DataFrame, three rows per map, columns as :func:`score_pairs`.
    """
    from types import SimpleNamespace

    from benchmark.segmenters.sanity import Grid, GroundTruthGeometry, OneRoom
    from envs.maps.gridmap import GridMap

    resolution = _check_resolution(resolution)
    segs = {"one_room": OneRoom(), "gt_geometry": GroundTruthGeometry(), "grid": Grid(grid_size)}
    rows = []
    for mid, path in gt_paths.items():
        try:
            gt, gi = read_gt(path, gt_format, params, resolution)
            grid = GridMap(gt >= 0, resolution, (0.0, 0.0))
            err = None
        except Exception as e:  # a bad ground truth fails its rows alone
            err = f"{type(e).__name__}: {e}"
        for name, seg in segs.items():
            row = _base_row(mid, dataset, name, resolution, params)
            if err:
                row.update(status="failed", error=err)
            else:
                inst = seg(grid, scene=SimpleNamespace(instances=gt)) if name == "gt_geometry" else seg(grid)
                row.update(score_instances(inst, gt, params, resolution=resolution))
                row.update({f"gt_{k}": v for k, v in gi.items()})
                if keep is not None:
                    keep.add(name, mid, inst, gt)
            rows.append(row)
    return pd.DataFrame(rows)


@dataclass
class ExternalMethod:
    """Another method's output maps and how to pair and read them (``conf/scoring/external/*.yaml``).

    Args:
        method: name in the ``method`` column.
        resolution: metres per pixel of the ground truth.
        gt_dir, gt_pattern: ground-truth folder and file name rule with ``{id}``.
        pred_dir, pred_pattern: prediction folder and rule with ``{id}``.
        manifest: CSV ``id, ground_truth, prediction`` (replaces folders and patterns).
        pred_resolution: metres per pixel of the predictions (None: same extent as the GT).
        gt_format, pred_format: ``"instance"`` or ``"label"``.
        dataset: name in the ``dataset`` column.
    """

    method: str
    resolution: float
    gt_dir: str | None = None
    gt_pattern: str = "{id}_ground_truth.png"
    pred_dir: str | None = None
    pred_pattern: str | None = None
    manifest: str | None = None
    pred_resolution: float | None = None
    gt_format: str = "instance"
    pred_format: str = "instance"
    dataset: str = "external"
    unpaired: list = field(default_factory=list, init=False, repr=False)

    def __post_init__(self) -> None:
        if not self.method:
            raise ValueError("external.method: a method name is needed (e.g. external.method=ROSE2)")
        _check_resolution(self.resolution)
        for f in (self.gt_format, self.pred_format):
            if f not in FORMATS:
                raise ValueError(f"external format must be one of {FORMATS}, got {f!r}")
        if not self.manifest and not (self.gt_dir and self.pred_dir and self.pred_pattern):
            raise ValueError("external: give either manifest=FILE.csv or gt_dir, pred_dir and pred_pattern (with {id})")

    def pairs(self) -> list[Pair]:
        """The maps to score (predictions with no ground truth go to ``self.unpaired``)."""
        if self.manifest:
            return pairs_from_manifest(self.manifest)
        pairs, unpaired = pairs_by_pattern(self.gt_dir, self.gt_pattern, self.pred_dir, self.pred_pattern)
        self.unpaired = [str(p) for p in unpaired]
        return pairs

    def score(self, params: MetricParams = MetricParams(), sanity: bool = False,
              grid_size: float = 3.0, keep: MapSample | None = None) -> pd.DataFrame:
        """Rows of :func:`score_pairs` (+ :func:`sanity_rows` when ``sanity``); predictions with
        no ground truth are listed in ``df.attrs["unpaired"]``; ``keep``: see :class:`MapSample`."""
        pairs = self.pairs()
        df = score_pairs(pairs, self.method, params, self.dataset, self.gt_format, self.pred_format,
                         resolution=self.resolution, pred_resolution=self.pred_resolution, keep=keep)
        if sanity:
            gts = {p.map_id: p.gt for p in pairs}
            df = pd.concat([df, sanity_rows(gts, params, self.dataset, self.gt_format, resolution=self.resolution,
                                            grid_size=grid_size, keep=keep)], ignore_index=True)
        df.attrs["unpaired"] = list(self.unpaired)
        return df


def score_directory(
    gt_dir: str | Path, gt_pattern: str, pred_dir: str | Path, pred_pattern: str, method: str,
    params: MetricParams = MetricParams(), dataset: str = "external", *, resolution: float,
    pred_resolution: float | None = None, gt_format: str = "instance", pred_format: str = "instance",
) -> pd.DataFrame:
    """One row per ground-truth map in ``gt_dir``: metrics of ``method``'s map with the same id
    (:class:`ExternalMethod` with folders and patterns)."""
    return ExternalMethod(method, resolution, str(gt_dir), gt_pattern, str(pred_dir), pred_pattern, None,
                          pred_resolution, gt_format, pred_format, dataset).score(params)


#: Columns of the summary table: the paper's three, then the ones merging cannot game.
SUMMARY_METRICS = ("iou", "precision", "recall", "matched_iou", "pq", "room_iou", "ipa_recall", "ipa_precision")


def summary_table(df: pd.DataFrame, metrics: tuple[str, ...] = SUMMARY_METRICS) -> pd.DataFrame:
    """Table V-style summary: per method, the mean over its successful maps with its 95 %
    interval (``mean [lo, hi]``, percentile bootstrap over maps, :mod:`benchmark.stats`),
    in percent, then the mean segment count, count error and reader counts, the maps scored and
    failed."""
    from benchmark.stats import bootstrap_ci  # noqa: PLC0415

    ok = df[df["status"] == "ok"]
    methods = list(dict.fromkeys(df["method"]))
    g = ok.groupby("method", sort=False)
    out = pd.DataFrame(index=pd.Index(methods, name="method"))
    out["maps"] = g.size().reindex(methods).fillna(0).astype(int)
    for m in metrics:
        mean = g[m].mean().reindex(methods)
        ci = {k: bootstrap_ci(v.dropna().to_numpy()) for k, v in g[m]}
        out[m] = [("n/a" if not np.isfinite(a) else f"{100 * a:.2f}" if not np.isfinite(ci.get(k, (np.nan,))[0])
                   else f"{100 * a:.2f} [{100 * ci[k][0]:.2f}, {100 * ci[k][1]:.2f}]") for k, a in zip(methods, mean)]
    out["segments"] = [f"{v:.1f}" if np.isfinite(v) else "n/a"
                       for v in g["n_pred_segments"].mean().reindex(methods)]
    out["count_error"] = [f"{v:+.1f}" if np.isfinite(v) else "n/a" for v in g["count_error"].mean().reindex(methods)]
    if "pred_unassigned_px" in ok:
        out["unassigned_px"] = [f"{v:.0f}" if np.isfinite(v) else "–"
                                for v in g["pred_unassigned_px"].mean().reindex(methods)]
    out["failed"] = df[df["status"] != "ok"].groupby("method").size().reindex(methods).fillna(0).astype(int)
    return out.reset_index()


def failures(df: pd.DataFrame) -> pd.DataFrame:
    """The failed or missing maps: method, house_id and the reason."""
    return df.loc[df["status"] != "ok", ["method", "house_id", "error"]].reset_index(drop=True)


def report(df: pd.DataFrame, params: MetricParams, out: Path | None = None, note: str = "",
           resolution: float | None = None, extra: dict[str, str] | None = None) -> str:
    """Write ``df`` as ``out/metrics.csv`` (per map) and its Table V-style summary as
    ``out/table5.md``, ``table5.csv`` and ``table5.tex`` (when ``out`` is given; the set written
    as a whole), and print the summary, the metric parameters, then every failed/missing map.

    Returns: the printed text."""
    from envs.atomic import atomic_write_text  # noqa: PLC0415

    summary = summary_table(df)
    text = summary.to_markdown(index=False)
    text += (f"\n\nMean [95 % interval] over maps (percentile bootstrap over maps, 2000 resamples, seed 0), "
             f"percent; segments, count error (segments - rooms) and unassigned "
             f"pixels (prediction pixels of not-a-room colours) are means. Metrics: "
             f"{describe(params, resolution, colours=True)}{note}\n")
    bad = failures(df)
    if len(bad):
        text += f"\nFailed or missing maps ({len(bad)}):\n\n" + bad.to_markdown(index=False) + "\n"
    unpaired = df.attrs.get("unpaired") or []
    if unpaired:
        text += f"\nPredictions with no ground-truth map ({len(unpaired)}): " + ", ".join(unpaired) + "\n"
    if out:
        from envs.atomic import atomic_folder  # noqa: PLC0415

        with atomic_folder(out) as tmp:
            atomic_write_text(tmp / "metrics.csv", df.to_csv(index=False))
            atomic_write_text(tmp / "table5.md", text)
            atomic_write_text(tmp / "table5.csv", summary.to_csv(index=False))
            atomic_write_text(tmp / "table5.tex", summary.to_latex(index=False, escape=True, caption=(
                f"Comparison on the same maps (mean [95 % interval] over maps, percent). {describe(params, resolution)}"),
                label="tab:table5"))
            for name, body in (extra or {}).items():
                atomic_write_text(tmp / name, body)
    print(text, end="")
    return text
