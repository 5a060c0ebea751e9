"""Score a folder of another method's output maps against matching ground-truth maps.

Pairing is by a naming rule: both patterns contain ``{id}`` (e.g. ground truth
``NN_ground_truth.png`` and predictions ``NN_output.png``); every ground-truth map gets a
row, and a missing or unreadable prediction gives a ``failed`` row naming the file, so no
map is silently dropped. Both maps are instance-coloured PNGs (one colour per room, black
not walkable, read with :func:`envs.mapio.read_instance_png`); a prediction of another
size is resampled (nearest) onto the ground-truth grid.
"""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd

from benchmark.metrics import MetricParams, describe, resample_nearest, score_instances
from envs.mapio import DEFAULT_MIN_PIXELS, read_instance_png


def _glob_ids(folder: Path, pattern: str) -> dict[str, Path]:
    if "{id}" not in pattern:
        raise ValueError(f"pattern {pattern!r} must contain '{{id}}'")
    rx = re.compile("^" + re.escape(pattern).replace(r"\{id\}", "(?P<id>.+?)") + "$")
    out = {}
    for p in sorted(folder.iterdir()) if folder.is_dir() else []:
        m = rx.match(p.name)
        if m:
            out[m.group("id")] = p
    return out


def score_directory(
    gt_dir: str | Path, gt_pattern: str, pred_dir: str | Path, pred_pattern: str, method: str,
    params: MetricParams = MetricParams(), dataset: str = "external", min_pixels: int = DEFAULT_MIN_PIXELS,
    resolution: float | None = None,
) -> pd.DataFrame:
    """One row per ground-truth map: metrics of ``method``'s map with the same id.

    Args:
        gt_dir, gt_pattern: ground-truth folder and file name pattern with ``{id}``.
        pred_dir, pred_pattern: prediction folder and pattern with ``{id}``.
        method: method name for the ``method`` column.
        params: metric parameters.
        dataset: value of the ``dataset`` column.
        min_pixels: colours on fewer pixels are anti-aliasing (see envs.mapio).
        resolution: metres per pixel of the maps (recorded in the rows).
    """
    gt_dir, pred_dir = Path(gt_dir), Path(pred_dir)
    if not gt_dir.is_dir():
        raise FileNotFoundError(f"ground-truth folder not found: {gt_dir}")
    gts = _glob_ids(gt_dir, gt_pattern)
    if not gts:
        raise FileNotFoundError(f"no ground-truth map matching {gt_pattern!r} in {gt_dir}")
    preds = _glob_ids(pred_dir, pred_pattern)
    rows = []
    for mid, gpath in gts.items():
        row = {"house_id": mid, "dataset": dataset, "method": method, "resolution": resolution,
               "metric_params": describe(params), "prediction": "", "status": "ok", "error": ""}
        try:
            if mid not in preds:
                raise FileNotFoundError(f"no prediction {pred_pattern.format(id=mid)} in {pred_dir}")
            row["prediction"] = str(preds[mid])
            gt = read_instance_png(gpath, min_pixels=min_pixels)
            pred = read_instance_png(preds[mid], min_pixels=min_pixels)
            if pred.shape != gt.shape:
                pred = resample_nearest(pred, gt.shape)
            row.update(score_instances(pred, gt, params))
        except Exception as e:  # one missing or bad map fails alone, with its reason
            row["status"] = "failed"
            row["error"] = f"{type(e).__name__}: {e}"
        rows.append(row)
    return pd.DataFrame(rows)


def report(df: pd.DataFrame, params: MetricParams, out: Path | None = None, note: str = "") -> None:
    """Write ``df`` as ``out/metrics.csv`` (when given) and print its Table V-style summary
    with the metric parameters."""
    from envs.atomic import atomic_write_text  # noqa: PLC0415

    if out:
        atomic_write_text(Path(out) / "metrics.csv", df.to_csv(index=False))
    print(summary_table(df).to_markdown(index=False))
    print(f"\nMean ± std over maps, percent. Metrics: {describe(params)}{note}")


def summary_table(df: pd.DataFrame, metrics: tuple[str, ...] = ("iou", "precision", "recall")) -> pd.DataFrame:
    """Table V-style summary: mean and std per method over its successful maps, in percent,
    with the count of maps and of failed/missing ones."""
    ok = df[df["status"] == "ok"]
    g = ok.groupby("method", sort=False)
    out = pd.DataFrame({"maps": g.size()})
    for m in metrics:
        out[m] = [f"{100 * a:.2f} ± {100 * s:.2f}" for a, s in zip(g[m].mean(), g[m].std(ddof=1).fillna(0))]
    failed = df[df["status"] != "ok"].groupby("method").size()
    out["failed"] = failed.reindex(out.index).fillna(0).astype(int)
    return out.reset_index()
