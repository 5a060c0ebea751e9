"""``python -m benchmark.commands.robustness``: the robustness benchmark's tables and figures.

    python -m benchmark.commands.robustness results/runs/robustness --out results/robustness
    python -m benchmark.commands.robustness RUN --reference "objects+graph_knn +post" --metric iou

Reads every job of the run (``experiment=robustness``), and per dataset and metric (the paper's
IoU, matched IoU, PQ) writes the summary of :mod:`benchmark.reports.robustness` (clean score,
each family's mean over its severities, corruption error and mCE against ``--reference``,
drops) as Markdown, CSV and LaTeX, a figure per family (metric vs severity, one line per
method, PNG and PDF), and ``robustness.md`` with every table, what it shows in words, the
reference and every severity's physical values. A house that failed under any condition is
left out of every cell of its dataset (one line names it), so every cell holds the same houses.
The output folder is written as a whole (an interrupted command leaves the old set or the new).
"""

from __future__ import annotations

import re
import sys
from collections.abc import Sequence
from pathlib import Path

from benchmark.commands import cli
from benchmark.commands.errors import one_line
from benchmark.paths import CONF_DIR
from benchmark.reports import robustness as rb
from benchmark.reports.formatting import metric_words
from benchmark.reports.tables import load_rows
from envs.atomic import atomic_folder

GEOMETRIC, SANITY, DEFAULT_REFERENCE = rb.GEOMETRIC, rb.SANITY, rb.REFERENCE


def severity_settings(conf_dir: str | Path = CONF_DIR) -> dict[tuple[str, int], str]:
    """(family, severity) -> its physical values, read from ``conf/corruption/<family>_<k>.yaml``
    (each ``key: value  # unit`` line under a stage)."""
    out = {}
    for p in sorted(Path(conf_dir, "corruption").glob("*_[1-9].yaml")):
        family, k = p.stem.rsplit("_", 1)
        parts, stage = [], ""
        for line in p.read_text(encoding="utf-8").splitlines():
            top = re.match(r"^(\w+):\s*$", line)
            if top:
                stage = top.group(1)
                continue
            m = re.match(r"^\s+(\w+):\s*([^#\s]+)\s*(?:#\s*(.*))?$", line)
            if m and stage != "robot":
                unit = (m.group(3) or "").split("(")[0].strip()
                parts.append(f"{stage}.{m.group(1)} {m.group(2)}{(' ' + unit) if unit else ''}")
        out[(family, int(k))] = "; ".join(parts)
    return out


def render(paths: Sequence[str | Path], out: Path | None, metrics: Sequence[str], reference: str,
           last_sweep: bool = False) -> str:
    """The Markdown of every table (and, with ``out``, the files). ``last_sweep``: only the jobs
    of the last multirun into each folder. Raises RobustnessError."""
    from benchmark.harness.store import sweep_scope

    scope = sweep_scope(paths, last_sweep)
    if scope.note:
        print(f"robustness: note: {scope.note}", file=sys.stderr)
    rows = load_rows(scope.files)
    if rows.attrs.get("set_aside"):
        print(f"robustness: {rows.attrs['set_aside']}", file=sys.stderr)
    missing = [c for c in ("corruption", "severity") if c not in rows]
    if missing:
        raise rb.RobustnessError(f"the rows under {[str(p) for p in paths]} have no {missing} column: "
                                 f"run `roomseg-bench experiment=robustness` (conf/corruption) first")
    rows = rows.copy()
    rows["severity"] = rows["severity"].astype(int)
    parts = rb.summarise(rows, metrics, reference)
    settings = severity_settings()
    md = ["# Robustness to robot conditions", "",
          f"Corruption error (CE) and mCE relative to **{reference}** (100 = as robust as it; lower is better); "
          "error = 100 - metric; drop = clean - mean over the family's severities. Metrics in percent, mean over "
          "houses; every cell of a dataset holds the same houses."
          + (f" Runs read: {scope.note}." if scope.note else ""), ""]
    for (dataset, metric), p in parts.items():
        words = metric_words(metric)
        md += [f"## {dataset}: {words}", "", f"{p['houses']} houses per cell"
               + (f"; left out (failed under some condition): {', '.join(p['dropped'])}" if p["dropped"] else "")
               + ".", "", rb.to_markdown(p["table"]), *[f"- {n}" for n in p["notes"]], ""]
        if out is not None:
            stem = f"robustness_{dataset}_{metric}"
            p["table"].round(4).to_csv(out / f"{stem}.csv")
            (out / f"{stem}.tex").write_text(rb.to_latex(p["table"], f"Robustness on {dataset}: {words}, CE relative "
                                                         f"to {reference}", f"tab:{stem}"), encoding="utf-8")
            (out / f"{stem}.md").write_text(rb.to_markdown(p["table"]), encoding="utf-8")
            if metric in ("iou", "matched_iou"):
                for family in rb.FAMILIES:
                    if family in set(p["cells"]["corruption"]):
                        rb.family_figure(p["cells"], family, out / "figures" / f"{stem}_{family}",
                                         words, f"{dataset}: {rb.FAMILY_WORDS[family]}")
    md += ["## Severities", "", "| family | severity | settings |", "|---|---:|---|"]
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
    ap.add_argument("--reference", default=DEFAULT_REFERENCE, help="the method CE is relative to (a method label)")
    ap.add_argument("--metric", action="append", choices=rb.METRICS, help="metric(s) (default: all three)")
    ap.add_argument("--last-sweep", action="store_true",
                    help="only the jobs of the last multirun into each folder (its last_sweep.json)")
    a = ap.parse_args(argv)
    metrics = a.metric or list(rb.METRICS)
    try:
        if a.out is None:
            text = render(a.paths, None, metrics, a.reference, a.last_sweep)
        else:
            with atomic_folder(a.out) as tmp:
                (tmp / "figures").mkdir()
                text = render(a.paths, tmp, metrics, a.reference, a.last_sweep)
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
