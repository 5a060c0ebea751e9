"""The robustness benchmark's summary: every method's score under each robot condition
(corruption family) at five severities, and its corruption error against a reference method,
the way ImageNet-C summarises image classifiers (Hendrycks and Dietterich, ICLR 2019).

Rows come from ``experiment=robustness`` (``make robustness``): each carries ``corruption``
(the family: ``clean``, ``scan``, ``pose``, ``explore``, ``classifier``, ``realistic``) and
``severity`` (0 clean, 1..5). For a metric m in percent (the paper's IoU, matched IoU, PQ):

* error E = 100 - m, per (method, family, severity), averaged over the dataset's houses;
* corruption error of method M on family f, relative to the reference method R:
  CE_f(M) = 100 x sum_s E_{s,f}(M) / sum_s E_{s,f}(R), over the severities s = 1..5;
* mCE(M) = the mean of CE_f(M) over the families (100 = as robust as the reference; lower is
  better);
* drop_f(M) = m_clean(M) - mean_s m_{s,f}(M): how much of its clean score the method loses
  (negative: the condition helped it).

A table cell never mixes house sets: every (method, family, severity) of one dataset must hold
the same houses, or the table is refused with one line naming the cells that differ.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

#: the corruption families in table order (``clean`` is severity 0 of every family).
FAMILIES = ("scan", "pose", "explore", "classifier", "realistic")
#: the metrics summarised (fractions in the rows, percent in the tables).
METRICS = ("iou", "matched_iou", "pq")
#: the method corruption errors are relative to by default: the classic geometric baseline
#: (Voronoi segmentation), which no view, pose or label reaches.
REFERENCE = "voronoi"
#: the geometric segmenters and the sanity rows among the methods (the sanity rows are shown,
#: not ranked).
GEOMETRIC = ("distance", "morphological", "voronoi")
SANITY = ("one_room", "gt_geometry", "grid")
#: words for the families, in tables and figures.
FAMILY_WORDS = {"scan": "scan map", "pose": "pose error", "explore": "exploration budget",
                "classifier": "classifier noise", "realistic": "realistic (all combined)"}


class RobustnessError(ValueError):
    """Rows that cannot make a fair robustness table (one line saying why)."""


def cell_means(rows: pd.DataFrame, metric: str) -> pd.DataFrame:
    """Mean metric (percent) per (method, corruption, severity) over the successful rows.

    Args:
        rows: per-house rows with ``method``, ``corruption``, ``severity``, ``house_id``,
            ``status`` and ``metric`` (a fraction).

    Returns:
        Columns method, corruption, severity, value (percent), n (houses).

    Raises:
        RobustnessError: cells holding different house sets, or a failed row in a cell (a
            mean over fewer houses would not compare).
    """
    need = {"method", "corruption", "severity", "house_id", metric}
    missing = sorted(need - set(rows.columns))
    if missing:
        raise RobustnessError(f"robustness rows lack column(s) {missing}")
    failed = rows[rows.get("status", "ok") != "ok"] if "status" in rows else rows.iloc[:0]
    if len(failed):
        f = failed.iloc[0]
        raise RobustnessError(f"{len(failed)} failed row(s), e.g. {f['method']} / {f['corruption']} "
                              f"{int(f['severity'])} / house {f['house_id']}: a cell would average fewer houses; "
                              f"fix or rerun them (their errors are in metrics.csv)")
    houses = rows.groupby(["method", "corruption", "severity"])["house_id"].agg(lambda s: tuple(sorted(s)))
    sets = houses.value_counts()
    if len(sets) > 1:
        common = sets.index[0]
        odd = houses[houses != common]
        (m, c, s), h = next(iter(odd.items()))
        raise RobustnessError(f"cells hold different house sets: {len(common)} houses in most cells but {len(h)} in "
                              f"{m} / {c} {s} (and {len(odd) - 1} more): rerun them on the same houses")
    g = rows.groupby(["method", "corruption", "severity"])[metric]
    out = pd.DataFrame({"value": 100.0 * g.mean(), "n": g.size()}).reset_index()
    return out


def summary_table(cells: pd.DataFrame, reference: str, families: Sequence[str] = FAMILIES) -> pd.DataFrame:
    """Per method: clean score, each family's mean over its severities, CE per family, mCE,
    each family's drop and the mean drop.

    Args:
        cells: :func:`cell_means` of one dataset and metric.
        reference: the method the corruption errors are relative to (a ``method`` value).
        families: families to report (those with rows).

    Returns:
        One row per method, sorted by mCE (then clean score); columns ``clean``, ``<family>``,
        ``CE <family>``, ``mCE``, ``drop <family>``, ``mean drop``.

    Raises:
        RobustnessError: no clean rows, the reference absent, or a family without all five
            severities for some method.
    """
    methods = sorted(cells["method"].unique())
    if reference not in methods:
        raise RobustnessError(f"reference method {reference!r} is not among the rows' methods {methods}")
    v = cells.set_index(["method", "corruption", "severity"])["value"]
    fams = [f for f in families if f in set(cells["corruption"])]
    out = pd.DataFrame(index=methods)
    try:
        out["clean"] = [v[(m, "clean", 0)] for m in methods]
    except KeyError as e:
        raise RobustnessError(f"no clean (severity 0) rows for {e.args[0][0]}") from None
    for f in fams:
        sev = sorted(cells.loc[cells["corruption"] == f, "severity"].unique())
        for m in methods:
            have = [s for s in sev if (m, f, s) in v.index]
            if have != sev:
                raise RobustnessError(f"{m}: family {f} has severities {have}, others {sev}")
        err = {m: float(np.sum([100.0 - v[(m, f, s)] for s in sev])) for m in methods}
        out[f] = [float(np.mean([v[(m, f, s)] for s in sev])) for m in methods]
        ref = err[reference]
        out[f"CE {f}"] = [100.0 * err[m] / ref if ref > 0 else np.nan for m in methods]
        out[f"drop {f}"] = out["clean"] - out[f]
    ce = [f"CE {f}" for f in fams]
    out["mCE"] = out[ce].mean(axis=1) if ce else np.nan
    out["mean drop"] = out[[f"drop {f}" for f in fams]].mean(axis=1) if fams else np.nan
    order = ["clean", *fams, *ce, "mCE", *[f"drop {f}" for f in fams], "mean drop"]
    out = out[order]
    out.index.name = "method"
    return out.sort_values(["mCE", "clean"], ascending=[True, False], na_position="last")


def rank_notes(table: pd.DataFrame, geometric: Sequence[str], cells: pd.DataFrame | None = None) -> list[str]:
    """One sentence per condition: which method ranks first, and whether the best view-based
    method or the best geometric one is ahead; with ``cells`` (:func:`cell_means`), also at
    which severities each is ahead, so a flip with severity shows."""
    notes = []
    fams = [c for c in table.columns if c in FAMILIES]
    geo = [m for m in table.index if m in set(geometric)]
    view = [m for m in table.index if m not in set(geometric)]
    for col in ("clean", *fams):
        first = table[col].idxmax()
        words = FAMILY_WORDS.get(col, col)
        line = f"{words}: {first} first ({table.loc[first, col]:.1f})"
        if geo and view:
            g, w = table.loc[geo, col].max(), table.loc[view, col].max()
            line += f"; best view-based {w:.1f}, best geometric {g:.1f}"
            flip = _flip(cells, col, geo, view) if cells is not None and col != "clean" else ""
            line += flip or f" ({'view-based ahead' if w > g else 'geometric ahead' if g > w else 'tied'})"
        notes.append(line)
    return notes


def _flip(cells: pd.DataFrame, family: str, geo: Sequence[str], view: Sequence[str]) -> str:
    """" (view-based ahead at severities 0-2, geometric ahead at severities 3-5)" (or "" when
    one side leads at every severity)."""
    v = cells.set_index(["method", "corruption", "severity"])["value"]
    sev = [0, *sorted(cells.loc[cells["corruption"] == family, "severity"].unique())]
    ahead = []
    for s in sev:
        c = "clean" if s == 0 else family
        g = max(v.get((m, c, s), -1.0) for m in geo)
        w = max(v.get((m, c, s), -1.0) for m in view)
        ahead.append("view-based" if w > g else "geometric" if g > w else "tied")
    if len(set(ahead)) == 1:
        return ""
    runs, start = [], 0
    for i in range(1, len(sev) + 1):
        if i == len(sev) or ahead[i] != ahead[start]:
            span = f"{sev[start]}" if i - 1 == start else f"{sev[start]}-{sev[i - 1]}"
            runs.append(f"{ahead[start]} ahead at severit{'y' if i - 1 == start else 'ies'} {span}")
            start = i
    return " (" + ", ".join(runs) + ")"


def to_markdown(table: pd.DataFrame, decimals: int = 1) -> str:
    """The table in Markdown (numbers with ``decimals``; missing values as a dash)."""
    header = ["method", *table.columns]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(["---", *["---:"] * len(table.columns)]) + "|"]
    for m, row in table.iterrows():
        cells = ["–" if not np.isfinite(x) else f"{x:.{decimals}f}" for x in row.to_numpy(dtype=float)]
        lines.append("| " + " | ".join([str(m).replace("|", "\\|"), *cells]) + " |")
    return "\n".join(lines) + "\n"


def to_latex(table: pd.DataFrame, caption: str, label: str, decimals: int = 1) -> str:
    """The table as a booktabs ``table`` environment."""
    from benchmark.reports.formatting import tex_escape

    cols = "l" + "r" * len(table.columns)
    head = " & ".join(["method", *[tex_escape(c) for c in table.columns]]) + r" \\"
    body = [" & ".join([tex_escape(str(m)), *["--" if not np.isfinite(x) else f"{x:.{decimals}f}"
                                              for x in row.to_numpy(dtype=float)]]) + r" \\"
            for m, row in table.iterrows()]
    return "\n".join([r"\begin{table}[t]", r"\centering", r"\scriptsize", rf"\begin{{tabular}}{{{cols}}}",
                      r"\toprule", head, r"\midrule", *body, r"\bottomrule", r"\end{tabular}",
                      rf"\caption{{{tex_escape(caption)}}}", rf"\label{{{label}}}", r"\end{table}", ""])


def drop_failed_houses(rows: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """Leave out every house that failed in any (method, condition): (rows, the houses left out)."""
    bad = sorted(set(rows.loc[rows["status"] != "ok", "house_id"].astype(str)))
    return rows[~rows["house_id"].astype(str).isin(bad)], bad


def summarise(rows: pd.DataFrame, metrics: Sequence[str], reference: str) -> dict:
    """Per dataset and metric: the summary table, its cells, and notes. Raises RobustnessError."""
    out = {}
    for dataset, d in rows.groupby("dataset"):
        d, dropped = drop_failed_houses(d)
        for metric in metrics:
            cells = cell_means(d, metric)
            table = summary_table(cells, reference)
            out[(dataset, metric)] = {"table": table, "cells": cells, "dropped": dropped,
                                      "houses": int(cells["n"].iloc[0]) if len(cells) else 0,
                                      "notes": rank_notes(table.drop(index=[m for m in SANITY if m in table.index]),
                                                          GEOMETRIC, cells)}
    return out


#: colour-blind safe colours (Okabe and Ito, 2008) and line styles, cycled per method.
OKABE_ITO = ("#000000", "#E69F00", "#56B4E9", "#009E73", "#0072B2", "#D55E00", "#CC79A7", "#F0E442")  # yellow last
STYLES = ("-", "--", ":", "-.")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")


def family_figure(cells: pd.DataFrame, family: str, path: Path, metric_words: str, title: str) -> list[Path]:
    """Metric vs severity (0 = clean .. 5) for one family, one line per method, colour-blind
    safe (Okabe-Ito colours, and a marker and line style per method so that it reads in grey);
    written as PNG and PDF. Returns the files."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from benchmark.reports.plotting import save

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    for i, m in enumerate(sorted(cells["method"].unique())):
        c = cells[cells["method"] == m]
        clean = c[c["corruption"] == "clean"]
        fam = c[c["corruption"] == family].sort_values("severity")
        x = [0, *fam["severity"].tolist()]
        y = [float(clean["value"].iloc[0]) if len(clean) else np.nan, *fam["value"].tolist()]
        ax.plot(x, y, color=OKABE_ITO[i % len(OKABE_ITO)], linestyle=STYLES[(i // len(OKABE_ITO)) % len(STYLES)],
                marker=MARKERS[i % len(MARKERS)], markersize=4, linewidth=1.4, label=m)
    ax.set_xlabel("severity (0 = clean)")
    ax.set_ylabel(f"{metric_words} (%)")
    ax.set_xticks(range(int(cells["severity"].max()) + 1))
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return save(fig, path.with_suffix(".png"), formats=("png", "pdf"))


__all__ = ["FAMILIES", "METRICS", "RobustnessError", "cell_means", "drop_failed_houses", "summarise", "summary_table",
           "rank_notes", "to_markdown",
           "to_latex", "family_figure"]
