"""Per-house metrics tables -> the paper's tables (Markdown, CSV, LaTeX) and the sensitivity plot.

``python -m benchmark.commands.tables RUN_DIR [RUN_DIR ...] [--table table4] [--out DIR]``

Reads every ``metrics.csv`` under the given folders (runs of :mod:`benchmark.harness.runner`, or
per-map tables of the baselines), keeps successful rows, and reports mean and standard
deviation over houses per table cell, with the number of houses and of failed houses.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.harness.cache import atomic_write_text
from benchmark.harness.store import iter_metric_files
from benchmark.reports import formatting


@dataclass(frozen=True)
class TableSpec:
    """How to group a per-house table into one of the paper's tables.

    ``rows``/``cols`` are row columns grouped into table rows and table columns; ``metrics``
    are averaged over houses; ``where`` keeps rows whose column equals (or is in) a value;
    ``exclude`` drops rows whose column equals a value.
    """

    title: str
    rows: tuple[str, ...]
    cols: tuple[str, ...] = ()
    metrics: tuple[str, ...] = ("iou", "accuracy")
    where: dict = field(default_factory=dict)
    exclude: dict = field(default_factory=dict)
    #: keep the sanity segmenters' rows (one room, ground-truth geometry, grid) as rows of
    #: their own: classifier "sanity", aggregator = the segmenter (README "Metrics").
    sanity: bool = False


#: the sanity segmenters (benchmark/segmenters/sanity.py), shown in comparison tables.
SANITY_SEGMENTERS = ("one_room", "gt_geometry", "grid")


#: the metrics beside the paper's that merging cannot game (README "Metrics"), in every
#: comparison table (fractions, shown in percent; count_error, segments minus rooms, is a
#: count and shown as it is).
ROBUST_METRICS = ("matched_iou", "pq", "room_iou", "ipa_recall", "ipa_precision", "count_error")

TABLES: dict[str, TableSpec] = {
    "table2": TableSpec("Table II: viewpoint strategies (no post-processing)",
                        rows=("dataset", "classifier", "aggregator"), cols=("viewpoints",),
                        where={"postprocess": "none"}, exclude={"segmenter_row": True}),
    "table3": TableSpec("Table III: post-processing, mean over all classifier x aggregator combinations",
                        rows=("dataset",), cols=("postprocess",), exclude={"segmenter_row": True}),
    "table4": TableSpec("Table IV: classifier x aggregator per dataset (with post-processing)",
                        rows=("classifier", "aggregator"), cols=("dataset",),
                        metrics=("iou", "matched_iou", "pq", "accuracy"),
                        exclude={"postprocess": "none", "segmenter_row": True}, sanity=True),
    "table5": TableSpec("Table V: comparison with baselines", rows=("dataset", "method"),
                        metrics=("iou", "precision", "recall", *ROBUST_METRICS, "accuracy")),
    "sensitivity": TableSpec("Sensitivity to classifier accuracy (oracle; classifier = noise model)",
                             rows=("classifier", "oracle_accuracy"), cols=("aggregator", "postprocess"),
                             metrics=("iou", "accuracy", "view_accuracy_seen"),
                             exclude={"segmenter_row": True}),
    "all": TableSpec("Every configuration", rows=("dataset", "method"),
                     metrics=("iou", "precision", "recall", *ROBUST_METRICS, "accuracy")),
}


def find_metric_files(paths: Sequence[str | Path]) -> list[Path]:
    """Every ``metrics.csv`` at or under ``paths`` (a path may also be a CSV file itself)."""
    out = list(iter_metric_files(paths))
    if not out:
        raise FileNotFoundError(f"no metrics.csv under {[str(p) for p in paths]}")
    return out


def method_label(row: pd.Series) -> str:
    """A row's method name: an explicit ``method``, a segmenter, or classifier+aggregator+post."""
    if isinstance(row.get("method"), str) and row.get("method"):
        return row["method"]
    if isinstance(row.get("segmenter"), str) and row.get("segmenter"):
        return row["segmenter"]
    parts = [str(row.get(k, "")) for k in ("classifier", "aggregator")]
    acc = row.get("oracle_accuracy")
    if isinstance(acc, float) and not np.isnan(acc):
        parts[0] += f"@{acc:g}"
    post = str(row.get("postprocess", ""))
    return "+".join(p for p in parts if p) + (" +post" if post and post != "none" else "")


def load_rows(paths: Sequence[str | Path]) -> pd.DataFrame:
    """All rows of all metrics files, with a ``method`` and a ``segmenter_row`` column."""
    frames = []
    for f in find_metric_files(paths):
        df = pd.read_csv(f, keep_default_na=True)
        df["source"] = str(f)
        frames.append(df)
    df = pd.concat(frames, ignore_index=True)
    for col in ("classifier", "aggregator", "postprocess", "viewpoints", "segmenter", "dataset"):
        if col not in df:
            df[col] = ""
        df[col] = df[col].astype("string").fillna("").astype(str)
    if "status" not in df:
        df["status"] = "ok"
    df["method"] = df.apply(method_label, axis=1)
    df["segmenter_row"] = df["segmenter"].str.len() > 0
    return df


def summarise(df: pd.DataFrame, spec: TableSpec) -> pd.DataFrame:
    """Mean, std and count over houses per (rows, cols) cell; ``n_failed`` per cell too."""
    sel = df
    sanity = None
    if spec.sanity and "segmenter" in df:
        sanity = df[df["segmenter"].isin(SANITY_SEGMENTERS)].copy()
        if not sanity.empty:
            sanity["classifier"], sanity["aggregator"] = "sanity", sanity["segmenter"]
            sanity["segmenter_row"], sanity["postprocess"] = False, "default"
            sel = pd.concat([sel[~sel.index.isin(sanity.index)], sanity], ignore_index=True)
    for k, v in spec.where.items():
        if k in sel:
            sel = sel[sel[k].isin(v if isinstance(v, list | tuple) else [v])]
    for k, v in spec.exclude.items():
        if k in sel:
            sel = sel[sel[k] != v]
    keys = [c for c in (*spec.rows, *spec.cols) if c in sel]
    if sel.empty or not keys:
        return pd.DataFrame()
    ok = sel[sel["status"] == "ok"]
    metrics = [m for m in spec.metrics if m in ok]
    g = ok.groupby(keys, dropna=False)[metrics]
    out = pd.concat({"mean": g.mean(), "std": g.std(ddof=1), }, axis=1)
    out.columns = [f"{m}_{s}" for s, m in out.columns]
    out["n"] = ok.groupby(keys, dropna=False).size()
    out["n_failed"] = sel[sel["status"] != "ok"].groupby(keys, dropna=False).size()
    out["n_failed"] = out["n_failed"].fillna(0).astype(int)
    return out.reset_index()


#: tables that compare values of one column: printed only when that column takes >= 2
#: values in the rows read (else a line says why the table is left out).
NEEDS_VARYING: dict[str, tuple[str, str]] = {
    "table2": ("viewpoints", "viewpoint strategies"),
    "table3": ("postprocess", "post-processing settings (none and default)"),
    "sensitivity": ("oracle_accuracy", "oracle accuracies"),
}


def why_empty(df: pd.DataFrame, name: str, summary: pd.DataFrame) -> str | None:
    """None when table ``name`` has something to show in ``summary``; otherwise one line
    saying why not (no rows selected, or the one column it compares does not vary)."""
    if summary.empty:
        spec = TABLES[name]
        sel = ", ".join([f"{k}={v}" for k, v in spec.where.items()] +
                        [f"{k}!={v}" for k, v in spec.exclude.items() if k != "segmenter_row"])
        return f"no rows{(' with ' + sel) if sel else ''} among the {len(df)} rows read"
    if name == "table5":
        baseline = df["segmenter_row"] | (df["classifier"] == "") if "segmenter_row" in df else df["classifier"] == ""
        if not baseline.any():
            return (f"it compares methods with baselines; none of the {len(df)} rows read is a baseline "
                    "(segmenter=... or scored external maps)")
    if name in NEEDS_VARYING:
        col, words = NEEDS_VARYING[name]
        vals = summary[col].dropna().unique() if col in summary else []
        if len(vals) < 2:
            shown = ", ".join(formatting.value_label(col, v) for v in vals) or "none"
            return f"it compares {words}; the rows read have {len(vals)} ({shown})"
    return None


def format_cells(summary: pd.DataFrame, spec: TableSpec, percent: bool = True, name: str = "") -> formatting.Grid:
    """The display grid of one table (see :mod:`benchmark.reports.formatting`)."""
    return formatting.build_grid(summary, spec.rows, spec.cols, spec.metrics, spec.title, percent,
                                 by_metric=name in formatting.BY_METRIC, pooled=name in formatting.POOLED)


def metric_notes(df: pd.DataFrame) -> list[str]:
    """The metric parameter lines of the rows (printed beside every table)."""
    if "metric_params" not in df:
        return []
    return sorted({str(v) for v in df["metric_params"].dropna().unique()})


def render(paths: Sequence[str | Path], tables: Sequence[str] | None = None, out_dir: Path | None = None,
           percent: bool = True) -> str:
    """Markdown text of the requested tables; with ``out_dir`` also write .md/.csv/.tex each.

    ``tables`` None: every table the rows have data for; a table left out (or asked for
    and empty) gets one line saying why. Returns the text printed by the command.
    """
    df = load_rows(paths)
    chunks, skipped = [], []
    asked = tables is not None
    for name in (tables if asked else list(TABLES)):
        if name not in TABLES:
            raise ValueError(f"unknown table {name!r}; expected one of {sorted(TABLES)}")
        spec = TABLES[name]
        if not asked and name == "all":
            continue
        summ = summarise(df, spec)
        reason = why_empty(df, name, summ)
        if reason is not None and (summ.empty or not asked):
            skipped.append(f"{spec.title}: left out, {reason}.")
            continue
        grid = format_cells(summ, spec, percent, name)
        notes = metric_notes(df)
        unit = "in percent" if percent else "as fractions"
        caption = f"{spec.title}. Mean ± std over {grid.over}, {unit}. " + " ".join(grid.notes)
        md = (f"### {spec.title}\n\n" + formatting.to_markdown(grid) + "\n\n" +
              f"Mean ± std over {grid.over}, {unit}. " + " ".join(grid.notes) +
              (" Metrics: " + "; ".join(notes) + "." if notes else "") +
              (f" Note: {reason}." if reason else "") + "\n")
        chunks.append(md)
        if out_dir is not None:
            out_dir.mkdir(parents=True, exist_ok=True)
            atomic_write_text(out_dir / f"{name}.md", md)
            atomic_write_text(out_dir / f"{name}.csv", summ.to_csv(index=False))
            atomic_write_text(out_dir / f"{name}.tex", formatting.to_latex(grid, f"tab:{name}", caption.strip()))
        if name == "sensitivity" and out_dir is not None and reason is None:
            from benchmark.reports.sensitivity_plots import plot_sensitivity_per_noise  # noqa: PLC0415

            if not plot_sensitivity_per_noise(summ, out_dir):  # one plot per noise model, and an overview
                plot_sensitivity(summ, out_dir / "sensitivity.png")
    if skipped:
        chunks.append("\n".join(skipped) + "\n")
    failed = df[df["status"] != "ok"]
    if len(failed):
        reasons = failed["error"].fillna("").str.split(":").str[0].value_counts()
        chunks.append(f"{len(failed)} of {len(df)} rows failed: " +
                      ", ".join(f"{k} x{v}" for k, v in reasons.items()) + "\n")
    return "\n".join(chunks)


def plot_sensitivity(summary: pd.DataFrame, path: Path, formats: Sequence[str] | None = None) -> list[Path]:
    """IoU and pixel accuracy (mean ± std over houses) against the oracle's accuracy: one
    line per aggregator x post-processing, a fixed colour per aggregator (Okabe-Ito) and a
    solid (post-processed) or dashed (raw) line, labelled in words.

    Returns:
        the files written (``path``, or ``path`` with each of ``formats``).
    """
    from benchmark.reports.plotting import plt, save

    colours = {"graph_knn": "#0072B2", "vision_cone": "#D55E00", "euclidean_knn": "#009E73"}
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), sharex=True)
    groups = [c for c in ("aggregator", "postprocess") if c in summary]
    keys = sorted(summary.groupby(groups).groups, key=lambda k: tuple(
        formatting._sort_key(c)(v) for c, v in zip(groups, k if isinstance(k, tuple) else (k,))))
    for key in keys:
        kt = key if isinstance(key, tuple) else (key,)
        g = summary
        for c, v in zip(groups, kt):
            g = g[g[c] == v]
        g = g.sort_values("oracle_accuracy")
        vals = dict(zip(groups, kt))
        label = formatting.combo_label(groups, kt)
        if vals.get("postprocess") == "none":
            label += " (raw)"
        style = "--" if vals.get("postprocess") == "none" else "-"
        for ax, m in zip(axes, ("iou", "accuracy")):
            ax.errorbar(g["oracle_accuracy"] * 100, g[f"{m}_mean"] * 100, yerr=g[f"{m}_std"] * 100, marker="o",
                        ms=4, capsize=3, ls=style, color=colours.get(vals.get("aggregator", ""), None), label=label)
    for ax, m in zip(axes, ("IoU (%)", "pixel accuracy (%)")):
        ax.set_xlabel("oracle classifier accuracy (%)")
        ax.set_ylabel(m)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    n = int(summary["n"].max()) if "n" in summary and len(summary) else 0
    fig.suptitle(f"Segmentation quality against classifier accuracy (mean ± std over {n} houses)", fontsize=10)
    fig.tight_layout()
    return save(fig, path, formats)
