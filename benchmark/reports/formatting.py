"""How summarised tables look: Markdown and LaTeX (booktabs), names and metrics in words.

:func:`build_grid` turns one table's summary (mean, std, n per cell, from
:func:`benchmark.reports.tables.summarise`) into a :class:`Grid`: row labels, a two-level
column header (e.g. dataset -> metric, or metric -> aggregator x post-processing) and
numeric cells. :func:`to_markdown` and :func:`to_latex` print a grid; both print the same
numbers with a fixed number of decimals per table, and neither puts ``|`` in a header cell.

The LaTeX output needs ``\\usepackage{booktabs}`` (said in its first line); it is a
``table`` float when the estimated width fits one column of a two-column article
(``\\columnwidth``, about 229 pt in ``article``, 252 pt in IEEEtran) and a full-width
``table*`` otherwise (also said in the first line). The width estimate is checked against
pdflatex's own measure in ``tests/test_tables_format.py``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

#: metric column -> short header word (Markdown and LaTeX).
METRIC_LABELS: dict[str, str] = {
    "iou": "IoU", "accuracy": "acc", "precision": "P", "recall": "R", "matched_iou": "matched IoU",
    "room_iou": "room IoU", "room_recall": "room R", "pq": "PQ", "sq": "SQ", "rq": "RQ",
    "pq_semantic": "semantic PQ", "segment_count_error": "segment count error", "class_iou": "class IoU",
    "view_accuracy": "view acc", "view_accuracy_seen": "view acc (seen)", "count_error": "segments - rooms",
    "ipa_precision": "ipa P", "ipa_recall": "ipa R", "matched_precision": "matched P", "matched_recall": "matched R",
}
#: metric column -> words for a caption or a plot axis.
METRIC_WORDS: dict[str, str] = {"iou": "IoU", "accuracy": "pixel accuracy", "precision": "precision",
                                "recall": "recall"}
#: grouping column -> header words.
KEY_LABELS: dict[str, str] = {"oracle_accuracy": "oracle accuracy", "postprocess": "post-processing",
                              "viewpoints": "viewpoints", "dataset": "dataset", "method": "method",
                              "classifier": "classifier", "aggregator": "aggregator"}
#: (grouping column, value) -> words; values not listed are printed as they are.
VALUE_LABELS: dict[str, dict[str, str]] = {
    "aggregator": {"graph_knn": "graph KNN", "vision_cone": "vision cone", "euclidean_knn": "Euclidean KNN",
                   "one_room": "one room", "gt_geometry": "ground-truth geometry", "grid": "3 m grid"},
    "classifier": {"sanity": "(sanity row)"},
    "postprocess": {"none": "raw", "default": "post"},
    "dataset": {"procthor": "ProcTHOR", "procthor_shared": "ProcTHOR", "architecthor": "ArchitecTHOR",
                "synthetic": "synthetic"},
    "viewpoints": {"autotrace": "autotrace", "autotrace_sparse": "autotrace (sparse)", "file": "from file"},
}
#: display order of known values (others follow, sorted).
VALUE_ORDER: dict[str, tuple[str, ...]] = {
    "postprocess": ("none", "default"),
    "aggregator": ("graph_knn", "vision_cone", "euclidean_knn", "one_room", "grid", "gt_geometry"),
    "classifier": ("objects", "oracle", "cnn", "dinov2", "vlm", "sanity"),
}
#: tables whose columns are grouped by metric first (one Markdown table per metric).
BY_METRIC = frozenset({"sensitivity"})
#: metrics that are counts, not fractions: shown as they are, never scaled to percent.
COUNT_METRICS = frozenset({"count_error", "n_pred_segments", "n_gt_segments", "n_views", "n_refused"})

#: tables whose cells pool several configurations (so a cell counts maps, not houses).
POOLED = frozenset({"table3"})

DASH = "–"


def finite_float(v) -> float | None:
    """``v`` as a float, or None when it is missing, not a number, or NaN (a CSV cell, a
    config value)."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        return None
    return None if math.isnan(f) else f


def metric_words(metric: str) -> str:
    """Words for a metric (``accuracy`` -> ``pixel accuracy``, ``view_accuracy_seen`` ->
    ``view accuracy seen``)."""
    return METRIC_WORDS.get(metric, METRIC_LABELS.get(metric, metric.replace("_", " ")))


def value_label(key: str, value) -> str:
    """Words for one grouping value (``graph_knn`` -> ``graph KNN``; 0.8 -> ``0.8``)."""
    if value is None:
        return DASH
    if isinstance(value, float | np.floating):
        return DASH if math.isnan(value) else f"{float(value):g}"
    if key == "method" and "+" in str(value):  # classifier+aggregator +post -> words
        parts = [p.strip() for p in str(value).split("+") if p.strip()]
        return " + ".join(VALUE_LABELS["aggregator"].get(p, p) for p in parts)
    return VALUE_LABELS.get(key, {}).get(str(value), str(value))


def combo_label(keys: Sequence[str], values: Sequence) -> str:
    """Words for a column combination: aggregator x post-processing -> ``graph KNN + post``,
    ``graph KNN`` (raw); other keys joined with ``, ``."""
    vals = dict(zip(keys, values))
    parts = []
    for k in keys:
        if k == "postprocess" and len(keys) > 1:
            continue
        parts.append(value_label(k, vals[k]))
    text = ", ".join(parts)
    if "postprocess" in vals and len(keys) > 1:
        post = str(vals["postprocess"])
        if post not in ("none", ""):
            text += " + post" if post == "default" else f" + {post}"
    return text


def _key(v):
    """A grouping value usable as a dict key: NaN (a missing value) -> None."""
    return None if isinstance(v, float | np.floating) and math.isnan(v) else v


def _sort_key(key: str):
    order = VALUE_ORDER.get(key, ())

    def k(v):
        if v is None:
            return (2, 0.0, "")
        if isinstance(v, float | np.floating | int) and not isinstance(v, bool):
            return (0, float(v), "") if not math.isnan(float(v)) else (2, 0.0, "")
        s = str(v)
        return (1, order.index(s) if s in order else len(order), s)
    return k


@dataclass
class Column:
    """One numeric column: its header (group, sub), the summary's metric and column values."""

    group: str
    sub: str
    metric: str
    combo: tuple = ()


@dataclass
class Grid:
    """A table ready to print.

    ``row_keys`` name the label columns; ``rows`` hold one tuple of label words per row;
    ``columns`` the numeric columns; ``cells[i][j]`` is (mean, std, n, n_failed, lo, hi) of row
    i, column j, lo and hi the bounds of its 95 % interval (scaled: percent when the table is),
    or None where no row exists; ``notes``
    are lines printed under the table.
    """

    title: str
    row_keys: list[str]
    rows: list[tuple[str, ...]]
    columns: list[Column]
    cells: list[list[tuple | None]]
    unit: str = "percent"
    notes: list[str] = field(default_factory=list)
    houses: list[list[str]] = field(default_factory=list)
    by_metric: bool = False
    house_labels: list[str] = field(default_factory=list)
    pooled: bool = False

    @property
    def over(self) -> str:
        """What the mean and std run over: houses, or (pooled tables) maps."""
        return "maps (house x configuration)" if self.pooled else "houses"

    @property
    def legend(self) -> str:
        """What a cell shows, for the line under the table: ``Mean [95 % CI] over houses (...)``."""
        from benchmark.stats import METHOD_WORDS

        return f"Mean [95 % interval] over {self.over} ({METHOD_WORDS})"

    @property
    def grouped(self) -> bool:
        return any(c.group for c in self.columns)


def build_grid(summary: pd.DataFrame, rows: Sequence[str], cols: Sequence[str], metrics: Sequence[str],
               title: str, percent: bool = True, by_metric: bool = False, pooled: bool = False) -> Grid:
    """Display grid of a summary (one row per cell with ``<m>_mean``, ``<m>_std``, ``n``,
    ``n_failed``). ``rows``/``cols`` are the spec's grouping columns; ``by_metric`` puts
    metrics on the top header level and column combinations under them; ``pooled`` says a
    cell pools several configurations (its count is of maps, one per house and configuration).

    Returns:
        Grid whose cells are scaled by 100 when ``percent``. A "houses" note replaces
        per-column house counts when every cell has the same count and no failures.
    """
    scale = 100.0 if percent else 1.0
    rows = [r for r in rows if r in summary]
    col_scale = {m: (1.0 if m in COUNT_METRICS else scale) for m in metrics}
    cols = [c for c in cols if c in summary]
    metrics = [m for m in metrics if f"{m}_mean" in summary]

    def uniq(keys):
        if not keys:
            return [()]
        vals = {tuple(_key(v) for v in t) for t in summary[list(keys)].itertuples(index=False, name=None)}
        return sorted(vals, key=lambda t: tuple(_sort_key(k)(v) for k, v in zip(keys, t)))

    row_vals, combos = uniq(rows), uniq(cols)
    columns: list[Column] = []
    if by_metric and cols:
        for m in metrics:
            columns += [Column(metric_words(m), combo_label(cols, c), m, c)
                        for c in combos]
    else:
        for c in combos:
            g = combo_label(cols, c) if cols else ""
            columns += [Column(g, METRIC_LABELS.get(m, m.replace("_", " ")), m, c) for m in metrics]
    index = {}
    for rec in summary.to_dict("records"):
        index[(tuple(_key(rec[r]) for r in rows), tuple(_key(rec[c]) for c in cols))] = rec
    cells, houses = [], []
    for rv in row_vals:
        line = []
        for col in columns:
            rec = index.get((rv, col.combo))
            if rec is None:
                line.append(None)
                continue
            mean, std = rec.get(f"{col.metric}_mean", np.nan), rec.get(f"{col.metric}_std", np.nan)
            lo, hi = rec.get(f"{col.metric}_lo", np.nan), rec.get(f"{col.metric}_hi", np.nan)
            s = col_scale.get(col.metric, scale)
            line.append((float(mean) * s, float(std) * s, int(rec.get("n", 0)), int(rec.get("n_failed", 0)),
                         float(lo) * s, float(hi) * s))
        cells.append(line)
        houses.append([f"{int(index[(rv, c)]['n'])}" + (f" ({int(index[(rv, c)]['n_failed'])} failed)"
                                                       if index[(rv, c)].get("n_failed") else "")
                       if (rv, c) in index else DASH for c in combos])
    grid = Grid(title, [KEY_LABELS.get(r, r.replace("_", " ")) for r in rows],
                [tuple(value_label(k, v) for k, v in zip(rows, rv)) for rv in row_vals], columns, cells,
                "percent" if percent else "fraction", houses=houses, by_metric=bool(by_metric and cols), pooled=pooled,
                house_labels=[(combo_label(cols, c) + " houses").strip() if cols else "houses" for c in combos])
    counts = {(int(r["n"]), int(r.get("n_failed", 0))) for r in index.values()}
    if len(counts) == 1:
        n, nf = counts.pop()
        what = "maps (house x configuration)" if pooled else "houses"
        grid.notes.append(f"{n} {what} per cell" + (f", {nf} failed" if nf else "") + ".")
        grid.houses, grid.house_labels = [], []
    else:
        grid.notes.append("Houses per cell (failed in brackets) in the houses column(s).")
    return grid


def _interval(cell: tuple) -> tuple[float, float] | None:
    """A cell's 95 % interval (lo, hi), or None when it has none (one house, an old summary)."""
    if len(cell) < 6 or not (math.isfinite(cell[4]) and math.isfinite(cell[5])):
        return None
    return cell[4], cell[5]


def fmt_cell(cell: tuple | None, decimals: int, std: bool = True) -> str:
    """``mean [lo, hi]`` (its 95 % interval over houses) with ``decimals`` decimals, or
    ``mean ± std`` for a cell without interval bounds (a summary without ``_lo``/``_hi``
    columns); ``mean`` alone when the
    spread is missing (one house) or ``std`` is False; a dash when the mean is missing (never 0
    for a missing number)."""
    if cell is None or math.isnan(cell[0]):
        return DASH
    ci = _interval(cell)
    if std and ci is not None:
        return f"{cell[0]:.{decimals}f} [{ci[0]:.{decimals}f}, {ci[1]:.{decimals}f}]"
    if not std or math.isnan(cell[1]):
        return f"{cell[0]:.{decimals}f}"
    return f"{cell[0]:.{decimals}f} ± {cell[1]:.{decimals}f}"


def error_bars(frame: pd.DataFrame, metric: str, scale: float = 100.0) -> np.ndarray:
    """Matplotlib ``yerr`` for a summary's ``<metric>_mean``: (2, n) distances down to
    ``<metric>_lo`` and up to ``<metric>_hi`` (its 95 % interval), times ``scale``; the std
    either side for a summary without bounds; 0 where a bound is missing (one house)."""
    mean = frame[f"{metric}_mean"].to_numpy(float)
    if f"{metric}_lo" in frame and f"{metric}_hi" in frame:
        down = mean - frame[f"{metric}_lo"].to_numpy(float)
        up = frame[f"{metric}_hi"].to_numpy(float) - mean
    else:
        down = up = frame[f"{metric}_std"].to_numpy(float)
    return scale * np.nan_to_num(np.clip(np.vstack([down, up]), 0.0, None))


def _md_escape(text: str) -> str:
    return str(text).replace("|", "/").replace("\n", " ")


def _md_table(header: list[str], align: list[str], body: list[list[str]]) -> str:
    header = [_md_escape(h) for h in header]
    body = [[_md_escape(c) for c in line] for line in body]
    widths = [max([len(h), 3] + [len(line[i]) for line in body]) for i, h in enumerate(header)]

    def line(cells):
        return "| " + " | ".join((c.rjust(w) if a == "r" else c.ljust(w)) for c, w, a in zip(cells, widths, align)) + " |"

    sep = "|" + "|".join((":" + "-" * (w + 1)) if a == "l" else ("-" * (w + 1) + ":") for w, a in zip(widths, align)) + "|"
    return "\n".join([line(header), sep, *(line(b) for b in body)])


def to_markdown(grid: Grid, decimals: int = 2) -> str:
    """Markdown (pipe table, no ``|`` inside a cell, as many separator cells as header cells).
    A by-metric grid gives one table per metric, each under a bold metric name."""
    groups = list(dict.fromkeys(c.group for c in grid.columns))
    by_metric = grid.by_metric
    blocks = []
    parts = [(g, [j for j, c in enumerate(grid.columns) if c.group == g]) for g in groups] if by_metric \
        else [("", list(range(len(grid.columns))))]
    for g, js in parts:
        header = [*grid.row_keys]
        for j in js:
            c = grid.columns[j]
            header.append(c.sub if by_metric else (f"{c.group} {c.sub}" if c.group else c.sub))
        align = ["l"] * len(grid.row_keys) + ["r"] * len(js)
        body = [[*lab] + [fmt_cell(grid.cells[i][j], decimals) for j in js] for i, lab in enumerate(grid.rows)]
        if grid.houses:
            header += grid.house_labels
            align += ["r"] * len(grid.house_labels)
            body = [b + h for b, h in zip(body, grid.houses)]
        table = _md_table(header, align, body)
        blocks.append((f"**{g}**\n\n" if by_metric else "") + table)
    return "\n\n".join(blocks)


_TEX_SPECIAL = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
                "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}"}


def tex_escape(text: str) -> str:
    """Text safe inside a LaTeX cell."""
    return "".join(_TEX_SPECIAL.get(ch, ch) for ch in str(text)).replace("±", r"$\pm$").replace("–", "--")


# Approximate advance widths (pt) in Computer Modern at 8 pt (\footnotesize), for the
# column-versus-page decision; tests/test_tables_format.py checks it against pdflatex.
_W_DIGIT, _W_LOWER, _W_UPPER, _W_SPACE, _W_PM = 4.0, 3.9, 5.9, 2.7, 9.5
TABCOLSEP_PT = 3.0
#: \columnwidth of a two-column ``article`` at 10 pt (pt); the narrower of article and IEEEtran.
COLUMN_WIDTH_PT = 229.0
#: \textwidth of the same page (pt).
PAGE_WIDTH_PT = 469.0


def _text_width(s: str) -> float:
    w = 0.0
    for ch in s:
        if ch.isdigit():
            w += _W_DIGIT
        elif ch == "±":
            w += _W_PM
        elif ch in " .,":
            w += _W_SPACE
        elif ch.isupper():
            w += _W_UPPER
        else:
            w += _W_LOWER
    return w


def _header_lines(text: str) -> list[str]:
    """A column header broken before ``+`` (``graph KNN + post`` -> two lines)."""
    head, sep, rest = str(text).partition(" + ")
    return [head, "+ " + rest] if sep else [str(text)]


def _tex_header(text: str, align: str = "r") -> str:
    lines = _header_lines(text)
    if len(lines) == 1:
        return tex_escape(text)
    return f"\\begin{{tabular}}[b]{{@{{}}{align}@{{}}}}" + " \\\\ ".join(tex_escape(x) for x in lines) + "\\end{tabular}"


def _latex_layout(grid: Grid):
    """(numeric column headers, top header groups [(label, span)], blocks [(label, {row i: [cells]})]).

    A by-metric grid stacks one block of rows per metric under the same columns (the
    column combinations); other grids have one block and, when grouped, a top header."""
    houses = [list(h) for h in grid.houses]
    if grid.by_metric:
        groups = list(dict.fromkeys(c.group for c in grid.columns))
        subs = [c.sub for c in grid.columns if c.group == groups[0]]
        blocks = []
        for g in groups:
            js = [j for j, c in enumerate(grid.columns) if c.group == g]
            blocks.append((g, [[grid.cells[i][j] for j in js] + (houses[i] if houses else [])
                               for i in range(len(grid.rows))]))
        return subs + grid.house_labels, [], blocks
    top = []
    for c in grid.columns:
        if top and top[-1][0] == c.group:
            top[-1][1] += 1
        else:
            top.append([c.group, 1])
    if grid.house_labels:
        top.append(["", len(grid.house_labels)])
    body = [list(grid.cells[i]) + (houses[i] if houses else []) for i in range(len(grid.rows))]
    return [c.sub for c in grid.columns] + grid.house_labels, (top if grid.grouped else []), [("", body)]


def _tex_cell(c, decimals: int, std: bool = True, stacked: bool = False) -> str:
    if isinstance(c, str):
        return tex_escape(c)
    if c is None or math.isnan(c[0]):
        return "--"
    ci = _interval(c)
    if std and ci is not None:
        if stacked:  # the interval under the mean, in the same column
            return f"\\shortstack[r]{{${c[0]:.{decimals}f}$\\\\{{}}[${ci[0]:.{decimals}f}$, ${ci[1]:.{decimals}f}$]}}"
        return f"${c[0]:.{decimals}f}$ [${ci[0]:.{decimals}f}$, ${ci[1]:.{decimals}f}$]"
    if not std or math.isnan(c[1]):
        return f"${c[0]:.{decimals}f}$"
    return f"${c[0]:.{decimals}f} \\pm {c[1]:.{decimals}f}$"


#: LaTeX styles tried in order until the table fits: (font size command, its size relative
#: to \\footnotesize, \\tabcolsep in pt, whether cells show the interval (or std), whether the
#: interval stands under the mean rather than beside it).
LATEX_STYLES = (("\\footnotesize", 1.0, TABCOLSEP_PT, True, False), ("\\scriptsize", 0.875, 2.0, True, False),
                ("\\scriptsize", 0.875, 2.0, True, True),
                ("\\scriptsize", 0.875, 2.0, False, False))


def estimate_width(grid: Grid, decimals: int = 1, scale: float = 1.0, tabcolsep: float = TABCOLSEP_PT,
                   std: bool = True, stacked: bool = False) -> float:
    """Estimated width (pt) of :func:`to_latex`'s tabular: text at \\footnotesize times
    ``scale``, ``tabcolsep`` pt either side of each column, cells with or without the
    interval, beside the mean or (``stacked``) under it (pdflatex's measure is within about
    10 %: tests/test_tables_format.py)."""

    def cell_width(c) -> float:
        if isinstance(c, str):
            return _text_width(c)
        text = fmt_cell(c, decimals, std)
        if stacked and " [" in text:
            return max(_text_width(x) for x in text.replace(" [", "\n[").split("\n"))
        return _text_width(text)

    heads, _, blocks = _latex_layout(grid)
    widths = []
    for i, key in enumerate(grid.row_keys):
        widths.append(max([_text_width(key)] + [_text_width(r[i]) for r in grid.rows]))
    for j, h in enumerate(heads):
        cells = [row[j] for _, b in blocks for row in b]
        widths.append(max([_text_width(x) for x in _header_lines(h)] +
                          [cell_width(c) for c in cells]))
    return scale * sum(widths) + 2 * tabcolsep * len(widths)


def to_latex(grid: Grid, label: str, caption: str, decimals: int = 1) -> str:
    """A booktabs table: first line says what it needs and which width it fits; caption and
    label; label columns left, numbers right with ``decimals`` decimals (mean [95 % interval]);
    headers with ``+`` broken over two lines; a by-metric grid as one block of rows per metric.

    The first of :data:`LATEX_STYLES` with the std that fits one column (\\columnwidth of a
    two-column article) makes a ``table``; otherwise the first with the std that fits the
    page makes a ``table*``; cells without the std only when nothing else fits (the caption
    says so); a table wider than the page in every style says so in its first line.

    Returns:
        LaTeX source of the float.
    """
    styles = [(st, estimate_width(grid, decimals, st[1], st[2], st[3], st[4])) for st in LATEX_STYLES]
    order = [(st, w, env) for keep_std in (True, False) for env, limit in (("table", COLUMN_WIDTH_PT),
                                                                            ("table*", PAGE_WIDTH_PT))
             for st, w in styles if st[3] == keep_std and w <= limit]
    pick = order[0] if order else (*styles[-1], "table*")
    (size, _, sep, std, stacked), width, env = pick
    if env == "table":
        where = "fits one column of a two-column article (\\columnwidth)"
    elif width <= PAGE_WIDTH_PT:
        where = "full page width (table*, \\textwidth of a two-column article)"
    else:
        where = (f"wider than a page (\\textwidth {PAGE_WIDTH_PT:.0f} pt): drop columns, or use a "
                 "sidewaystable (package rotating)")
    if not std:
        caption = caption.rstrip() + " Means only; the intervals (lo, hi) and standard deviations are in the .csv file."
    heads, top, blocks = _latex_layout(grid)
    nrk, ncols = len(grid.row_keys), len(heads)
    lines = [f"% Needs \\usepackage{{booktabs}} in the preamble. Width: {where}, estimated {width:.0f} pt.",
             f"\\begin{{{env}}}[t]", "\\centering", size,
             f"\\setlength{{\\tabcolsep}}{{{sep:g}pt}}",
             f"\\caption{{{tex_escape(caption)}}}", f"\\label{{{label}}}",
             f"\\begin{{tabular}}{{{'l' * nrk + 'r' * ncols}}}", "\\toprule"]
    if top:
        cells, rules, pos = [""] * nrk, [], nrk + 1
        for g, n in top:
            cells.append(f"\\multicolumn{{{n}}}{{c}}{{{tex_escape(g)}}}" if n > 1 else tex_escape(g))
            if g:
                rules.append(f"\\cmidrule(lr){{{pos}-{pos + n - 1}}}")
            pos += n
        lines += [" & ".join(cells) + " \\\\", "".join(rules)]
    lines.append(" & ".join([tex_escape(k) for k in grid.row_keys] + [_tex_header(h) for h in heads]) + " \\\\")
    for name, body in blocks:
        lines.append("\\midrule")
        if name:
            lines.append(f"\\multicolumn{{{nrk + ncols}}}{{l}}{{\\emph{{{tex_escape(name)}}}}} \\\\")
        for lab, row in zip(grid.rows, body):
            lines.append(" & ".join([tex_escape(x) for x in lab] + [_tex_cell(c, decimals, std, stacked) for c in row])
                         + " \\\\")
    lines += ["\\bottomrule", "\\end{tabular}", f"\\end{{{env}}}", ""]
    return "\n".join(lines)


__all__ = ["Grid", "Column", "build_grid", "to_markdown", "to_latex", "estimate_width", "fmt_cell", "tex_escape",
           "value_label", "combo_label", "METRIC_LABELS", "METRIC_WORDS", "BY_METRIC", "COLUMN_WIDTH_PT",
           "PAGE_WIDTH_PT"]
