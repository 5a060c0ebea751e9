"""``python -m benchmark.commands.robustness``: the robustness benchmark's tables and figures.

    python -m benchmark.commands.robustness results/runs/robustness --out results/robustness
    python -m benchmark.commands.robustness RUN --reference "objects+graph_knn +post" --metric iou

Reads every job of the run (``experiment=robustness``), and per dataset and metric (the paper's
IoU, matched IoU, PQ) writes the summary of :mod:`benchmark.reports.robustness` (clean score,
each family's mean over its severities, corruption error, relative CE, mCE and relative mCE
against ``--reference`` for matched IoU and PQ, drops from each family's severity 0 (its own rows
where the run has them, as ``explore_0``, else clean); each with its 95 % interval over houses)
as Markdown, CSV and LaTeX, the steps where a curve rises with severity (``*_rising.csv``), a
figure per family (metric vs severity, one line per method, PNG and PDF; none for the labelled
conditions ``lost`` and ``kidnap``, whose severities are no ladder: robustness.md has a table of
each of their conditions instead), and
``robustness.md`` with every table, the rankings and what they show in words, the curves that
rise by more than chance, how many houses a cell needs to detect ``--delta`` points (the power
report) and every severity's physical values. A family whose severities are not all there (a
job that did not finish, for some method or all; the severities its sweep's ``multirun.yaml`` asked
for, or every one ``conf/corruption`` defines where no sweep record is left) is left out with a
line naming it; a sweep
whose jobs did not all finish is named with its missing jobs (stderr and robustness.md). A house that failed under any condition is
left out of every cell of its dataset (one line names it), so every cell holds the same houses.
The ipa_room_segmentation rows (``experiment=robustness_ipa``: a sweep of their own in the run's
``ipa/`` folder) have houses and conditions of their own: per dataset and metric they get a table
of their own beside the ports on the same houses (``*_ipa.csv`` and ``.md``; robustness.md names
the houses), in no cell, mean, mCE or verdict of the main tables; with ``--last-sweep`` an ipa
sweep that finished before the main sweep started (an earlier run's) is left out with a line.
The output folder is written as a whole (an interrupted command leaves the old set or the new).
The figures and the severities' settings (a config composed per severity) are made side by side
on forked processes, one per core (``ROOMSEG_JOBS=1``: one after another in this process).
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Sequence
from pathlib import Path

from benchmark.commands import cli
from benchmark.commands.errors import one_line
from benchmark.harness.processes import run_forked
from benchmark.paths import CONF_DIR
from benchmark.reports import robustness as rb
from benchmark.reports.formatting import metric_words
from benchmark.reports.tables import load_rows
from envs.atomic import atomic_folder

GEOMETRIC, SANITY, DEFAULT_REFERENCE = rb.GEOMETRIC, rb.SANITY, rb.REFERENCE


def severity_settings(conf_dir: str | Path = CONF_DIR) -> dict[tuple[str, int], str]:
    """(family, severity) -> the settings its ``conf/corruption/<family>_<k>.yaml`` chooses, as
    the composed config has them: the keys the file sets (read as YAML), each with its value in
    the config composed with ``corruption=<family>_<k>`` (units: the configuration reference)."""
    from omegaconf import OmegaConf

    from benchmark.config import compose
    from benchmark.harness.store import flat_settings

    out = {}
    for p in sorted(Path(conf_dir, "corruption").glob("*_[0-9].yaml")):  # a family's own severity 0 too
        family, k = p.stem.rsplit("_", 1)
        given = OmegaConf.to_container(OmegaConf.load(p))
        keys = [key for key in flat_settings({g: v for g, v in given.items() if g not in ("defaults", "robot")})
                if not key.endswith("_target_")]
        cfg = compose("config", [f"corruption={p.stem}"])
        values = [f"{key} {OmegaConf.select(cfg, key)}" for key in keys]
        groups = [f"{g}={choice}" for d in given.get("defaults", []) if isinstance(d, dict)
                  for g, choice in ((str(x).split("/")[-1], y) for x, y in d.items())]
        out[(family, int(k))] = "; ".join([*groups, *values])
    return out


#: value columns shown in robustness.md's summary (every column, with its interval, is in the .csv
#: and .md files of each table); the labelled conditions have a table of their own there.
SHOWN = ("clean", *[f for f in rb.FAMILIES if f not in rb.LABELLED], "mCE", "rel mCE", "mean drop")


def labelled_columns(table) -> list[str]:
    """The labelled conditions' columns of a summary table: per labelled family, one per severity
    (``lost 1``, ...), then the family's mean and its drop."""
    return [c for f in rb.LABELLED if f in table.columns for c in (*rb.condition_columns(table.columns, f), f,
                                                                    f"drop {f}")]


def earlier_nested_sweeps(paths: Sequence[str | Path]) -> list[tuple[Path, str]]:
    """Sweep folders inside another sweep folder at or under ``paths`` (``runs/robustness/ipa``, the
    ipa rows' multirun, which `make robustness` runs after the main one) whose last sweep finished
    before the enclosing folder's last sweep started: an earlier run's, left out with ``--last-sweep``
    (a `make robustness` without the ipa build would otherwise show the rows of an older one). Each
    with one line saying so."""
    from benchmark.harness.store import LAST_SWEEP, last_sweep

    out = []
    for p in map(Path, paths):
        if not p.is_dir():
            continue
        sweeps = sorted({m.parent for m in p.rglob(LAST_SWEEP)}, key=lambda d: len(d.parts))
        for inner in sweeps:
            outer = next((d for d in reversed(sweeps) if d != inner and d in inner.parents), None)
            if outer is None:
                continue
            started, finished = (last_sweep(outer) or {}).get("started_at"), (last_sweep(inner) or {}).get("finished_at")
            if started and finished and finished < started:  # ISO 8601, UTC: ordered as text
                out.append((inner, f"{inner}: left out, an earlier run's sweep (finished {finished}, before the last "
                                   f"sweep of {outer} started, {started})"))
    return out


def _stem(dataset: str, metric: str) -> str:
    """The name every file of one dataset's table of one metric starts with."""
    return f"robustness_{dataset}_{metric}"


def _summary_part(rows, metric: str, reference: str, expected, delta: float, unrecorded, out: Path | None) -> dict:
    """:func:`benchmark.reports.robustness.summarise` of one dataset's rows and one metric; with
    ``out``, its figures too (matched IoU and IoU: one per family, a labelled condition's
    severities being no ladder)."""
    parts = rb.summarise(rows, [metric], reference, expected, delta=delta, unrecorded=unrecorded)
    if out is not None and metric in ("iou", "matched_iou"):
        for (dataset, _), p in parts.items():
            for family in rb.FAMILIES:
                if family in set(p["cells"]["corruption"]) and family not in rb.LABELLED:
                    rb.family_figure(p["cells"], family, out / "figures" / f"{_stem(dataset, metric)}_{family}",
                                     metric_words(metric), f"{dataset}: {rb.FAMILY_WORDS[family]}")
    return parts


def render(paths: Sequence[str | Path], out: Path | None, metrics: Sequence[str], reference: str,
           delta: float = rb.DELTA, last_sweep: bool = False) -> str:
    """The Markdown of every table (and, with ``out``, the files). ``last_sweep``: only the jobs
    of the last multirun into each folder. Raises RobustnessError."""
    from benchmark.harness.store import sweep_scope
    from benchmark.reports.sweep_jobs import partial_sweep_lines
    from benchmark.stats import METHOD_WORDS

    scope = sweep_scope(paths, last_sweep)
    if scope.note:
        print(f"robustness: note: {scope.note}", file=sys.stderr)
    files = scope.files
    stale = earlier_nested_sweeps(paths) if last_sweep else []
    for d, why in stale:
        print(f"robustness: note: {why}", file=sys.stderr)
        files = [f for f in files if d.resolve() not in f.resolve().parents]
    rows = load_rows(files)
    if rows.attrs.get("set_aside"):
        print(f"robustness: {rows.attrs['set_aside']}", file=sys.stderr)
    partial = partial_sweep_lines(paths)
    for line in partial:
        print(f"robustness: {line}", file=sys.stderr)
    missing = [c for c in ("corruption", "severity") if c not in rows]
    if missing:
        raise rb.RobustnessError(f"the rows under {[str(p) for p in paths]} have no {missing} column: "
                                 f"run `roomseg-bench experiment=robustness` (conf/corruption) first")
    rows = rows.copy()
    rows["severity"] = rows["severity"].astype(int)
    expected, unrecorded = rb.expected_severities(paths)  # the sweep's, else every one conf/corruption defines
    # each dataset and metric summarised (and its figures drawn) on its own, side by side on forked
    # processes with the severities' settings (run_forked): the same parts, in the same order, as
    # rb.summarise of every dataset and metric at once
    tasks = [severity_settings]
    for _, d in rows.groupby("dataset"):
        tasks += [functools.partial(_summary_part, d, metric, reference, expected, delta, unrecorded, out)
                  for metric in metrics]
    settings, *done = run_forked(tasks)
    del rows, tasks
    parts = {k: v for part in done for k, v in part.items()}
    labelled = [f for f in rb.LABELLED if any(f in p["table"].columns for p in parts.values())]
    with_ipa = sorted({d for (d, _), p in parts.items() if p.get("apart") is not None})
    ref_words = ("a method every family degrades, chosen per dataset and metric (named under each table)"
                 if reference in (None, "auto") else f"**{reference}**")
    md = ["# Robustness to robot conditions", "",
          f"Matched IoU and PQ rank the methods; the paper's IoU is shown beside them but builds no mCE (it "
          f"rewards maps that shrink). Corruption error (CE), relative CE and their means over the families "
          f"(mCE, rel mCE; `realistic`, the combination of the others, is reported apart and in neither, and so is "
          f"the ablation `pose`, views-only pose noise on a perfect map, which no robot has) are "
          f"relative to {ref_words}: 100 = as robust as it, lower is better; relative CE subtracts each "
          f"method's clean error, so clean accuracy cancels. Error = 100 - metric; drop = clean - mean over "
          f"the family's severities. Metrics in percent, mean over houses with its 95 % interval "
          f"[lo, hi] ({METHOD_WORDS}); every cell of a dataset holds the same houses. Rankings: braces hold "
          f"methods that no paired interval separates; every verdict is corrected for its family (Holm: the "
          f"first line under each table names the families and their sizes)."
          + (f" Runs read: {scope.note}." if scope.note else "")
          + (" The labelled conditions (" + ", ".join(f"`{f}`" for f in labelled) + ": each severity a situation of "
             "its own, not a step of one ladder) are reported apart too, each condition in a column of a table of "
             "its own, and are in neither mean." if labelled else "")
          + (f" The ipa_room_segmentation rows (`make ipa-env`) run on houses and conditions of their own: each "
             f"dataset's are in a table of their own beside the ports on the same houses ({', '.join(with_ipa)}), in "
             f"no mean, mCE or verdict of the main tables." if with_ipa else
             " No ipa_room_segmentation rows in these runs (`make ipa-env`, then `make robustness`, adds them)."),
          "",
          *[f"**Partial sweep**: {x}." for x in partial],
          *[f"**Earlier run left out**: {why}." for _, why in stale],
          *([""] if partial or stale else [])]
    power = []
    for (dataset, metric), p in parts.items():
        words = metric_words(metric)
        t = p["table"]
        shown = [c for c in SHOWN if c in t.columns]
        md += [f"## {dataset}: {words}", "", f"{p['houses']} houses per cell"
               + (f"; left out (failed under some condition): {', '.join(p['dropped'])}" if p["dropped"] else "")
               + ".", "", rb.to_markdown(t, columns=shown), *[f"- {n}" for n in p["notes"]], ""]
        apart = labelled_columns(t)
        if apart:
            md += [f"Labelled conditions ({words}; each condition on its own, then the family's mean and its drop; "
                   f"reported apart, in neither mCE nor the mean drop):", "", rb.to_markdown(t, columns=apart), ""]
        curves = p["curves"]
        if metric in rb.RANKED:
            sig = curves[curves["significant"]] if len(curves) else curves
            n_curves = len({(m, f) for m in t.index if m not in SANITY for f in rb.FAMILIES if f in t.columns})
            md += [f"Curves that rise with severity ({words}): {curves[['method', 'family']].drop_duplicates().shape[0]} "
                   f"of {n_curves} method x family curves rise somewhere; {len(sig)} step(s) rise with a paired 95 % "
                   f"interval above zero (the others are within noise; docs/robustness.md says what the "
                   f"significant ones are)"
                   + (":" if len(sig) else "."), ""]
            md += [f"- {r.method} / {rb.FAMILY_WORDS.get(r.family, r.family)}, severity {r.step}: +{r.rise:.1f} "
                   f"[{r.lo:+.1f}, {r.hi:+.1f}]" for r in sig.itertuples()]
            md.append("")
        if p.get("apart") is not None:
            md += rb.apart_lines(p["apart"], words)
            if out is not None and len(p["apart"]["table"].columns):
                p["apart"]["table"].round(4).to_csv(out / f"robustness_{dataset}_{metric}_ipa.csv")
                (out / f"robustness_{dataset}_{metric}_ipa.md").write_text(rb.to_markdown(p["apart"]["table"]),
                                                                            encoding="utf-8")
        if p.get("power") and metric == "matched_iou":
            power += rb.power_lines(dataset, p["power"], words)
        if out is not None:
            stem = _stem(dataset, metric)
            t.round(4).to_csv(out / f"{stem}.csv")
            if len(curves):
                curves.round(4).to_csv(out / f"{stem}_rising.csv", index=False)
            (out / f"{stem}.tex").write_text(rb.to_latex(t[[c for c in t.columns if c.split(" lo")[0].split(" hi")[0]
                                                              in shown]],
                                                         f"Robustness on {dataset}: {words}"
                                                         + (f", CE relative to {p['reference']}" if p["reference"] else "")
                                                         + "; mean [95 % interval] over houses", f"tab:{stem}"),
                                             encoding="utf-8")
            (out / f"{stem}.md").write_text(rb.to_markdown(t), encoding="utf-8")
    if power:
        md += ["## How many houses", "", *[f"- {x}" for x in power], ""]
    md += ["## Severities", "", "What each severity's `conf/corruption` file sets, as the composed config has it (units: "
           "the configuration reference, docs/reference/config.md).", "",
           "| family | severity | settings |", "|---|---:|---|"]
    md += [f"| {f} | {k} | {v} |" for (f, k), v in sorted(settings.items())]
    md.append("")
    text = "\n".join(md)
    if out is not None:
        (out / "robustness.md").write_text(text, encoding="utf-8")
    return text


def main(argv: Sequence[str] | None = None) -> int:
    ap = cli.ArgumentParser(prog="python -m benchmark.commands.robustness",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("paths", nargs="+", help="the robustness run's folder(s)")
    ap.add_argument("--out", type=Path, default=None, help="folder for the tables and figures (written as a whole)")
    ap.add_argument("--reference", default=DEFAULT_REFERENCE,
                    help="the method CE is relative to (a method label), or auto (default): a method every family "
                         "degrades")
    ap.add_argument("--delta", type=float, default=rb.DELTA,
                    help="the difference (points of matched IoU) the power report sizes the houses for (default 3)")
    ap.add_argument("--metric", action="append", choices=rb.METRICS, help="metric(s) (default: all three)")
    ap.add_argument("--last-sweep", action="store_true",
                    help="only the jobs of the last multirun into each folder (its last_sweep.json)")
    a = ap.parse_args(argv)
    metrics = a.metric or list(rb.METRICS)
    try:
        if a.out is None:
            text = render(a.paths, None, metrics, a.reference, a.delta, a.last_sweep)
        else:
            with atomic_folder(a.out) as tmp:
                (tmp / "figures").mkdir()
                text = render(a.paths, tmp, metrics, a.reference, a.delta, a.last_sweep)
    except (rb.RobustnessError, FileNotFoundError, ValueError) as e:
        print(f"robustness: error: {one_line(e)}", file=sys.stderr)
        return 2
    except OSError as e:
        from benchmark.harness.write_errors import cannot_write

        print(f"robustness: error: {cannot_write(e, a.out)}", file=sys.stderr)
        return 2
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
