"""The robustness benchmark's summary: every method's score under each robot condition
(corruption family) at five severities, with 95 % intervals over houses, rankings in groups that
no paired interval separates, and corruption errors against a reference method, the way
ImageNet-C summarises image classifiers (Hendrycks and Dietterich, ICLR 2019).

Rows come from ``experiment=robustness`` (``make robustness``): each carries ``corruption``
(the family: ``clean``, ``scan``, ``pose``, ``slam``, ``explore``, ``classifier``, ``realistic``,
``lost``, ``kidnap``) and ``severity`` (0 clean, 1 up to the family's highest: 5 for the severity
ladders, 3 for ``lost``, 2 for ``kidnap``). For a metric m in percent (matched IoU and PQ rank; the
paper's IoU is shown but builds no mCE, since it rewards maps that shrink):

* error E = 100 - m, per (method, family, severity), averaged over the dataset's houses;
* severity 0 of family f, E_{0,f}(M): the family's own severity-0 rows (``corruption`` = f,
  ``severity`` 0; the ``explore`` family's unlimited frontier run) where the run has them, else the
  clean rows (:func:`zero_key`); the summary's ``clean`` column is always the clean rows;
* corruption error of method M on family f, relative to the reference method R:
  CE_f(M) = 100 x sum_s E_{s,f}(M) / sum_s E_{s,f}(R), over the severities s >= 1;
  relative CE_f(M) = 100 x sum_s (E_{s,f}(M) - E_{0,f}(M)) / sum_s (E_{s,f}(R) - E_{0,f}(R))
  (the method's own severity-0 error cancels);
* mCE and relative mCE (M) = their mean over the families but those reported apart
  (:data:`APART`: ``realistic``, the composite of the others; the labelled conditions ``lost``,
  ``kidnap`` and ``views_final``, whose severities are named situations, not a ladder of one robot;
  and the ablation ``pose``, views-only pose noise on a perfect map, which no robot has):
  100 = as robust as the reference, lower is better;
* R is a method that every family degrades (by default chosen so: :func:`pick_reference`); a
  family that leaves the reference untouched gets no CE (it would measure clean accuracy);
* drop_f(M) = m_{0,f}(M) - mean_s m_{s,f}(M) (negative: the condition helped it).

Every number that ranks has a 95 % bootstrap interval over houses (:mod:`benchmark.stats`,
houses resampled alike in every cell, so differences are paired). A table cell never mixes house
sets, and a family whose severities are not all there for every method is left out with a line
saying so (:func:`complete_families`).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark import stats

#: the corruption families in table order (``clean`` is severity 0 of every family that has no
#: severity-0 rows of its own: :func:`zero_key`).
FAMILIES = ("scan", "pose", "slam", "explore", "classifier", "realistic", "lost", "kidnap", "views_final")
#: the metrics summarised (fractions in the rows, percent in the tables); matched IoU and PQ
#: rank methods and build mCE; the paper's IoU rewards shrinking maps and builds none.
METRICS = ("iou", "matched_iou", "pq")
RANKED = ("matched_iou", "pq")
#: families that combine the others: reported apart, never in mCE or the mean drop.
COMPOSITE = ("realistic",)
#: labelled conditions: each severity is a named situation (how many wrong loop closures, how many
#: kidnappings; ``views_final``: slam_3 with the views at the final optimum instead of at capture
#: time), not a step of one robot's ladder: reported apart, each condition in a column of its own,
#: never in mCE or the mean drop. They may have fewer than five severities.
LABELLED = ("lost", "kidnap", "views_final")
#: ablations: a model no robot has, kept to show what it alone changes, reported apart, never in
#: mCE or the mean drop. ``pose``: views-only pose noise on a perfect map (``pose_error=slam``: the
#: views move by independent noise and drift while the map stays the floor plan at the true poses),
#: where a robot builds its map at its own estimate (``slam``, ``realistic``).
ABLATION = ("pose",)
#: every family reported apart from mCE and the mean drop.
APART = (*COMPOSITE, *LABELLED, *ABLATION)
#: what a family's own severity 0 is, where a run has one (its rows: ``corruption`` = the family,
#: ``severity`` 0); a family without such rows starts from the clean rows.
OWN_ZERO_WORDS = {"explore": "the unlimited frontier run (every method on the explorer's own map), not clean"}
#: the method corruption errors are relative to by default: ``auto``, a method every family
#: degrades (:func:`pick_reference`). The classic geometric baseline (Voronoi segmentation) is
#: untouched by poses, labels and views, so CE against it measured clean accuracy there.
REFERENCE = "auto"
#: the geometric segmenters and the sanity rows among the methods (the sanity rows are shown,
#: not ranked).
GEOMETRIC = ("distance", "morphological", "voronoi")
SANITY = ("one_room", "gt_geometry", "grid")
#: words for the families, in tables and figures.
FAMILY_WORDS = {"scan": "scan map", "pose": "views-only pose noise, perfect map (ablation)",
                "slam": "SLAM (one pose estimate)",
                "explore": "exploration budget", "classifier": "classifier noise",
                "realistic": "realistic (all combined)", "lost": "lost robot (wrong loop closures)",
                "kidnap": "kidnapped robot", "views_final": "views at the final SLAM optimum (slam_3)"}


def zero_key(keys: Collection[tuple[str, str, int]], method: str, family: str) -> tuple[str, str, int]:
    """The cell that is severity 0 of ``family`` for ``method``: the family's own severity-0 cell
    (``(method, family, 0)``) where ``keys`` hold it, else the clean one (``(method, "clean", 0)``)."""
    own = (method, family, 0)
    return own if own in keys else (method, "clean", 0)


def own_zero_families(keys: Collection[tuple[str, str, int]], families: Sequence[str]) -> list[str]:
    """The ``families`` that have severity-0 cells of their own among ``keys``."""
    have = {c for (_, c, s) in keys if s == 0}
    return [f for f in families if f in have]


def own_zero_note(family: str) -> str:
    """The line that says a family's severity 0 is its own condition, not clean."""
    what = OWN_ZERO_WORDS.get(family, "its own condition, not clean")
    return (f"{family}: severity 0 is {what}; its drop, relative CE and curve start there (the clean column "
            f"stays the clean rows).")


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


def house_values(rows: pd.DataFrame, metric: str) -> dict[tuple[str, str, int], np.ndarray]:
    """Per (method, corruption, severity), the metric of every house in percent, houses in
    sorted order (the same houses in every cell: :func:`cell_means` checks it first)."""
    out = {}
    for key, g in rows.sort_values("house_id", kind="stable").groupby(["method", "corruption", "severity"]):
        out[(str(key[0]), str(key[1]), int(key[2]))] = 100.0 * g[metric].to_numpy(dtype=float)
    return out


def complete_families(cells: pd.DataFrame, expected: Mapping[str, Sequence[int]] | None = None,
                      families: Sequence[str] = FAMILIES,
                      unrecorded: Collection[str] = ()) -> tuple[list[str], list[str]]:
    """The families whose every expected severity holds rows for every method, and one line per
    family left out saying which severities lack rows (for every method, or for which).

    Args:
        cells: :func:`cell_means` of one dataset.
        expected: family -> the severities the sweep asked for (default: 1 up to the highest
            severity with rows, so a severity missing in the middle is caught, and 0 where some
            method has the family's own severity-0 rows; a family's top severities missing for
            every method are caught only with ``expected``). A family with fewer than five
            severities (``lost``: 1..3, ``kidnap``: 1..2) is complete when those are all there.
        unrecorded: families whose ``expected`` severities no sweep record gives (the severities
            ``conf/corruption`` defines: :func:`expected_severities`): checked only where they
            have rows, severity 0 as without ``expected``, and their line says so."""
    methods = sorted(cells["method"].unique())
    have = cells.groupby(["corruption", "severity"])["method"].agg(set)
    kept, notes = [], []
    for f in families:
        present = sorted(int(s) for (c, s) in have.index if c == f)
        guessed = f in unrecorded and bool(expected) and f in expected
        if not present and not (expected and f in expected and not guessed):
            continue
        if guessed:  # every severity the configs define (0 where the rows have it)
            want = [0] * (0 in present) + sorted({int(s) for s in expected[f] if int(s) > 0})
        elif expected and f in expected:
            want = sorted({int(s) for s in expected[f]})
        else:  # severity 0 only where the family has its own (some method's rows): then every method needs it
            want = [0] * (0 in present) + list(range(1, max(present) + 1))
        gaps = []
        for s in want:
            got = have.get((f, s), set())
            if not got:
                gaps.append(f"severity {s} has no rows for any method")
            elif len(got) < len(methods):
                lack = [m for m in methods if m not in got]
                gaps.append(f"severity {s} has no rows for {', '.join(lack[:3])}"
                            + (f" and {len(lack) - 3} more" if len(lack) > 3 else ""))
        if gaps:
            why = (f"no sweep record (multirun.yaml) says which severities were run, so every one conf/corruption "
                   f"defines ({_span(want)}) is expected; " if guessed else "")
            notes.append(f"{FAMILY_WORDS.get(f, f)} left out of the summary: {'; '.join(gaps)} "
                         f"({why}a mean over the other severities would not compare)")
        else:
            kept.append(f)
    return kept, notes


def _span(severities: Sequence[int]) -> str:
    """``1-5``, ``0-5``, or ``1, 3`` where the severities are not consecutive."""
    s = sorted(severities)
    if len(s) > 1 and s == list(range(s[0], s[-1] + 1)):
        return f"{s[0]}-{s[-1]}"
    return ", ".join(map(str, s))


def defined_severities(conf_dir: str | Path | None = None) -> dict[str, list[int]]:
    """family -> the severities ``conf/corruption`` defines (its ``<family>_<k>.yaml`` files, a
    family's own severity 0 included)."""
    from benchmark.paths import CONF_DIR

    out: dict[str, set[int]] = {}
    for p in Path(conf_dir or CONF_DIR, "corruption").glob("*_[0-9].yaml"):
        family, k = p.stem.rsplit("_", 1)
        out.setdefault(family, set()).add(int(k))
    return {f: sorted(v) for f, v in sorted(out.items())}


def recorded_severities(paths: Sequence[str | Path]) -> dict[str, list[int]] | None:
    """family -> the severities the sweep(s) at or above ``paths`` asked for (their
    ``multirun.yaml``: in a folder read, under it, or in the folder above a job folder or a job's
    metrics file), or None when no sweep record is found (a published copy, or a run whose
    records are gone).

    Raises:
        ValueError: an unreadable ``multirun.yaml`` (the message names it)."""
    import re

    from benchmark.reports.sweep_jobs import MULTIRUN, expected_jobs

    sweeps: dict[Path, None] = {}
    for p in map(Path, paths):
        d = p.parent if p.is_file() else p
        for cand in (d, d.parent):  # the folder itself, or the sweep folder holding a job
            if (cand / MULTIRUN).exists():
                sweeps.setdefault(cand.resolve(), None)
        if p.is_dir():
            for m in sorted(p.rglob(MULTIRUN)):
                sweeps.setdefault(m.parent.resolve(), None)
    if not sweeps:
        return None
    out: dict[str, set[int]] = {}
    for sweep in sweeps:
        for job in expected_jobs(sweep) or []:
            for o in job:
                m = re.fullmatch(r"corruption=(\w+)_(\d+)", o)
                if m:
                    out.setdefault(m.group(1), set()).add(int(m.group(2)))
    return {f: sorted(v) for f, v in out.items()}


def expected_severities(paths: Sequence[str | Path],
                        conf_dir: str | Path | None = None) -> tuple[dict[str, list[int]], list[str]]:
    """The severities a summary of the rows under ``paths`` expects per family, and the families
    no sweep record names: the severities the sweep(s) asked for (:func:`recorded_severities`),
    and for every other family those ``conf/corruption`` defines (:func:`defined_severities`),
    so that a family whose top severities are gone with the sweep's records is left out with a
    line, not averaged over the severities left (:func:`complete_families`)."""
    recorded = recorded_severities(paths) or {}
    defined = defined_severities(conf_dir)
    unrecorded = sorted(f for f in defined if f not in recorded)
    return {**defined, **recorded}, unrecorded


def _means(values: Mapping[tuple[str, str, int], np.ndarray], n_boot: int) -> dict[tuple[str, str, int], np.ndarray]:
    """Per cell: its mean (index 0) and ``n_boot`` bootstrap means (1..), houses resampled
    alike in every cell (paired)."""
    n = len(next(iter(values.values())))
    idx = stats.resample_indices(n, n_boot) if n_boot and n >= 2 else np.zeros((0, n), int)
    return {k: np.concatenate([[v.mean()], v[idx].mean(axis=1)]) for k, v in values.items()}


def _measures(means: Mapping, methods: Sequence[str], fams: Sequence[str], reference: str | None,
              ref_ok: Mapping[str, bool]) -> dict[str, dict[str, np.ndarray]]:
    """Every column of the summary per method, each an array (point estimate first, then the
    bootstrap draws); a family's mean is over its severities >= 1, its drop from its severity 0
    (:func:`zero_key`), and a labelled condition also gets one column per severity (``lost 2``).
    CE and relative CE of a family whose drop for the reference is not shown
    above zero (``ref_ok``) are NaN, and such a family is left out of mCE."""
    out: dict[str, dict[str, np.ndarray]] = {"clean": {m: means[(m, "clean", 0)] for m in methods}}
    sev = {f: sorted(s for (m, c, s) in means if c == f and m == methods[0] and s > 0) for f in fams}
    for f in fams:
        out[f] = {m: np.mean([means[(m, f, s)] for s in sev[f]], axis=0) for m in methods}
        out[f"drop {f}"] = {m: means[zero_key(means, m, f)] - out[f][m] for m in methods}
        if f in LABELLED:  # each labelled condition on its own
            for s in sev[f]:
                out[f"{f} {s}"] = {m: means[(m, f, s)] for m in methods}
    nan = np.full_like(out["clean"][methods[0]], np.nan)
    for f in fams:
        err = {m: np.sum([100.0 - means[(m, f, s)] for s in sev[f]], axis=0) for m in methods}
        rel = {m: len(sev[f]) * out[f"drop {f}"][m] for m in methods}
        ok = reference is not None and ref_ok.get(f, False)
        with np.errstate(divide="ignore", invalid="ignore"):
            out[f"CE {f}"] = {m: 100.0 * err[m] / err[reference] if ok else nan for m in methods}
            out[f"rel CE {f}"] = {m: 100.0 * rel[m] / rel[reference] if ok else nan for m in methods}
    core = [f for f in fams if f not in APART and reference is not None and ref_ok.get(f, False)]
    for name, pre in (("mCE", "CE "), ("rel mCE", "rel CE ")):
        out[name] = {m: np.mean([out[pre + f][m] for f in core], axis=0) if core else nan for m in methods}
    plain = [f for f in fams if f not in APART]
    out["mean drop"] = {m: np.mean([out[f"drop {f}"][m] for f in plain], axis=0) if plain else nan for m in methods}
    return out


def pick_reference(means: Mapping, methods: Sequence[str], fams: Sequence[str]) -> tuple[str | None, str]:
    """The method corruption errors are relative to: among the methods that every family
    (but those reported apart: the composite ``realistic``, the labelled conditions, the ablation ``pose``) degrades, the lower end of each family's drop interval
    above zero, the one whose smallest such lower end is largest (the denominators of its CE
    are farthest from zero, so its CE is the steadiest). Returns (method or None, why)."""
    plain = [f for f in fams if f not in APART]
    best, score = None, -np.inf
    for m in methods:
        lows = []
        for f in plain:
            sev = sorted(s for (mm, c, s) in means if c == f and mm == m and s > 0)
            drop = means[zero_key(means, m, f)] - np.mean([means[(m, f, s)] for s in sev], axis=0)
            lows.append(_interval(drop)[0])
        low = min(lows) if lows else -np.inf
        if np.isfinite(low) and low > 0 and low > score:
            best, score = m, low
    if best is None:
        return None, "no method is degraded by every family (each family's drop interval above zero): no CE"
    return best, (f"{best}: every family degrades it (the smallest lower end of a family's drop interval, "
                  f"{score:.1f} points, is the largest of any method)")


def _interval(draws: np.ndarray, level: float = stats.LEVEL) -> tuple[float, float]:
    b = np.asarray(draws, float)[1:]
    b = b[np.isfinite(b)]
    if b.size < 2:
        return float("nan"), float("nan")
    a = (1.0 - level) / 2.0
    lo, hi = np.quantile(b, [a, 1.0 - a])
    return float(lo), float(hi)


def summary_table(cells: pd.DataFrame, reference: str | None, families: Sequence[str] = FAMILIES,
                  values: Mapping[tuple[str, str, int], np.ndarray] | None = None,
                  n_boot: int = stats.N_BOOT) -> pd.DataFrame:
    """Per method: clean score, each family's mean over its severities, CE and relative CE per
    family, mCE and relative mCE (over the families but those reported apart: ``realistic``, the
    labelled conditions and the ablation ``pose``, each of those in columns of its own after the mean drop, a labelled
    condition with one column per severity first), each family's drop (from its severity 0:
    :func:`zero_key`) and the mean drop; with ``values`` (:func:`house_values`), a 95 %
    bootstrap interval for every column (``<column> lo``, ``<column> hi``).

    CE_f(M) = 100 x sum_s E_{s,f}(M) / sum_s E_{s,f}(R); relative CE_f(M) = 100 x sum_s
    (E_{s,f}(M) - E_{0,f}(M)) / sum_s (E_{s,f}(R) - E_{0,f}(R)) (Hendrycks and Dietterich), s >= 1:
    the method's own severity-0 error cancels. A family that does not degrade the reference R (its drop
    interval not above zero; without ``values``, its drop not above zero) gets no CE: it would
    measure clean accuracy, not robustness.

    Args:
        cells: :func:`cell_means` of one dataset and metric, families already complete
            (:func:`complete_families`).
        reference: the method CE is relative to, or None (``auto``: :func:`pick_reference`).
        families: families to report (those with rows).

    Returns:
        One row per method, sorted by mCE (then clean score); ``attrs["reference"]`` the
        reference used and ``attrs["notes"]`` lines about it.

    Raises:
        RobustnessError: no clean rows, the reference absent, or a family without the same
            severities for every method.
    """
    methods = sorted(cells["method"].unique())
    if reference is not None and reference not in methods:
        raise RobustnessError(f"reference method {reference!r} is not among the rows' methods {methods}")
    fams = [f for f in families if f in set(cells["corruption"])]
    for m in methods:
        if not ((cells["method"] == m) & (cells["corruption"] == "clean")).any():
            raise RobustnessError(f"no clean (severity 0) rows for {m}")
    for f in fams:
        sev = sorted(int(s) for s in cells.loc[cells["corruption"] == f, "severity"].unique())
        for m in methods:
            have = sorted(int(s) for s in cells.loc[(cells["corruption"] == f) & (cells["method"] == m), "severity"].unique())
            if have != sev:
                raise RobustnessError(f"{m}: family {f} has severities {have}, others {sev}")
    if values is not None:
        means = _means(values, n_boot)
    else:
        means = {(r.method, r.corruption, int(r.severity)): np.array([r.value])
                 for r in cells.itertuples(index=False)}
    notes = [own_zero_note(f) for f in own_zero_families(means, fams)]
    ablations = [f for f in fams if f in ABLATION]
    if ablations:
        notes.append(f"{', '.join(FAMILY_WORDS.get(f, f) for f in ablations)}: an ablation, not a robot condition (the "
                     f"views move while the map stays at the true poses; a robot builds its map at its own estimate: "
                     f"slam, realistic), reported apart: in neither mCE nor the mean drop.")
    labelled = [f for f in fams if f in LABELLED]
    if labelled:
        notes.append(f"{', '.join(FAMILY_WORDS.get(f, f) for f in labelled)}: labelled conditions (each severity a "
                     f"situation of its own, with a column of its own), reported apart: in neither mCE nor the "
                     f"mean drop.")
    if reference is None:
        reference, why = pick_reference(means, [m for m in methods if m not in SANITY], fams)
        notes.append(f"Reference: {why}.")
    ref_ok = {}
    for f in fams:
        sev = sorted(s for (m, c, s) in means if c == f and m == reference and s > 0) if reference else []
        if not reference:
            continue
        drop = means[zero_key(means, reference, f)] - np.mean([means[(reference, f, s)] for s in sev], axis=0)
        lo = _interval(drop)[0] if values is not None else drop[0]
        ref_ok[f] = bool(np.isfinite(lo) and lo > 0)
        if not ref_ok[f]:
            notes.append(f"No CE for {FAMILY_WORDS.get(f, f)}: it does not degrade the reference {reference} "
                         f"(drop {drop[0]:+.1f}); a CE there would measure clean accuracy, not robustness.")
    cols = _measures(means, methods, fams, reference, ref_ok)
    plain = [f for f in fams if f not in APART]
    comp = [f for f in fams if f in APART]
    order = ["clean", *plain, *[f"CE {f}" for f in plain], "mCE", *[f"rel CE {f}" for f in plain], "rel mCE",
             *[f"drop {f}" for f in plain], "mean drop",
             *[c for f in comp for c in (*condition_columns(cols, f), f, f"CE {f}", f"rel CE {f}", f"drop {f}")]]
    data: dict[str, list[float]] = {}
    for c in order:  # built as one frame (a column at a time fragments a wide one)
        data[c] = [float(cols[c][m][0]) for m in methods]
        if values is not None:
            iv = [_interval(cols[c][m]) for m in methods]
            data[f"{c} lo"], data[f"{c} hi"] = [x[0] for x in iv], [x[1] for x in iv]
    out = pd.DataFrame(data, index=pd.Index(methods, name="method"))
    out = out.sort_values(["mCE", "clean"], ascending=[True, False], na_position="last")
    out.attrs.update(reference=reference, notes=notes, draws={c: cols[c] for c in ("clean", *fams, "mCE", "rel mCE")})
    return out


def condition_columns(table: Collection[str], family: str) -> list[str]:
    """A labelled condition's columns of one severity each (``lost 1``, ``lost 2``, ...), in
    severity order, among the column names ``table``; none for any other family."""
    if family not in LABELLED:
        return []
    found = [c for c in table if c.startswith(f"{family} ") and c[len(family) + 1:].isdigit()]
    return sorted(found, key=lambda c: int(c[len(family) + 1:]))


def numbers(table: pd.DataFrame) -> list[str]:
    """The table's value columns (those without a `` lo`` / `` hi`` bound beside them)."""
    return [c for c in table.columns if not (c.endswith(" lo") or c.endswith(" hi"))]


def rank_notes(table: pd.DataFrame, geometric: Sequence[str], cells: pd.DataFrame | None = None,
               values: Mapping[tuple[str, str, int], np.ndarray] | None = None) -> list[str]:
    """One sentence per condition: the ranking (groups that no paired interval separates, with
    ``values``; else who is first), and how the best view-based method and the best geometric
    one compare at each severity (paired interval: "ahead" only where it excludes zero; "change
    places" only between two such leads); then the ranking on mCE and relative mCE.

    With ``values``, every verdict is corrected for the family it belongs to (Holm,
    :func:`benchmark.stats.holm_verdicts`), and a line before the others names the families and
    their sizes: a ranking's family is every pair of its methods; the view-based against
    geometric verdicts of all the conditions form one family (:func:`view_geometric_verdicts`)."""
    notes = []
    fams = [c for c in table.columns if c in FAMILIES]
    methods = list(table.index)
    geo = [m for m in methods if m in set(geometric)]
    view = [m for m in methods if m not in set(geometric)]
    flips = (view_geometric_verdicts(values, cells, ("clean", *fams), geo, view)
             if values is not None and cells is not None and geo and view else None)
    if values is not None:
        notes.append(family_note(len(methods), flips))
    for col in ("clean", *fams):
        words = FAMILY_WORDS.get(col, col)
        if values is not None:
            per = {m: _per_house(values, m, col) for m in methods}
            line = f"{words}: {stats.group_words(stats.groups(per, corrected=True))}"
        else:
            first = table[col].idxmax()
            line = f"{words}: {first} first ({table.loc[first, col]:.1f})"
        if geo and view:
            if flips is not None:
                line += "; " + _flip_words(flips, col)
            else:
                g, w = table.loc[geo, col].max(), table.loc[view, col].max()
                line += (f"; best view-based {w:.1f}, best geometric {g:.1f} "
                         f"({'view-based ahead' if w > g else 'geometric ahead' if g > w else 'tied'})")
        notes.append(line)
    draws = table.attrs.get("draws", {})
    for name in ("mCE", "rel mCE"):
        d = {m: draws[name][m] for m in methods} if name in draws else {}
        if d and all(np.isfinite(v[0]) for v in d.values()) and len(next(iter(d.values()))) > 2:
            notes.append(f"{name} (lower is better): {stats.group_words(_groups_from_draws(d))}")
    return notes


def family_note(n_methods: int, flips: Mapping | None) -> str:
    """The line that says how the verdicts below are corrected for their number: the families
    and their sizes, the p-value, Holm's step-down and the level each interval is read at."""
    pairs = n_methods * (n_methods - 1) // 2
    alpha = 1.0 - stats.LEVEL
    line = (f"Verdicts corrected for their number (Holm 1979, family-wise error {100 * alpha:g} % per family; two-sided "
            f"bootstrap p-value of each paired difference: twice the share of its {stats.N_BOOT} seeded resampled "
            f"means on the far side of zero): each ranking (of a condition, on mCE, on relative mCE) is a family "
            f"of its {pairs} method pairs ({n_methods} methods)")
    if flips:
        m = next(iter(flips.values()))["m"]
        line += (f"; the best view-based minus best geometric verdicts of every condition and severity are one family "
                 f"of {m} comparisons (clean, each condition's own severity 0 where it has one, every severity >= 1)")
    return (line + f". The i-th smallest p-value of a family is read at {100 * alpha:g} % / (m - i + 1) until the first that Holm "
            "keeps (whose level then holds for the rest); a pair is separated, or a side \"ahead\", only where Holm "
            "rejects and the paired percentile interval at that level excludes zero; each verdict below shows that "
            "interval and its level.")


def view_geometric_verdicts(values: Mapping[tuple[str, str, int], np.ndarray], cells: pd.DataFrame,
                            families: Sequence[str], geo: Sequence[str], view: Sequence[str]) -> dict:
    """Best view-based minus best geometric method (by mean) under every condition of
    ``families`` (``clean``: severity 0 only) at every severity, corrected as one family by
    Holm (:func:`benchmark.stats.holm_verdicts`). A family's severity 0 without rows of its own
    is the clean comparison: counted once.

    Returns:
        (family, severity) -> the verdict dict of :func:`benchmark.stats.holm_verdicts` (diff,
        lo, hi at its level, level, p, p_holm, ahead, m)."""
    keys, cell_of = [], {}
    for family in families:
        fam = cells.loc[cells["corruption"] == family, "severity"]
        for s in [0] if family == "clean" else [0, *sorted(int(s) for s in fam.unique() if s > 0)]:
            def key(m: str, s: int = s, family: str = family) -> tuple[str, str, int]:
                return zero_key(values, m, family) if s == 0 else (m, family, s)

            w = max(view, key=lambda m: values[key(m)].mean())
            g = max(geo, key=lambda m: values[key(m)].mean())
            cell = (key(w), key(g))
            keys.append((family, s))
            cell_of[(family, s)] = cell
    unique = list(dict.fromkeys(cell_of.values()))
    verdicts = dict(zip(unique, stats.holm_verdicts([(values[w], values[g]) for w, g in unique])))
    return {k: verdicts[cell_of[k]] for k in keys}


def _per_house(values: Mapping, m: str, col: str) -> np.ndarray:
    """A method's per-house score under a condition: clean, or the mean over a family's severities
    (1 and up: a family's own severity 0 is not one of them)."""
    if col == "clean":
        return values[(m, "clean", 0)]
    return np.mean([v for (mm, c, s), v in values.items() if mm == m and c == col and s > 0], axis=0)


def _groups_from_draws(draws: Mapping[str, np.ndarray]) -> list[list[str]]:
    """:func:`stats.groups` for a lower-is-better number known by paired bootstrap draws
    (index 0 the estimate): a method joins the group of the best one left unless Holm separates
    them, every pair of methods one family (p-value and interval from the draws of their
    difference: :func:`benchmark.stats.bootstrap_p`, :func:`_interval` at the Holm level)."""
    names = sorted(draws, key=lambda m: (float(draws[m][0]), m))
    pairs = [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]
    diffs = [np.asarray(draws[b], float) - np.asarray(draws[a], float) for a, b in pairs]
    ps = np.array([stats.bootstrap_p(d[1:]) for d in diffs])
    rejected = stats.holm(ps)[1]
    alphas = stats.holm_levels(ps)
    apart = {ab for ab, d, r, a in zip(pairs, diffs, rejected, alphas) if r and stats.separated(*_interval(d, 1 - a))}
    out = []
    left = list(names)
    while left:
        lead = left[0]
        grp = [lead] + [m for m in left[1:] if (lead, m) not in apart]
        out.append(grp)
        left = [m for m in left if m not in grp]
    return out


def _flip_words(flips: Mapping[tuple[str, int], dict], family: str) -> str:
    """Best view-based minus best geometric at each severity of ``family``, from its verdicts
    corrected for their number (:func:`view_geometric_verdicts`), each with its interval and the
    level it is read at; "ahead" only where the verdict says so, "change places at severity s"
    only where a lead so supported turns into one for the other side."""
    sev = sorted(s for (f, s) in flips if f == family)
    parts, leads = [], []
    for s in sev:
        v = flips[(family, s)]
        side = ("view-based ahead" if v["diff"] > 0 else "geometric ahead") if v["ahead"] else "tied"
        leads.append(side)
        parts.append(f"{s}: {side} {v['diff']:+.1f} [{v['lo']:+.1f}, {v['hi']:+.1f}] at {stats.level_words(v['level'])}")
    if family == "clean":
        return f"best view-based minus best geometric (paired interval, Holm-corrected): {parts[0][3:]}"
    sure = [(s, x) for s, x in zip(sev, leads) if x != "tied"]
    changes = [b[0] for a, b in zip(sure, sure[1:]) if a[1] != b[1]]
    verdict = (f"they change places at severit{'y' if len(changes) == 1 else 'ies'} {', '.join(map(str, changes))}"
               if changes else "no change of places that the intervals support")
    return (f"best view-based minus best geometric by severity (paired interval, Holm-corrected): {'; '.join(parts)}; "
            f"{verdict}")


def rising_curves(values: Mapping[tuple[str, str, int], np.ndarray], families: Sequence[str]) -> pd.DataFrame:
    """Every step of a method's curve (severity 0: the family's own or clean, :func:`zero_key`;
    then severity 1, 2, ...) where its mean rises with severity, with the paired interval of the rise and whether it excludes zero.

    Returns:
        Columns method, family, step (``"2->3"``), rise, lo, hi (points), significant."""
    rows = []
    methods = sorted({m for (m, _, _) in values})
    for f in families:
        for m in methods:
            sev = sorted(s for (mm, c, s) in values if mm == m and c == f and s > 0)
            curve = [values[zero_key(values, m, f)], *[values[(m, f, s)] for s in sev]]
            xs = [0, *sev]
            for i in range(1, len(curve)):
                d, lo, hi = stats.paired_ci(curve[i], curve[i - 1])
                if d > 0:
                    rows.append({"method": m, "family": f, "step": f"{xs[i - 1]}->{xs[i]}", "rise": d, "lo": lo,
                                 "hi": hi, "significant": bool(stats.separated(lo, hi))})
    return pd.DataFrame(rows, columns=["method", "family", "step", "rise", "lo", "hi", "significant"])


#: the difference a cell should detect by default (points of matched IoU) and the power.
DELTA, POWER = 3.0, 0.8


def power_report(values: Mapping[tuple[str, str, int], np.ndarray], methods: Sequence[str], delta: float = DELTA,
                 power: float = POWER) -> dict:
    """How many houses a cell needs: from the spread (standard deviation over houses) of the
    paired difference between every two ``methods`` under every condition, the houses a paired
    t-test needs to detect ``delta`` points at ``power`` (two-sided, 5 %), at the median spread
    and at the 90th percentile; and the smallest difference the run's own houses detect at the
    median spread.

    Returns:
        dict: n (houses now), pairs (comparisons), sd_median, sd_p90, need_median, need_p90,
        detectable (points), delta, power."""
    sds = []
    conds = sorted({(c, s) for (_, c, s) in values})
    for c, s in conds:
        ms = [m for m in methods if (m, c, s) in values]
        for i, a in enumerate(ms):
            for b in ms[i + 1:]:
                d = values[(a, c, s)] - values[(b, c, s)]
                if d.size >= 2:
                    sds.append(float(np.std(d, ddof=1)))
    n = len(next(iter(values.values()))) if values else 0
    if not sds:
        return {"n": n, "pairs": 0}
    med, p90 = float(np.median(sds)), float(np.quantile(sds, 0.9))
    return {"n": n, "pairs": len(sds), "sd_median": med, "sd_p90": p90, "delta": delta, "power": power,
            "need_median": stats.houses_needed(med, delta, power), "need_p90": stats.houses_needed(p90, delta, power),
            "detectable": stats.detectable_difference(med, n, power) if n >= 2 else float("nan")}


#: the shared ProcTHOR houses (data/procthor): a ProcTHOR cell can hold no more.
PROCTHOR_SHARED_HOUSES = 150


def power_lines(dataset: str, p: dict, metric_words: str) -> list[str]:
    """The power report of one dataset in words (and, for ProcTHOR, whether its 150 shared
    houses are enough)."""
    if not p.get("pairs"):
        return [f"{dataset}: no paired comparison to size (fewer than two methods)."]
    lines = [f"{dataset}: the paired difference of two methods under one condition spreads by "
             f"{p['sd_median']:.1f} points over houses (median of {p['pairs']} comparisons; 90th percentile "
             f"{p['sd_p90']:.1f}). To detect {p['delta']:g} points of {metric_words} at {p['power']:.0%} power "
             f"(paired t-test, two-sided 5 %) a cell needs {p['need_median']} houses at the median spread, "
             f"{p['need_p90']} at the 90th percentile. With its {p['n']} houses this run detects "
             f"{p['detectable']:.1f} points at the median spread."]
    if dataset.lower().startswith("procthor") and p["need_median"] > PROCTHOR_SHARED_HOUSES:
        lines.append(f"{dataset}: the {PROCTHOR_SHARED_HOUSES} shared ProcTHOR houses are too few for a "
                     f"{p['delta']:g}-point claim at the median spread; at {PROCTHOR_SHARED_HOUSES} houses the "
                     f"smallest detectable difference is "
                     f"{stats.detectable_difference(p['sd_median'], PROCTHOR_SHARED_HOUSES):.1f} points.")
    return lines


def _cell_text(row: pd.Series, c: str, decimals: int) -> str:
    x = row[c]
    if not np.isfinite(x):
        return "–"
    lo, hi = row.get(f"{c} lo", np.nan), row.get(f"{c} hi", np.nan)
    if np.isfinite(lo) and np.isfinite(hi):
        return f"{x:.{decimals}f} [{lo:.{decimals}f}, {hi:.{decimals}f}]"
    return f"{x:.{decimals}f}"


def to_markdown(table: pd.DataFrame, decimals: int = 1, columns: Sequence[str] | None = None,
                labels: Mapping[str, str] | None = None) -> str:
    """The table in Markdown: each number with its 95 % interval beside it where the table has
    one (``mean [lo, hi]``), ``decimals`` decimals, a missing value as a dash. ``columns``: the
    value columns to show (default all); ``labels``: header words for some of them."""
    cols = list(columns) if columns is not None else numbers(table)
    header = ["method", *[(labels or {}).get(c, c) for c in cols]]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(["---", *["---:"] * len(cols)]) + "|"]
    for m, row in table.iterrows():
        cells = [_cell_text(row, c, decimals) for c in cols]
        lines.append("| " + " | ".join([str(m).replace("|", "\\|"), *cells]) + " |")
    return "\n".join(lines) + "\n"


def to_latex(table: pd.DataFrame, caption: str, label: str, decimals: int = 1) -> str:
    """The table as a booktabs ``table*`` environment (each number with its interval beside it)."""
    from benchmark.reports.formatting import tex_escape

    cols = numbers(table)
    spec = "l" + "r" * len(cols)
    head = " & ".join(["method", *[tex_escape(c) for c in cols]]) + r" \\"
    body = [" & ".join([tex_escape(str(m)), *[tex_escape(_cell_text(row, c, decimals)) for c in cols]]) + r" \\"
            for m, row in table.iterrows()]
    return "\n".join([r"\begin{table*}[t]", r"\centering", r"\scriptsize", rf"\begin{{tabular}}{{{spec}}}",
                      r"\toprule", head, r"\midrule", *body, r"\bottomrule", r"\end{tabular}",
                      rf"\caption{{{tex_escape(caption)}}}", rf"\label{{{label}}}", r"\end{table*}", ""])


def drop_failed_houses(rows: pd.DataFrame) -> tuple[pd.DataFrame, list[str]]:
    """Leave out every house that failed in any (method, condition), and every house whose SLAM
    solve did not converge in any (``slam_converged`` 0: cut off at its iteration cap; no verdict
    rests on an unconverged solve, and a house leaves every cell so that cells stay paired):
    (rows, the houses left out, an unconverged one named "<house> (SLAM solve not converged)")."""
    bad = set(rows.loc[rows["status"] != "ok", "house_id"].astype(str))
    unconverged = set()
    if "slam_converged" in rows:
        flag = rows["slam_converged"].astype(str).str.strip().str.lower()
        unconverged = set(rows.loc[flag.isin(["0", "0.0", "false"]), "house_id"].astype(str)) - bad
    names = sorted(bad) + [f"{h} (SLAM solve not converged)" for h in sorted(unconverged)]
    return rows[~rows["house_id"].astype(str).isin(bad | unconverged)], names


#: the name prefix of methods run on houses and conditions of their own (``experiment=robustness_ipa``:
#: the authors' ipa_room_segmentation, ``make ipa-env``): their rows are set apart from the main
#: tables (in no cell, mean, mCE, reference, ranking or verdict there, and no failure of theirs
#: drops a house from them) and shown in a table of their own beside the ports on the same houses
#: (:func:`apart_summary`).
OWN_HOUSES_PREFIX = "ipa_"


def own_house_rows(rows: pd.DataFrame) -> pd.Series:
    """Which of ``rows`` belong to the methods run on houses of their own (:data:`OWN_HOUSES_PREFIX`)."""
    return rows["method"].astype(str).str.startswith(OWN_HOUSES_PREFIX)


def condition_name(corruption: str, severity: int) -> str:
    """A condition as ``conf/corruption`` names it: ``clean``, ``scan_3``."""
    return "clean" if corruption == "clean" else f"{corruption}_{int(severity)}"


def _condition_order(key: tuple[str, int]) -> tuple[int, str, int]:
    c, s = key
    return (0 if c == "clean" else 1 + FAMILIES.index(c) if c in FAMILIES else len(FAMILIES) + 1, c, s)


def _house_words(houses: Sequence[str]) -> str:
    return ", ".join(houses)


def apart_summary(own: pd.DataFrame, rest: pd.DataFrame, metric: str, beside: Sequence[str] = GEOMETRIC,
                  n_boot: int = stats.N_BOOT) -> dict:
    """The table of the methods run on houses of their own (``own``: the ipa rows of one dataset)
    beside the ports (``beside``, their rows taken from ``rest`` on the same houses and
    conditions): one column per condition the own rows have (``clean``, ``scan_3``, ...), the mean
    over houses with its 95 % interval (houses resampled alike in every cell). A house that failed
    in any of the table's rows leaves every cell of it (named), a condition some method of the
    table lacks leaves it (a line says which), and so does a house not in every remaining cell.
    For the ranked metrics, one ranking per condition (groups that no paired interval separates,
    Holm-corrected over the condition's pairs), over these houses only.

    Returns:
        dict: table (one row per method, sorted by the clean score), houses (the ids every cell
        holds), dropped (houses left out, named), notes (lines), conditions (column names)."""
    conds = sorted({(str(c), int(s)) for c, s in zip(own["corruption"], own["severity"])}, key=_condition_order)
    houses = set(own["house_id"].astype(str))
    cond_of = list(zip(rest["corruption"].astype(str), rest["severity"].astype(int)))
    take = (rest["method"].isin(list(beside)) & rest["house_id"].astype(str).isin(houses)
            & pd.Series([k in set(conds) for k in cond_of], index=rest.index, dtype=bool))
    both = pd.concat([own, rest[take]], ignore_index=True)
    both["house_id"] = both["house_id"].astype(str)
    both, dropped = drop_failed_houses(both)
    methods = [*sorted(own["method"].unique()), *[m for m in beside if m in set(both["method"])]]
    notes = []
    have = {(m, c, int(s)): set(g["house_id"]) for (m, c, s), g in both.groupby(["method", "corruption", "severity"])}
    kept = []
    for c, s in conds:
        lack = [m for m in methods if not have.get((m, c, s))]
        if lack:
            notes.append(f"{condition_name(c, s)} left out of this table: no rows for {', '.join(lack)}")
        else:
            kept.append((c, s))
    common = set.intersection(*[have[(m, c, s)] for m in methods for c, s in kept]) if kept else set()
    odd = sorted(set(both["house_id"]) - common) if kept else []
    if odd:
        notes.append(f"left out of this table (not in every cell of it): {_house_words(odd)}")
    shown = sorted(common)
    cols = [condition_name(c, s) for c, s in kept]
    if not shown or not kept:
        return {"table": pd.DataFrame(index=pd.Index(methods, name="method")), "houses": shown, "dropped": dropped,
                "notes": notes + ["no house holds rows of every method of this table under any condition"],
                "conditions": cols}
    both = both[both["house_id"].isin(common)].sort_values("house_id", kind="stable")
    values = {(str(m), str(c), int(s)): 100.0 * g[metric].to_numpy(dtype=float)
              for (m, c, s), g in both.groupby(["method", "corruption", "severity"]) if (c, int(s)) in kept}
    means = _means(values, n_boot)
    data: dict[str, list[float]] = {}
    for (c, s), name in zip(kept, cols):
        data[name] = [float(means[(m, c, s)][0]) for m in methods]
        iv = [_interval(means[(m, c, s)]) for m in methods]
        data[f"{name} lo"], data[f"{name} hi"] = [x[0] for x in iv], [x[1] for x in iv]
    table = pd.DataFrame(data, index=pd.Index(methods, name="method"))
    if "clean" in table:
        table = table.sort_values("clean", ascending=False)
    if len(shown) < 2:
        notes.append("one house: no interval and no ranking (ROBUST_IPA_HOUSES sets how many houses the ipa rows get)")
    elif metric in RANKED:
        notes.append(f"Rankings over these {len(shown)} houses only (each condition's ranking a family of its "
                     f"{len(methods) * (len(methods) - 1) // 2} method pairs, Holm-corrected):")
        for (c, s), name in zip(kept, cols):
            per = {m: values[(m, c, s)] for m in methods}
            notes.append(f"{name}: {stats.group_words(stats.groups(per, corrected=True))}")
    return {"table": table, "houses": shown, "dropped": dropped, "notes": notes, "conditions": cols}


def apart_lines(apart: dict, words: str) -> list[str]:
    """The Markdown lines of the ipa rows of one dataset and metric (:func:`apart_summary`; ``words``
    names the metric): their houses and conditions, the table beside the ports on those houses,
    its notes. robustness.md (``python -m benchmark.commands.robustness``) and the robustness
    block of docs/robustness.md (``make readme-tables``) both print it."""
    houses = apart["houses"]
    return [f"ipa_room_segmentation ({words}; the authors' C++, `make ipa-env`) beside the ports, on houses of its "
            f"own: {len(houses)} house(s) ({', '.join(houses)}) under {len(apart['conditions'])} condition(s) "
            f"({', '.join(apart['conditions'])}); the ports' rows here are theirs on the same houses. Reported apart: "
            f"in no mean, mCE, reference, ranking or verdict above, which are over the other house set"
            + (f"; left out (failed in a row of this table): {', '.join(apart['dropped'])}" if apart["dropped"] else "")
            + ".", "", to_markdown(apart["table"]) if len(apart["table"].columns) else "(no cell)",
            *[f"- {n}" for n in apart["notes"]], ""]


def summarise(rows: pd.DataFrame, metrics: Sequence[str], reference: str | None = None,
              expected: Mapping[str, Sequence[int]] | None = None, n_boot: int = stats.N_BOOT,
              delta: float = DELTA, unrecorded: Collection[str] = ()) -> dict:
    """Per dataset and metric: the summary table (CE and mCE for the ranked metrics only), its
    cells, the notes (rankings, reference, families left out), the rising curves and the power
    report. ``reference`` None or ``"auto"``: :func:`pick_reference`. ``expected``: family ->
    severities the sweep asked for, ``unrecorded``: the families among them no sweep record
    names (both :func:`expected_severities` of the rows' folders; :func:`complete_families`).
    The rows of methods run on houses of their own (:func:`own_house_rows`: the ipa rows) are in
    none of that: each part's ``apart`` holds their table beside the ports (:func:`apart_summary`),
    None where the dataset has none. Raises RobustnessError."""
    if reference == "auto":
        reference = None
    out = {}
    for dataset, d in rows.groupby("dataset"):
        own_mask = own_house_rows(d)
        own, d = d[own_mask], d[~own_mask]  # the ipa rows: a table of their own (apart_summary)
        if not len(d):
            raise RobustnessError(f"{dataset}: only rows of {sorted(own['method'].unique())} (houses of their own); "
                                  f"run experiment=robustness on that dataset first")
        every = d
        d, dropped = drop_failed_houses(d)
        for metric in metrics:
            cells = cell_means(d, metric)
            kept, left = complete_families(cells, expected, unrecorded=unrecorded)
            keep = cells["corruption"].isin(["clean", *kept])
            cells = cells[keep].reset_index(drop=True)
            sub = d[d["corruption"].isin(["clean", *kept])]
            values = house_values(sub, metric)
            ranked = metric in RANKED
            table = summary_table(cells, reference, kept, values, n_boot)
            if not ranked:
                table = table.drop(columns=[c for c in table.columns if "CE" in c]).sort_values("clean", ascending=False)
            methods = [m for m in table.index if m not in SANITY]
            notes = list(left)
            if ranked:
                notes += table.attrs["notes"]
            else:
                notes.append("The paper's IoU rewards maps that shrink (a missing room costs it nothing): shown, "
                             "not ranked, and no mCE is built on it.")
            notes += rank_notes(table.loc[methods], GEOMETRIC, cells, values) if ranked else []
            out[(dataset, metric)] = {"table": table, "cells": cells, "dropped": dropped, "left_out": left,
                                      "houses": int(cells["n"].iloc[0]) if len(cells) else 0, "notes": notes,
                                      "reference": table.attrs.get("reference") if ranked else None,
                                      "curves": rising_curves({k: v for k, v in values.items() if k[0] in methods},
                                                              [f for f in kept]),
                                      "power": power_report(values, methods, delta) if ranked else None,
                                      "apart": apart_summary(own, every, metric, n_boot=n_boot) if len(own) else None}
    return out


#: colour-blind safe colours (Okabe and Ito, 2008) and line styles, cycled per method.
OKABE_ITO = ("#000000", "#E69F00", "#56B4E9", "#009E73", "#0072B2", "#D55E00", "#CC79A7", "#F0E442")  # yellow last
STYLES = ("-", "--", ":", "-.")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")


def family_figure(cells: pd.DataFrame, family: str, path: Path, metric_words: str, title: str) -> list[Path]:
    """Metric vs severity (0 = clean, or the family's own severity 0 where the cells have it;
    then 1 up to the family's highest) for one family, one line per method, colour-blind
    safe (Okabe-Ito colours, and a marker and line style per method so that it reads in grey);
    written as PNG and PDF. Returns the files."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from benchmark.reports.plotting import save

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    own = bool(((cells["corruption"] == family) & (cells["severity"] == 0)).any())
    for i, m in enumerate(sorted(cells["method"].unique())):
        c = cells[cells["method"] == m]
        zero = c[(c["corruption"] == family) & (c["severity"] == 0)]
        clean = zero if len(zero) else c[c["corruption"] == "clean"]
        fam = c[(c["corruption"] == family) & (c["severity"] > 0)].sort_values("severity")
        x = [0, *fam["severity"].tolist()]
        y = [float(clean["value"].iloc[0]) if len(clean) else np.nan, *fam["value"].tolist()]
        ax.plot(x, y, color=OKABE_ITO[i % len(OKABE_ITO)], linestyle=STYLES[(i // len(OKABE_ITO)) % len(STYLES)],
                marker=MARKERS[i % len(MARKERS)], markersize=4, linewidth=1.4, label=m)
    ax.set_xlabel("severity (0 = the family's own severity 0, not clean)" if own else "severity (0 = clean)")
    ax.set_ylabel(f"{metric_words} (%)")
    ax.set_xticks(range(int(cells["severity"].max()) + 1))
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return save(fig, path.with_suffix(".png"), formats=("png", "pdf"))


__all__ = ["FAMILIES", "METRICS", "RANKED", "COMPOSITE", "LABELLED", "ABLATION", "APART", "OWN_ZERO_WORDS", "RobustnessError", "cell_means", "complete_families",
           "drop_failed_houses", "house_values", "numbers", "pick_reference", "power_lines", "power_report",
           "rank_notes", "family_note", "view_geometric_verdicts", "rising_curves", "summarise", "summary_table",
           "defined_severities", "recorded_severities", "expected_severities", "to_markdown", "to_latex", "family_figure",
           "zero_key", "own_zero_families", "own_zero_note", "condition_columns", "OWN_HOUSES_PREFIX",
           "own_house_rows", "condition_name", "apart_summary", "apart_lines"]
