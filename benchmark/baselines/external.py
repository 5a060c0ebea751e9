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

**Resolution.** ``resolution`` is the ground truth's metres per pixel. A prediction at
``pred_resolution`` (when given and different) is scaled by nearest neighbour onto the
ground-truth grid with both maps' top-left corners at the same place, then cropped or
padded (-1); with ``pred_resolution=None`` a prediction of another size is taken to cover
the same extent and is resampled onto the ground-truth shape.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.metrics import MetricParams, describe, resample_nearest, score_instances, segments
from envs.maps.label_png import DEFAULT_MIN_PIXELS, read_instance_png, read_label_png

#: Metric columns every row has (NaN on a failed row).
METRIC_COLUMNS = ("iou", "precision", "recall", "accuracy", "n_pred_segments", "n_gt_segments")

#: Map formats :func:`read_map` understands.
FORMATS = ("instance", "label")


@dataclass(frozen=True)
class Pair:
    """One map to score: its id, ground-truth file and prediction file (None: missing)."""

    map_id: str
    gt: Path
    pred: Path | None


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


def read_map(path: str | Path, fmt: str = "instance", min_pixels: int = DEFAULT_MIN_PIXELS) -> np.ndarray:
    """A map file -> (H, W) int32 ids (room instances or class labels), -1 not walkable.

    Args:
        fmt: ``"instance"`` (colour per room) or ``"label"`` (class colours with sidecar).
        min_pixels: instance maps only: colours on fewer pixels are anti-aliasing (envs.maps.label_png).
    """
    if fmt == "instance":
        return read_instance_png(path, min_pixels=min_pixels)
    if fmt == "label":
        return read_label_png(path)[0]
    raise ValueError(f"map format must be one of {FORMATS}, got {fmt!r}")


def onto_grid(pred: np.ndarray, shape: tuple[int, int], resolution: float | None = None,
              pred_resolution: float | None = None) -> np.ndarray:
    """Bring a prediction onto the ground-truth grid of ``shape`` (see module doc).

    Args:
        resolution, pred_resolution: metres per pixel of the ground truth and of ``pred``;
            both given and different -> scale about the top-left corner, crop/pad with -1.
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


def score_pairs(pairs: list[Pair], method: str, params: MetricParams = MetricParams(), dataset: str = "external",
                gt_format: str = "instance", pred_format: str = "instance", min_pixels: int = DEFAULT_MIN_PIXELS,
                resolution: float | None = None, pred_resolution: float | None = None) -> pd.DataFrame:
    """One row per pair: ``method``'s map scored against the ground truth (see module doc).

    Columns: house_id, dataset, method, resolution, metric_params, prediction, status
    ("ok" / "failed"), error, and the metrics of :func:`benchmark.metrics.score_instances`
    (iou, precision, recall, accuracy = NaN, n_pred_segments, n_gt_segments).
    """
    for f in (gt_format, pred_format):
        if f not in FORMATS:
            raise ValueError(f"map format must be one of {FORMATS}, got {f!r}")
    rows = []
    for pair in pairs:
        row: dict = dict.fromkeys(METRIC_COLUMNS, np.nan)
        row |= {"house_id": pair.map_id, "dataset": dataset, "method": method, "resolution": resolution,
               "metric_params": describe(params), "prediction": str(pair.pred or ""), "status": "ok", "error": ""}
        try:
            if pair.pred is None:
                raise FileNotFoundError(f"no prediction listed for map {pair.map_id!r}")
            if not Path(pair.pred).is_file():
                raise FileNotFoundError(f"no prediction for map {pair.map_id!r}: {pair.pred} not found")
            gt = read_map(pair.gt, gt_format, min_pixels)
            if gt_format == "label":  # rooms = connected regions of one class
                gt = segments(gt, params.connectivity)
            pred = onto_grid(read_map(pair.pred, pred_format, min_pixels), gt.shape, resolution, pred_resolution)
            row.update(score_instances(pred, gt, params))
        except Exception as e:  # one missing or bad map fails alone, with its reason
            row["status"] = "failed"
            row["error"] = f"{type(e).__name__}: {e}"
        rows.append(row)
    return pd.DataFrame(rows)


def score_directory(
    gt_dir: str | Path, gt_pattern: str, pred_dir: str | Path, pred_pattern: str, method: str,
    params: MetricParams = MetricParams(), dataset: str = "external", min_pixels: int = DEFAULT_MIN_PIXELS,
    resolution: float | None = None, pred_resolution: float | None = None, gt_format: str = "instance",
    pred_format: str = "instance",
) -> pd.DataFrame:
    """One row per ground-truth map in ``gt_dir``: metrics of ``method``'s map with the same id.

    Args:
        gt_dir, gt_pattern: ground-truth folder and file name pattern with ``{id}``.
        pred_dir, pred_pattern: prediction folder and pattern with ``{id}``.
        method: method name for the ``method`` column.
        params: metric parameters.
        dataset: value of the ``dataset`` column.
        min_pixels: colours on fewer pixels are anti-aliasing (see envs.maps.label_png).
        resolution, pred_resolution: metres per pixel of the ground truth and predictions.
        gt_format, pred_format: ``"instance"`` or ``"label"``.
    Predictions whose id has no ground truth are listed in ``df.attrs["unpaired"]``.
    """
    pairs, unpaired = pairs_by_pattern(gt_dir, gt_pattern, pred_dir, pred_pattern)
    df = score_pairs(pairs, method, params, dataset, gt_format, pred_format, min_pixels, resolution, pred_resolution)
    df.attrs["unpaired"] = [str(p) for p in unpaired]
    return df


def summary_table(df: pd.DataFrame, metrics: tuple[str, ...] = ("iou", "precision", "recall")) -> pd.DataFrame:
    """Table V-style summary: mean and std per method over its successful maps, in percent,
    with the count of maps scored and of failed/missing ones."""
    ok = df[df["status"] == "ok"]
    methods = list(dict.fromkeys(df["method"]))
    g = ok.groupby("method", sort=False)
    out = pd.DataFrame(index=pd.Index(methods, name="method"))
    out["maps"] = g.size().reindex(methods).fillna(0).astype(int)
    for m in metrics:
        mean, std = g[m].mean().reindex(methods), g[m].std(ddof=1).reindex(methods).fillna(0)
        out[m] = [f"{100 * a:.2f} ± {100 * s:.2f}" if np.isfinite(a) else "n/a" for a, s in zip(mean, std)]
    out["failed"] = df[df["status"] != "ok"].groupby("method").size().reindex(methods).fillna(0).astype(int)
    return out.reset_index()


def failures(df: pd.DataFrame) -> pd.DataFrame:
    """The failed or missing maps: method, house_id and the reason."""
    return df.loc[df["status"] != "ok", ["method", "house_id", "error"]].reset_index(drop=True)


def report(df: pd.DataFrame, params: MetricParams, out: Path | None = None, note: str = "") -> None:
    """Write ``df`` as ``out/metrics.csv`` and ``out/table5.md`` (when given) and print its
    Table V-style summary, the metric parameters, then every failed/missing map."""
    from envs.atomic import atomic_write_text  # noqa: PLC0415

    text = summary_table(df).to_markdown(index=False)
    text += f"\n\nMean ± std over maps, percent. Metrics: {describe(params)}{note}\n"
    bad = failures(df)
    if len(bad):
        text += f"\nFailed or missing maps ({len(bad)}):\n\n" + bad.to_markdown(index=False) + "\n"
    unpaired = df.attrs.get("unpaired") or []
    if unpaired:
        text += f"\nPredictions with no ground-truth map ({len(unpaired)}): " + ", ".join(unpaired) + "\n"
    if out:
        atomic_write_text(Path(out) / "metrics.csv", df.to_csv(index=False))
        atomic_write_text(Path(out) / "table5.md", text)
    print(text, end="")
