"""Per-house metrics tables -> the paper's tables (Markdown, CSV, LaTeX) and the sensitivity plot.

``python -m benchmark.commands.tables RUN_DIR [RUN_DIR ...] [--table table4] [--out DIR]``

Reads every ``metrics.csv`` under the given folders (runs of :mod:`benchmark.harness.runner`, or
per-map tables of the baselines), each through :func:`read_rows`, the one loader every reader of
rows uses (checked by :func:`benchmark.harness.store.read_metrics`, and each (configuration, house)
once in a file), keeps successful rows, and reports mean and standard deviation over houses per table cell, with
the number of houses and of failed houses.

What a cell holds (:func:`load_rows`, :func:`summarise`):

* each (configuration, house) once. A row's configuration is its job's settings (``job.json``:
  the resolved config without the settings that change no row) less the house selection
  (``houses``, ``run.limit``, ``run.houses``, ``env.start``/``stop``/``n_houses``/... :
  :data:`benchmark.harness.store.SELECTION_KEYS`), and the row's own names (dataset,
  classifier, aggregator, ...). Where several jobs hold the same pair, the newest job's row
  wins (``finished_at`` of its ``summary.json``, else the file's time) and the rows set aside
  are counted in ``load_rows(...).attrs["set_aside"]``, one line naming their folders;
* never two settings: where rows of different configurations fall into one cell (equal in
  every column the table groups by, e.g. two ``aggregator.k``), the table gets one row per
  configuration, labelled in a ``settings`` column by what differs, and a line under the table
  says so. Tables that pool on purpose (Table III: over classifiers and aggregators) name
  what they pool in :attr:`TableSpec.pools`;
* when the cells compared hold different sets of houses (within a dataset), a line under the
  table says so.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from benchmark import stats
from benchmark.harness.cache import atomic_write_text
from benchmark.harness.store import METRICS, SELECTION_KEYS, Job, iter_metric_files, read_metrics
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
    #: their own: classifier "sanity", aggregator = the segmenter (docs/metrics.md).
    sanity: bool = False
    #: config groups a cell averages over on purpose (their settings and names may differ
    #: inside a cell); every other difference splits the cell (see the module doc).
    pools: tuple[str, ...] = ()
    #: metrics the table ranks its rows by, per dataset, in groups that a paired interval
    #: cannot separate (a line each under the table: :func:`rank_lines`).
    rank: tuple[str, ...] = ()
    #: with ``rank``: the columns whose values are ranked against each other, once per
    #: combination of the other row and column keys (Table II: the viewpoint strategies of
    #: each classifier x aggregator); empty: every row of a dataset is ranked together.
    rank_within: tuple[str, ...] = ()


#: the sanity segmenters (benchmark/segmenters/sanity.py), shown in comparison tables.
SANITY_SEGMENTERS = ("one_room", "gt_geometry", "grid")


#: the metrics beside the paper's that merging cannot game (docs/metrics.md), in every
#: comparison table (fractions, shown in percent; count_error, segments minus rooms, is a
#: count and shown as it is).
ROBUST_METRICS = ("matched_iou", "pq", "room_iou", "ipa_recall", "ipa_precision", "count_error")

TABLES: dict[str, TableSpec] = {
    "table2": TableSpec("Table II: viewpoint strategies (no post-processing)",
                        rows=("dataset", "classifier", "aggregator"), cols=("viewpoints",),
                        where={"postprocess": "none"}, exclude={"segmenter_row": True},
                        rank=("iou",), rank_within=("viewpoints",)),
    "table3": TableSpec("Table III: post-processing, mean over all classifier x aggregator combinations",
                        rows=("dataset",), cols=("postprocess",), exclude={"segmenter_row": True},
                        pools=("classifier", "aggregator"), rank=("iou",)),
    "table4": TableSpec("Table IV: classifier x aggregator per dataset (with post-processing)",
                        rows=("classifier", "aggregator"), cols=("dataset",),
                        metrics=("iou", "matched_iou", "pq", "accuracy"),
                        exclude={"postprocess": "none", "segmenter_row": True}, sanity=True,
                        rank=("matched_iou", "pq")),
    "table5": TableSpec("Table V: comparison with baselines", rows=("dataset", "method"),
                        metrics=("iou", "precision", "recall", *ROBUST_METRICS, "accuracy"),
                        rank=("matched_iou", "pq")),
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


def method_label(row: pd.Series | dict[str, Any]) -> str:
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


#: the columns :func:`method_label` reads.
LABEL_COLUMNS = ("method", "segmenter", "classifier", "aggregator", "oracle_accuracy", "postprocess")


def _per_distinct_row(df: pd.DataFrame, cols: Sequence[str], make: Callable[[tuple], Any]) -> list:
    """``make(values)`` of every row's values in ``cols``, called once per distinct combination
    (told apart by their ``repr``: 1 and 1.0, 0.0 and -0.0 are not merged); the rows of one
    combination share the result object."""
    made: dict[tuple[str, ...], Any] = {}
    out = []
    for rec in df[list(cols)].itertuples(index=False, name=None):
        key = tuple(map(repr, rec))
        if key not in made:
            made[key] = make(rec)
        out.append(made[key])
    return out


def _method_labels(df: pd.DataFrame) -> list[str]:
    """:func:`method_label` of every row of ``df``, worked out once per distinct combination of
    the columns it reads."""
    cols = [c for c in LABEL_COLUMNS if c in df]
    return _per_distinct_row(df, cols, lambda rec: method_label(dict(zip(cols, rec))))


#: columns of a row that name its configuration (beside its job's settings).
ROW_NAMES = ("dataset", "env", "viewpoints", "renderer", "classifier", "oracle_accuracy", "aggregator",
             "postprocess", "segmenter", "label", "corruption", "severity", "method")
#: columns that tell configurations apart when nothing else does (rows read without their
#: job's settings): the metric parameters in words and the scoring stage's cache key.
ROW_KEYS_LAST = ("metric_params", "score_key")
#: config groups a method's rows use and a segmenter's rows do not.
METHOD_GROUPS = ("viewpoints", "renderer", "classifier", "aggregator", "postprocess")
#: settings that select houses rather than change a house's row.
HOUSE_SELECTION = ("houses", "run.limit", "run.houses")


def job_configuration(settings: dict[str, Any] | None) -> dict[str, Any]:
    """The part of a job's configuration that its settings give: ``settings`` (flat, from
    :meth:`benchmark.harness.store.Job.settings`) less the house selection
    (:data:`HOUSE_SELECTION` and ``env.<k>`` for ``k`` in :data:`~benchmark.harness.store.SELECTION_KEYS`),
    and for a segmenter's job less the method's groups, which its rows do not use."""
    if not settings:
        return {}
    drop = {*HOUSE_SELECTION, *(f"env.{k}" for k in SELECTION_KEYS)}
    out = {k: v for k, v in settings.items() if k not in drop}
    if any(k.startswith("segmenter.") for k in out):
        out = {k: v for k, v in out.items() if k.split(".", 1)[0] not in METHOD_GROUPS}
    return out


def _plain(v: Any) -> Any:
    """A CSV cell as a JSON value: NaN -> None, NumPy scalars -> Python."""
    if isinstance(v, np.generic):
        v = v.item()
    return None if isinstance(v, float) and np.isnan(v) else v


def _configurations(df: pd.DataFrame, settings: dict[str, Any]) -> list[str]:
    """Per row, its configuration as canonical JSON: ``{"settings": ..., "row": ...}``. The
    row's ``score_key`` counts only without settings (it also follows ``run.cache_salt``,
    which changes no row)."""
    cols = [c for c in (*ROW_NAMES, *ROW_KEYS_LAST) if c in df and not (settings and c == "score_key")]
    # json.dumps({"settings": ..., "row": ...}, sort_keys=True) in two parts: the settings (the
    # same for every row of a file) written once, the row's names once per distinct combination
    tail = ', "settings": ' + json.dumps(settings, sort_keys=True, default=str) + "}"
    return _per_distinct_row(df, cols, lambda rec: '{"row": ' + json.dumps(
        {c: _plain(v) for c, v in zip(cols, rec)}, sort_keys=True, default=str) + tail)


def _folders(paths: Sequence[str], limit: int = 4) -> str:
    counts = pd.Series(list(paths)).value_counts(sort=False)
    parts = [f"{p} ({n})" for p, n in counts.items()]
    return ", ".join(parts[:limit]) + (f" and {len(parts) - limit} more" if len(parts) > limit else "")


def _once_per_file(df: pd.DataFrame) -> None:
    """Check that one file's rows (:func:`read_rows`) hold each (configuration, house) once.

    Raises:
        ValueError: the file holds the same house twice for one configuration (one line naming
            the file, the house and both lines)."""
    if "house_id" not in df:
        return
    key = ["_config", "house_id"]
    twice = df["house_id"].notna() & df.duplicated(key, keep=False)
    if twice.any():
        rows = df[twice]
        first = rows.iloc[0]
        lines = rows[(rows["house_id"] == first["house_id"]) & (rows["_config"] == first["_config"])]["_line"].tolist()
        raise ValueError(f"{first['source']}: house {first['house_id']} is on lines {lines[0]} and {lines[1]} with "
                         f"the same configuration; expected one row per house and configuration")


def _newest_only(df: pd.DataFrame) -> tuple[pd.DataFrame, str]:
    """``df`` (rows of :func:`read_rows`, each file checked) with each (configuration, house)
    once, the newest job's row; and one line saying how many older rows were set aside and from
    which folders ("" when none)."""
    if "house_id" not in df:
        return df, ""
    has = df["house_id"].notna()
    key = ["_config", "house_id"]
    older = df.sort_values(["_finished", "source"], kind="stable").duplicated(key, keep="last")
    older = older.reindex(df.index) & has
    if not older.any():
        return df, ""
    kept = df[~older & has].drop_duplicates(key).set_index(key)["source"]
    aside = df[older]
    newer = kept.reindex(pd.MultiIndex.from_frame(aside[key])).tolist()
    line = (f"set aside {int(older.sum())} older row(s) whose configuration and house a newer job also holds, "
            f"from {_folders([str(Path(s).parent) for s in aside['source']])}; kept the newer rows of "
            f"{_folders([str(Path(s).parent) for s in newer])}")
    return df[~older], line


#: the columns :func:`read_rows` adds to a file's own.
ROW_SOURCE_COLUMNS = ("source", "_config", "_finished", "_line")


def read_rows(path: str | Path) -> pd.DataFrame:
    """One metrics file's rows, with the checks every reader of rows applies (``tables``,
    ``report``, ``figures``, ``robustness``, the published runs): the file's own
    (:func:`benchmark.harness.store.read_metrics`: whole, parsed, shares in [0, 1], as many rows
    as its job's summary says) and each (configuration, house) once in it.

    Returns:
        The file's rows as written, and :data:`ROW_SOURCE_COLUMNS`: ``source`` (the file),
        ``_config`` (each row's configuration as JSON: its job's settings and its own names),
        ``_finished`` (the job's finish time, POSIX s) and ``_line`` (the row's line in the file).

    Raises:
        ValueError: a malformed file or value, or the file holding a house twice for one
            configuration (one line naming the file)."""
    f = Path(path)
    df = read_metrics(f)
    job = Job(f.parent)
    is_job = f.name == METRICS
    df["source"] = str(f)
    df["_config"] = _configurations(df, job_configuration(job.settings() if is_job else None))
    df["_finished"] = job.finished_at() if is_job else f.stat().st_mtime
    df["_line"] = np.arange(len(df)) + 2
    _once_per_file(df)
    return df


#: metrics files a process reads at least before :func:`load_rows` spreads them over forked
#: processes (below it, starting one costs more than it saves)
FILES_PER_PROCESS = 100


def _read_chunk(files: Sequence[Path]) -> pd.DataFrame:
    return pd.concat([read_rows(f) for f in files], ignore_index=True)


def _read_files(files: Sequence[Path]) -> list[pd.DataFrame]:
    """Each file's :func:`read_rows`, in order: on the cores this process may use (forked
    processes, each reading a run of consecutive files) when there are at least
    :data:`FILES_PER_PROCESS` files per process, else one after the other here. Concatenated,
    the same frame either way (columns in their order of first appearance, each file's rows in
    the files' order); a bad file raises the same one-line error, the first in file order."""
    from benchmark.harness.processes import forked_workers, run_forked

    n = min(forked_workers(), len(files) // FILES_PER_PROCESS)
    if n <= 1:
        return [read_rows(f) for f in files]
    bounds = np.linspace(0, len(files), n + 1).round().astype(int)
    return run_forked([functools.partial(_read_chunk, list(files[a:b])) for a, b in zip(bounds[:-1], bounds[1:])], n)


def load_rows(paths: Sequence[str | Path], newest: bool = True) -> pd.DataFrame:
    """All rows of the metrics files at or under ``paths``, each file read by :func:`read_rows`
    (its checks), and (``newest``) each (configuration, house) once: the newest job's row (see
    the module doc). ``newest=False`` keeps every job's rows (the report lists each job).

    Returns:
        The rows, with ``method`` and ``segmenter_row`` columns and :data:`ROW_SOURCE_COLUMNS`;
        ``attrs["n_read"]`` is the number of rows read and ``attrs["set_aside"]`` one line about
        the older rows set aside ("" if none).

    Raises:
        FileNotFoundError: no metrics file.
        ValueError: a malformed file or value, or one file holding a house twice for one
            configuration (one line naming the file).
    """
    df = pd.concat(_read_files(find_metric_files(paths)), ignore_index=True)
    n_read = len(df)
    df, line = _newest_only(df) if newest else (df, "")
    df = df.reset_index(drop=True)
    for col in ("classifier", "aggregator", "postprocess", "viewpoints", "segmenter", "dataset"):
        if col not in df:
            df[col] = ""
        df[col] = df[col].astype("string").fillna("").astype(str)
    if "status" not in df:
        df["status"] = "ok"
    df["method"] = _method_labels(df)
    df["segmenter_row"] = df["segmenter"].str.len() > 0
    df.attrs.update(n_read=n_read, set_aside=line)
    return df


def _pooled(key: str, pools: Sequence[str], row: bool) -> bool:
    """Whether a configuration key is one a table pools over (its differences do not split)."""
    if not pools:
        return False
    if row:  # the method's name and the score key follow the pooled groups too
        return key in pools or key in ("method", "score_key") or (key == "oracle_accuracy" and "classifier" in pools)
    return key.split(".", 1)[0] in pools


def _differing(configs: Sequence[dict], part: str) -> set[str]:
    """The keys of ``part`` ("settings" or "row") whose values are not the same in every one
    of ``configs`` (a key some configurations lack counts as different)."""
    def value(c: dict, k: str) -> str | None:
        return json.dumps(c[part][k], sort_keys=True, default=str) if k in c[part] else None

    names = set().union(*(c[part] for c in configs))
    return {k for k in names if len({value(c, k) for c in configs}) > 1}


def _value_words(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_value_words(x) for x in v) + "]"
    return str(v)


def settings_labels(configs: Sequence[str], cells: Sequence[Sequence[str]],
                    pools: Sequence[str] = ()) -> tuple[dict[str, str], list[str]]:
    """Labels that tell apart the configurations sharing a cell.

    Args:
        configs: every configuration of the table's rows (JSON, as ``_config``).
        cells: per cell, the configurations in it.
        pools: config groups the table pools over (ignored in comparisons).

    Returns:
        ({configuration: label}, the keys the labels show). A label is ``key=value`` for each
        key shown that the configuration has, joined by ``, ``. The keys are chosen by tiers,
        each only where the earlier ones leave configurations of a cell equal: the row's names
        (``viewpoints=autotrace_sparse``), then the job's settings (``aggregator.k=3``), then
        the metric parameters and score key. ({}, []) when no cell mixes configurations.
    """
    parsed = {c: json.loads(c) for c in configs}
    for p in parsed.values():
        p["row"] = {k: v for k, v in p["row"].items() if not _pooled(k, pools, True)}
        p["settings"] = {k: v for k, v in p["settings"].items() if not _pooled(k, pools, False)}
    tiers = [("row", lambda k: k not in ROW_KEYS_LAST), ("settings", lambda k: True),
             ("row", lambda k: k in ROW_KEYS_LAST)]
    shown: list[tuple[str, str]] = []

    def label(c: str) -> tuple:
        return tuple(json.dumps(parsed[c][part].get(k), default=str) if k in parsed[c][part] else None
                     for part, k in shown)

    for part, wanted in tiers:
        for cell in cells:
            groups: dict[tuple, list[dict]] = {}
            for c in dict.fromkeys(cell):
                groups.setdefault(label(c), []).append(parsed[c])
            for same in groups.values():
                if len(same) > 1:
                    new = sorted(k for k in _differing(same, part) if wanted(k) and (part, k) not in shown)
                    shown += [(part, k) for k in new]
    if not shown:
        return {}, []
    out = {}
    for c in parsed:
        out[c] = ", ".join(f"{k}={_value_words(parsed[c][part][k])}" for part, k in shown if k in parsed[c][part])
    return out, [k for _, k in shown]


def house_set_note(ok: pd.DataFrame, keys: Sequence[str]) -> str | None:
    """One line when the cells of a table (grouped by ``keys``; compared within one dataset
    when ``dataset`` is a key) hold different sets of successful houses, else None."""
    if "house_id" not in ok or ok.empty or not keys:
        return None
    sets = ok.groupby(list(keys), dropna=False)["house_id"].agg(lambda h: frozenset(map(str, h)))
    parts = sets.groupby(level="dataset") if "dataset" in keys else [("", sets)]
    for ds, part in parts:
        if len(set(part)) < 2:
            continue
        union, common = frozenset().union(*part), frozenset.intersection(*part)
        lacking = [cell for cell, h in part.items() if h != union]
        example = sorted(union - common)[0]
        where = f" of dataset {ds}" if ds else ""
        return (f"Note: the cells{where} hold different house sets: {len(union)} houses in all, {len(common)} in every "
                f"cell; {len(lacking)} of {len(part)} cells lack some (e.g. {example}), so their means are not over "
                f"the same houses.")
    return None


def summarise(df: pd.DataFrame, spec: TableSpec) -> pd.DataFrame:
    """Mean, std and count over houses per (rows, cols) cell; ``n_failed`` per cell too.

    A cell holding rows of different configurations (other than in :attr:`TableSpec.pools`)
    is split: a ``settings`` column labels each configuration by what differs
    (:func:`settings_labels`). ``attrs["notes"]`` holds the lines to print under the table
    (the split, different house sets)."""
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
    notes = []
    if "_config" in sel:
        cells = sel.groupby(keys, dropna=False)["_config"].unique().tolist()
        labels, shown = settings_labels(sel["_config"].unique().tolist(), cells, spec.pools)
        if labels:
            sel = sel.assign(settings=sel["_config"].map(labels))
            keys = [*keys, "settings"]
            notes.append(f"Note: rows of different settings that would share a cell are kept apart, labelled by "
                         f"{', '.join(shown)}.")
    ok = sel[sel["status"] == "ok"]
    if "house_id" in ok:  # a cell's houses in a fixed order: its seeded interval does not follow file order
        ok = ok.sort_values("house_id", kind="stable")
    metrics = [m for m in spec.metrics if m in ok]
    g = ok.groupby(keys, dropna=False)[metrics]
    # a pooled cell (several configurations per house) is resampled by house: its mean over maps
    # is the mean of its per-house means when every house has the same configurations
    per = ok.groupby([*keys, "house_id"], dropna=False)[metrics].mean() if spec.pools and "house_id" in ok else None
    ci_of = per.groupby(level=list(range(len(keys))), dropna=False) if per is not None else g
    ci = ci_of.agg(lambda s: stats.bootstrap_ci(pd.to_numeric(s, errors="coerce").dropna().to_numpy()))
    out = pd.concat({"mean": g.mean(), "std": g.std(ddof=1),
                     "lo": ci.map(lambda t: t[0]), "hi": ci.map(lambda t: t[1])}, axis=1)
    out.columns = [f"{m}_{s}" for s, m in out.columns]
    out = out[[f"{m}_{s}" for m in metrics for s in ("mean", "std", "lo", "hi")]]
    out["n"] = ok.groupby(keys, dropna=False).size()
    out["n_failed"] = sel[sel["status"] != "ok"].groupby(keys, dropna=False).size()
    out["n_failed"] = out["n_failed"].fillna(0).astype(int)
    houses = house_set_note(ok, keys)
    if houses:
        notes.append(houses)
    if spec.rank and spec.rank_within:
        outer = [k for k in keys if k != "dataset" and k not in spec.rank_within]
        inner = [k for k in keys if k in spec.rank_within]
        for key, part in (ok.groupby(outer, dropna=False) if outer and inner else []):
            key = key if isinstance(key, tuple) else (key,)
            what = " + ".join(formatting.value_label(k, v) for k, v in zip(outer, key) if str(v))
            notes += [line.replace("Ranking on ", f"Ranking of {what} on ", 1)
                      for line in rank_lines(part, inner, spec.rank)]
    elif spec.rank:
        notes += rank_lines(ok, [k for k in keys if k != "dataset"], spec.rank)
    out = out.reset_index()
    out.attrs["notes"] = notes
    return out


def rank_lines(ok: pd.DataFrame, keys: Sequence[str], metrics: Sequence[str]) -> list[str]:
    """Per dataset and metric, one line ranking the table's rows (grouped by ``keys``) in groups
    that cannot be separated (:func:`benchmark.stats.groups`: paired by house, bootstrap interval
    of the difference against the group's best, the ranking's k (k - 1) / 2 pairs one family
    corrected by Holm: :func:`benchmark.stats.holm_verdicts`), over the houses every row
    holds (a house's mean where a pooled table holds several configurations per house); rows of
    the sanity segmenters are left out (they are checks, not methods)."""
    out = []
    if "house_id" not in ok or not keys or ok.empty:
        return out
    parts = ok.groupby("dataset") if "dataset" in ok else [("", ok)]
    for ds, d in parts:
        d = d[~d.get("segmenter", pd.Series("", index=d.index)).isin(SANITY_SEGMENTERS)]
        if "classifier" in d:
            d = d[d["classifier"] != "sanity"]
        for metric in metrics:
            if metric not in d:
                continue
            v = d.dropna(subset=[metric])
            wide = v.pivot_table(index="house_id", columns=list(keys), values=metric, aggfunc="mean")
            if wide.shape[1] < 2:
                continue
            n_all = len(wide)
            wide = wide.dropna()
            if len(wide) < 2:
                continue
            labels = {}
            for col in wide.columns:
                col = col if isinstance(col, tuple) else (col,)
                labels[col] = " + ".join(formatting.value_label(k, x) for k, x in zip(keys, col) if str(x))
            values = {labels[c if isinstance(c, tuple) else (c,)]: 100.0 * wide[c].to_numpy(dtype=float)
                      for c in wide.columns}
            where = f"{formatting.value_label('dataset', ds)}, " if ds else ""
            lost = f", leaving out {n_all - len(wide)} houses some rows lack" if len(wide) < n_all else ""
            if len(values) == 2:  # one difference: say it with its paired interval
                (a, va), (b, vb) = sorted(values.items(), key=lambda kv: -float(np.mean(kv[1])))
                out.append(f"Ranking on {formatting.metric_words(metric)} ({where}paired over {len(wide)} houses"
                           f"{lost}): {stats.verdict(a, b, *stats.paired_ci(va, vb))}.")
                continue
            pairs = len(values) * (len(values) - 1) // 2
            out.append(f"Ranking on {formatting.metric_words(metric)} ({where}paired over {len(wide)} houses{lost}; "
                       f"braces hold rows no paired interval separates, Holm-corrected over the ranking's {pairs} "
                       f"pairs): {stats.group_words(stats.groups(values, corrected=True))}.")
    return out


def split_rank_notes(notes: Sequence[str]) -> tuple[str, list[str]]:
    """(the notes but the ranking lines, joined by spaces; the ranking lines of :func:`rank_lines`)."""
    ranks = [n for n in notes if n.startswith("Ranking on ")]
    return " ".join(n for n in notes if n not in ranks), ranks


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
    rows = (*spec.rows, "settings") if "settings" in summary else spec.rows
    grid = formatting.build_grid(summary, rows, spec.cols, spec.metrics, spec.title, percent,
                                 by_metric=name in formatting.BY_METRIC, pooled=name in formatting.POOLED)
    grid.notes += summary.attrs.get("notes", [])
    return grid


def metric_notes(df: pd.DataFrame) -> list[str]:
    """The metric parameter lines of the rows (printed beside every table)."""
    if "metric_params" not in df:
        return []
    return sorted({str(v) for v in df["metric_params"].dropna().unique()})


def render(paths: Sequence[str | Path], tables: Sequence[str] | None = None, out_dir: Path | None = None,
           percent: bool = True, rows: pd.DataFrame | None = None, scope_note: str = "") -> str:
    """Markdown text of the requested tables; with ``out_dir`` also write .md/.csv/.tex each.

    ``tables`` None: every table the rows have data for; a table left out (or asked for
    and empty) gets one line saying why. ``rows``: the rows already read by
    :func:`load_rows` (``paths`` is then not read again). ``scope_note``: which runs the rows
    are, when more than one sweep's (:func:`benchmark.harness.store.sweep_scope`), written under
    every table. Returns the text printed by the command.
    """
    df = load_rows(paths) if rows is None else rows
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
        caption = f"{spec.title}. {grid.legend}, {unit}. " + " ".join(grid.notes)
        text, ranks = split_rank_notes(grid.notes)
        md = (f"### {spec.title}\n\n" + formatting.to_markdown(grid) + "\n\n" +
              f"{grid.legend}, {unit}. " + text +
              (" Metrics: " + "; ".join(notes) + "." if notes else "") +
              (f" Note: {reason}." if reason else "") +
              (f" Runs read: {scope_note}." if scope_note else "") + "\n" + "".join(f"\n- {r}" for r in ranks)
              + ("\n" if ranks else ""))
        chunks.append(md)
        if out_dir is not None:
            out_dir.mkdir(parents=True, exist_ok=True)
            atomic_write_text(out_dir / f"{name}.md", md)
            atomic_write_text(out_dir / f"{name}.csv", summ.to_csv(index=False))
            atomic_write_text(out_dir / f"{name}.tex", formatting.to_latex(grid, f"tab:{name}", caption.strip()))
        if name == "sensitivity" and out_dir is not None and reason is None and "settings" in summ:
            chunks.append("Sensitivity plot left out: its curves would join rows of different settings "
                          "(see the settings column).\n")
        elif name == "sensitivity" and out_dir is not None and reason is None:
            from benchmark.reports.sensitivity_plots import plot_sensitivity_per_noise  # noqa: PLC0415

            if not plot_sensitivity_per_noise(summ, out_dir):  # one plot per noise model, and an overview
                plot_sensitivity(summ, out_dir / "sensitivity.png")
    if skipped:
        chunks.append("\n".join(skipped) + "\n")
    from benchmark.reports.sweep_jobs import partial_sweep_lines

    chunks += [f"Note: {line}.\n" for line in partial_sweep_lines(paths)]
    failed = df[df["status"] != "ok"]
    if len(failed):
        reasons = failed["error"].fillna("").str.split(":").str[0].value_counts()
        chunks.append(f"{len(failed)} of {len(df)} rows failed: " +
                      ", ".join(f"{k} x{v}" for k, v in reasons.items()) + "\n")
    return "\n".join(chunks)


def plot_sensitivity(summary: pd.DataFrame, path: Path, formats: Sequence[str] | None = None) -> list[Path]:
    """IoU and pixel accuracy (mean and 95 % interval over houses) against the oracle's accuracy: one
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
            ax.errorbar(g["oracle_accuracy"] * 100, g[f"{m}_mean"] * 100, yerr=formatting.error_bars(g, m), marker="o",
                        ms=4, capsize=3, ls=style, color=colours.get(vals.get("aggregator", ""), None), label=label)
    for ax, m in zip(axes, ("IoU (%)", "pixel accuracy (%)")):
        ax.set_xlabel("oracle classifier accuracy (%)")
        ax.set_ylabel(m)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    n = int(summary["n"].max()) if "n" in summary and len(summary) else 0
    fig.suptitle(f"Segmentation quality against classifier accuracy (mean and 95 % interval over {n} houses)", fontsize=10)
    fig.tight_layout()
    return save(fig, path, formats)
