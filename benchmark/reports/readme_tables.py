"""README results that cannot go stale: blocks between markers, written from published runs.

The README holds each generated block between two markers::

    <!-- BEGIN generated: bench-table4 (make readme-tables; do not edit) -->
    ...
    <!-- END generated: bench-table4 -->

:data:`BLOCKS` says what each block shows and which published run it reads. A published
run is a copy of a sweep's per-house ``metrics.csv`` files (timing columns dropped) under
``results/published/<name>/`` with ``provenance.json`` (command, date, machine, wall time,
peak memory, commit), committed so that the blocks can be regenerated, and checked by
``tests/test_readme_tables.py``, without running the sweep. Commands::

    python -m benchmark.commands.maintainer.readme_tables publish results/runs/bench --name bench [--time FILE]
    python -m benchmark.commands.maintainer.readme_tables write      # README.md blocks from results/published
    python -m benchmark.commands.maintainer.readme_tables check      # exit 1 when a block differs
"""

from __future__ import annotations

import json
import platform
import re
import shutil
import subprocess
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from benchmark.reports import formatting

#: where published runs live, relative to the repository root.
PUBLISHED = Path("results/published")
PROVENANCE = "provenance.json"

_BEGIN = re.compile(r"<!-- BEGIN generated: ([A-Za-z0-9_.-]+)[^>]*-->\n(.*?)<!-- END generated: \1 -->", re.S)


@dataclass(frozen=True)
class Block:
    """One README block: a table of :data:`benchmark.reports.tables.TABLES` (``table``) over
    the published runs ``sources``, or, with ``table`` None, the timing line of ``sources[0]``."""

    name: str
    sources: tuple[str, ...]
    table: str | None = None


BLOCKS: dict[str, Block] = {b.name: b for b in (
    Block("bench-timing", ("bench",)),
    Block("bench-table4", ("bench",), "table4"),
    Block("bench-table3", ("bench",), "table3"),
    Block("robustness-timing", ("robustness",)),
    Block("robustness", ("robustness",), "robustness"),
    Block("robustness-power", ("robustness",), "robustness-power"),
)}
#: the files whose generated blocks ``make readme-tables`` writes: the README (timings, bench
#: tables, the robustness run's power report) and the robustness page (its full tables, too
#: long for the README).
BLOCK_FILES = ("README.md", "docs/index.md", "docs/robustness.md")

#: the columns a published robustness run keeps (one ``metrics.csv`` of every job's rows: 12,480
#: rows for 20 houses per dataset; the rest of each row is in the run's own folders).
ROBUSTNESS_COLUMNS = ("house_id", "dataset", "env", "viewpoints", "classifier", "oracle_accuracy", "aggregator",
                      "postprocess", "segmenter", "corruption", "severity", "status", "iou", "matched_iou", "pq",
                      "accuracy", "coverage_area", "coverage_rooms", "pose_error_mean_m", "label_noise_share",
                      "map_free_iou")


def machine() -> str:
    """This machine in words: CPU model and count, memory, OS (e.g. ``AMD EPYC, 2 cores,
    23 GiB, Linux 6.1``)."""
    import os

    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        cpu = platform.processor()
    mem = ""
    try:
        kb = int(next(ln for ln in Path("/proc/meminfo").read_text().splitlines()
                      if ln.startswith("MemTotal")).split()[1])
        mem = f", {kb / 2**20:.0f} GiB"
    except (OSError, StopIteration, ValueError):
        pass
    return f"{cpu or 'unknown CPU'}, {os.cpu_count()} cores{mem}, {platform.system()} {platform.release().split('-')[0]}"


def head_commit(root: Path) -> str:
    """The short hash of ``root``'s checked-out commit ('' outside a git checkout)."""
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True,
                              timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def measured_line(module: str, args: list[str]) -> str:
    """``Measured on DATE on MACHINE at commit C by `python -m MODULE ARGS`.``: the first line
    of a published measurement (``results/published/*.md``, included by the docs as it is)."""
    import datetime
    import shlex

    commit = head_commit(Path(__file__).resolve().parents[2])
    return (f"Measured on {datetime.date.today().isoformat()} on {machine()}"
            f"{f' at commit {commit}' if commit else ''} by "
            f"`python -m {module} {' '.join(shlex.quote(x) for x in args)}`.")


def publish(run_dir: str | Path, name: str, root: str | Path = ".", time_file: str | Path | None = None,
            command: str = "make bench", columns: Sequence[str] | None = None,
            compile_time_file: str | Path | None = None, timings_dir: str | Path | None = None) -> Path:
    """Copy a finished run's per-house metrics into ``<root>/results/published/<name>/``.

    Each job's ``metrics.csv`` keeps its relative folder and every column but the stage
    timings (``t_*``, which differ run to run). With ``columns``, every job's rows go into one
    ``metrics.csv`` with those columns only (a large sweep: the robustness benchmark). ``provenance.json`` records ``command``,
    the UTC date, :func:`machine`, the commit and, from ``time_file`` (GNU time's
    ``-f "%e %M"``: wall seconds and peak RSS in KiB), the wall time and peak memory; from
    ``compile_time_file`` (the same format), the seconds ``make setup``'s numba compile step took
    into an empty numba cache before the run (the run then timed as on a fresh clone); from
    ``timings_dir``, the repeated fresh-clone runs of ``make bench-publish``
    (:func:`read_timings`), whose medians, ranges and load averages the timing block shows.

    Returns:
        the published folder (replaced whole).

    Raises:
        FileNotFoundError: no finished job under ``run_dir``.
        ValueError: an unreadable ``time_file``, or a job's rows that fail the checks of
            :func:`benchmark.reports.tables.read_rows` (one line naming the file).
    """
    from benchmark.harness.cache import atomic_write_json
    from benchmark.harness.store import find_jobs
    from benchmark.reports.tables import ROW_SOURCE_COLUMNS, read_rows

    run_dir, root = Path(run_dir), Path(root)
    timings = read_timings(timings_dir) if timings_dir is not None else None  # read before anything is written
    jobs = find_jobs([run_dir])
    dest = root / PUBLISHED / name
    tmp = dest.with_name(f".{name}.tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    frames = []
    for job in jobs:
        df = read_rows(job.metrics_path).drop(columns=list(ROW_SOURCE_COLUMNS))  # checked as every reader checks
        df = df[[c for c in df.columns if not c.startswith("t_")]]
        if columns is not None:
            frames.append(df.reindex(columns=list(columns)))
            continue
        rel = job.dir.relative_to(run_dir) if job.dir != run_dir else Path(".")
        (tmp / rel).mkdir(parents=True, exist_ok=True)
        df.to_csv(tmp / rel / "metrics.csv", index=False)
    if columns is not None:
        tmp.mkdir(parents=True, exist_ok=True)
        pd.concat(frames, ignore_index=True).to_csv(tmp / "metrics.csv", index=False)
    import os

    prov = {"command": command, "run": str(run_dir), "date_utc": time.strftime("%Y-%m-%d", time.gmtime()),
            "machine": machine(), "commit": head_commit(root), "jobs": len(jobs)}
    if hasattr(os, "getloadavg"):  # the load while it ran, its own workers included (5-minute load average at the end)
        prov["load_avg_5min"] = round(os.getloadavg()[1], 1)
    if time_file is not None:
        wall, rss_kb = gnu_time(time_file)
        prov["wall_s"], prov["peak_rss_mb"] = round(wall, 1), round(rss_kb / 1024)
    if compile_time_file is not None:
        prov["numba_compile_s"] = round(gnu_time(compile_time_file)[0], 1)
    if timings is not None:
        prov["timings"] = timings
    atomic_write_json(tmp / PROVENANCE, prov)
    shutil.rmtree(dest, ignore_errors=True)
    tmp.rename(dest)
    return dest


def gnu_time(path: str | Path) -> tuple[float, int]:
    """(wall seconds, peak RSS KiB) from GNU time's ``-f "%e %M"`` output; ValueError naming the file."""
    try:
        wall, rss_kb = Path(path).read_text().split()[-2:]
        return float(wall), int(rss_kb)
    except (OSError, ValueError) as e:
        raise ValueError(f"{path}: expected GNU time's '%e %M' (seconds, KiB), got an error: {e}") from None


def gnu_time_cpu(path: str | Path) -> tuple[float, int, float]:
    """(wall seconds, peak RSS KiB, CPU seconds: user + system) from GNU time's ``-f "%e %M %U %S"``
    output; ValueError naming the file."""
    try:
        wall, rss_kb, user, system = Path(path).read_text().split()[-4:]
        return float(wall), int(rss_kb), float(user) + float(system)
    except (OSError, ValueError) as e:
        raise ValueError(f"{path}: expected GNU time's '%e %M %U %S' (seconds, KiB, CPU seconds), "
                         f"got an error: {e}") from None


#: the two timed ``make bench`` runs of each fresh-clone repetition of ``make bench-publish``: into an
#: empty results folder (stage cache empty), then again into the same folder (its cache filled).
TIMING_CASES = ("empty", "filled")


def _load_averages(path: Path) -> tuple[float, float]:
    """(1-minute, 5-minute) load average from a copy of ``/proc/loadavg``; ValueError naming the file."""
    try:
        one, five = Path(path).read_text().split()[:2]
        return float(one), float(five)
    except (OSError, ValueError) as e:
        raise ValueError(f"{path}: expected a copy of /proc/loadavg (1-, 5- and 15-minute load averages), "
                         f"got an error: {e}") from None


def read_timings(folder: str | Path) -> dict:
    """The repeated fresh-clone timings of ``make bench-publish`` under ``folder``: one subfolder
    per repetition (``1``, ``2``, ...), each holding ``compile.txt`` (``make setup``'s kernel
    compile step into an empty numba cache), ``empty.txt`` and ``filled.txt`` (GNU time's
    ``%e %M`` of ``make bench`` into an empty results folder, then again with its cache
    filled) and ``empty.load`` / ``filled.load`` (``/proc/loadavg`` as each ended).

    Returns:
        ``{"runs": n, "compile_s": [...], "empty": {"wall_s": [...], "peak_rss_mb": [...],
        "load_1min": [...], "load_5min": [...]}, "filled": {...}}``, each list in repetition order.

    Raises:
        ValueError: no repetition folder, or a file missing or malformed (one line naming it).
    """
    folder = Path(folder)
    reps = sorted((d for d in folder.iterdir() if d.is_dir()), key=lambda d: (not d.name.isdigit(),
                  int(d.name) if d.name.isdigit() else 0, d.name)) if folder.is_dir() else []
    if not reps:
        raise ValueError(f"--timings {folder}: no run folders in it; expected one folder per timed run "
                         "(1/, 2/, ...) as make bench-publish writes them")
    out: dict = {"runs": len(reps), "compile_s": []}
    for case in TIMING_CASES:
        out[case] = {"wall_s": [], "peak_rss_mb": [], "load_1min": [], "load_5min": []}
    for d in reps:
        out["compile_s"].append(round(gnu_time(d / "compile.txt")[0], 1))
        for case in TIMING_CASES:
            wall, rss_kb = gnu_time(d / f"{case}.txt")
            one, five = _load_averages(d / f"{case}.load")
            got = out[case]
            got["wall_s"].append(round(wall, 1))
            got["peak_rss_mb"].append(round(rss_kb / 1024))
            got["load_1min"].append(one)
            got["load_5min"].append(five)
    return out


def _median_range(values: Sequence[float], fmt: str, unit: str = "") -> tuple[str, str]:
    """(the median, ``lo-hi`` or ``""`` for one value), each formatted with ``fmt`` and ``unit``."""
    import statistics

    med = format(statistics.median(values), fmt) + unit
    lo, hi = format(min(values), fmt), format(max(values), fmt)
    return med, ("" if len(values) < 2 else f"{lo}-{hi}{unit}")


def timings_line(p: dict) -> str:
    """The timing block of a provenance with repeated fresh-clone runs (``p["timings"]``, from
    :func:`read_timings`): per case the median wall time, peak RSS and 1-minute load average
    at the run's end, each with its range over the runs."""
    t = p["timings"]
    n = t["runs"]

    def stat(values: Sequence[float], fmt: str, unit: str = "") -> str:
        med, span = _median_range(values, fmt, unit)
        return f"{med} ({span})" if span else med

    cases = []
    for case, words in zip(TIMING_CASES, ("from an empty cache", "again, its cache filled,")):
        c = t[case]
        cases.append(f"**{words} {stat(c['wall_s'], '.0f', ' s')} wall**, {stat(c['peak_rss_mb'], '.0f', ' MB')} "
                     f"peak RSS, load {stat(c['load_1min'], '.1f')}")
    commit = f" at commit {p['commit']}" if p.get("commit") else ""
    times = f"{n} times" if n > 1 else "once"
    medians = f"Medians over the {n} runs, their ranges in parentheses" if n > 1 else "One run"
    return (f"Measured with `/usr/bin/time` on {p['date_utc']} on {p['machine']}{commit}: `{p['command']}` "
            f"({p['jobs']} configurations) as on a fresh clone, {times} (numba's cache empty, then `make setup`'s "
            f"kernel compile step: {stat(t['compile_s'], '.0f', ' s')}), each time twice: {cases[0]}; {cases[1]}. "
            f"{medians}; load: the 1-minute load average as the run ended, its own workers included.\n")


def provenance(root: str | Path, name: str) -> dict:
    """A published run's provenance (FileNotFoundError naming how to publish it)."""
    p = Path(root) / PUBLISHED / name / PROVENANCE
    if not p.exists():
        raise FileNotFoundError(f"{p} is missing: publish the run first "
                                f"(python -m benchmark.commands.maintainer.readme_tables publish results/runs/{name} --name {name})")
    return json.loads(p.read_text(encoding="utf-8"))


def _source_line(root: Path, sources: Sequence[str]) -> str:
    provs = [provenance(root, s) for s in sources]
    p = provs[0]
    where = ", ".join(f"`{(PUBLISHED / s).as_posix()}`" for s in sources)
    return f"Source: {where} (`{p['command']}` on {p['date_utc']}, commit {p.get('commit') or '?'})."


def render_block(block: Block, root: str | Path = ".") -> str:
    """The Markdown of one block (ends with a newline).

    Raises:
        FileNotFoundError: a published run the block reads is missing.
    """
    from benchmark.reports.tables import (
        TABLES,
        format_cells,
        load_rows,
        metric_notes,
        split_rank_notes,
        summarise,
        why_empty,
    )

    root = Path(root)
    if block.table is None:
        p = provenance(root, block.sources[0])
        if "timings" in p:
            return timings_line(p)
        if "wall_s" not in p:
            return (f"Not timed: `{p['command']}` was published without a time file "
                    f"(on {p['date_utc']}, {p['machine']}).\n")
        load = (f"; 5-minute load average {p['load_avg_5min']:g} at its end, its own workers included"
                if "load_avg_5min" in p else "")
        numba = (f"; as on a fresh clone: numba's cache empty before `make setup`, whose kernel compile step "
                 f"took {p['numba_compile_s']:.0f} s" if "numba_compile_s" in p else "")
        return (f"Measured with `/usr/bin/time` on {p['date_utc']} on {p['machine']} (after `make setup`): "
                f"`{p['command']}` took **{p['wall_s']:.0f} s wall, {p['peak_rss_mb']} MB peak RSS** "
                f"({p['jobs']} configurations, from an empty cache{load}{numba}).\n")
    paths = [root / PUBLISHED / s for s in block.sources]
    for s in block.sources:
        provenance(root, s)  # a missing published run: one line saying how to publish it
    if block.table in ("robustness", "robustness-power"):
        return _robustness_block(root, paths, block.sources, power_only=block.table == "robustness-power")
    df = load_rows(paths)
    spec = TABLES[block.table]
    summ = summarise(df, spec)
    reason = why_empty(df, block.table, summ)
    if summ.empty:
        return f"({spec.title}: no rows, {reason}.)\n"
    grid = format_cells(summ, spec, True, block.table)
    notes = metric_notes(df)
    text, ranks = split_rank_notes(grid.notes)
    return (formatting.to_markdown(grid) + "\n\n" + f"{grid.legend}, in percent. " + text
            + (" Metrics: " + "; ".join(notes) + "." if notes else "") + " " + _source_line(root, block.sources) + "\n"
            + "".join(f"\n- {r}" for r in ranks) + ("\n" if ranks else ""))


def _severity_span(cells) -> str:
    """The severities the conditions average over, in words: ``1-5`` where every family has 1..5,
    else each family's span (``1-5; lost 1-3; kidnap 1-2``: the families beyond the common one)."""
    spans = {f: (int(g.min()), int(g.max())) for f, g in
             cells.loc[(cells["corruption"] != "clean") & (cells["severity"] > 0)].groupby("corruption")["severity"]}
    if not spans:
        return "1-5"
    common = max(set(spans.values()), key=lambda x: (list(spans.values()).count(x), x))
    odd = [f"{f} {a}-{b}" for f, (a, b) in spans.items() if (a, b) != common]
    return "; ".join([f"{common[0]}-{common[1]}", *odd])


def _robustness_block(root: Path, paths: Sequence[Path], sources: Sequence[str], power_only: bool = False) -> str:
    """Per dataset: matched IoU clean and under each condition (mean over its severities) with
    its 95 % interval, mCE and relative mCE against a reference every family degrades
    (``realistic`` apart), and what the intervals support in words (rankings in groups no
    paired interval separates; where the best view-based and the best geometric method are
    ahead, tied or change places); the curves that rise with severity beyond chance; the power
    report (how many houses 3 points need; the smallest difference this run detects); the table
    of the authors' ipa_room_segmentation beside the ports, on its houses of its own, where the
    run has those rows (:func:`benchmark.reports.robustness.apart_lines`); with ``power_only``,
    the power report alone (the README's block)."""
    from benchmark.reports import robustness as rb
    from benchmark.reports.tables import load_rows
    from benchmark.stats import METHOD_WORDS

    df = load_rows(paths)
    df["severity"] = df["severity"].astype(int)
    expected, unrecorded = rb.expected_severities(paths)  # a published copy: every severity conf/corruption defines
    parts = rb.summarise(df, ("matched_iou", "pq"), "auto", expected, unrecorded=unrecorded)
    out, power = [], []
    for dataset in sorted({d for d, _ in parts}):
        p, pq = parts[(dataset, "matched_iou")], parts[(dataset, "pq")]
        t = p["table"]
        ranked = [m for m in t.index if m not in rb.SANITY]  # sanity rows: docs
        fams = [f for f in rb.FAMILIES if f in t.columns and f not in rb.APART]
        comp = [f for f in rb.FAMILIES if f in t.columns and f in rb.APART]
        cols = ["clean", *fams, "mCE", "rel mCE", *comp]
        labels = {**{f: rb.FAMILY_WORDS[f] for f in fams},
                  **{f: rb.FAMILY_WORDS[f] if f in rb.ABLATION else f"{f} (apart)" for f in comp}}
        ref = p["reference"]
        pq_lines = [n for n in pq["notes"] if n.startswith(("mCE", "rel mCE"))]
        sig = p["curves"][p["curves"]["significant"]] if len(p["curves"]) else p["curves"]
        n_rise = p["curves"][["method", "family"]].drop_duplicates().shape[0] if len(p["curves"]) else 0
        out += [f"**{formatting.value_label('dataset', dataset)}** ({p['houses']} houses per cell; matched IoU in "
                f"percent, mean [95 % interval], conditions averaged over their severities {_severity_span(p['cells'])}; "
                f"mCE and relative mCE relative to {ref or 'no method (none is degraded by every family)'}, lower is "
                f"better; `realistic` combines the others and is in neither mean"
                + ("".join(f"; `{f}` is a labelled condition (each severity a situation of its own), apart too"
                           for f in comp if f in rb.LABELLED))
                + ("".join(f"; `{f}` is an ablation ({rb.FAMILY_WORDS[f]}: the map stays at the true poses), apart too"
                           for f in comp if f in rb.ABLATION)) + "):",
                "", rb.to_markdown(t.loc[ranked], columns=cols, labels=labels).rstrip(), "",
                *[f"- {x}" for x in p["notes"]], *[f"- PQ {x}" for x in pq_lines],
                f"- Curves that rise with severity: {n_rise} of {len(ranked) * len(fams + comp)} method x condition "
                f"curves rise somewhere; "
                + (f"{len(sig)} step(s) with a paired interval above zero: " + "; ".join(
                    f"{r.method} / {rb.FAMILY_WORDS.get(r.family, r.family)} {r.step} +{r.rise:.1f} "
                    f"[{r.lo:+.1f}, {r.hi:+.1f}]" for r in sig.itertuples()) if len(sig) else "none beyond noise")
                + ".", ""]
        if p.get("apart") is not None:  # the authors' ipa_room_segmentation, on houses of its own
            out += rb.apart_lines(p["apart"], "matched IoU in percent, mean [95 % interval]")
        power += rb.power_lines(formatting.value_label("dataset", dataset), p["power"], "matched IoU")
    houses = ["**How many houses** (paired differences of two methods under one condition; "
              f"{METHOD_WORDS}):", "", *[f"- {x}" for x in power], ""]
    out = houses if power_only else out + houses
    return "\n".join(out) + _source_line(root, sources) + "\n"


def blocks_in(text: str) -> dict[str, str]:
    """name -> current content of every generated block in ``text``.

    Raises:
        ValueError: a block named twice, or a BEGIN marker without its END."""
    found: dict[str, str] = {}
    for m in _BEGIN.finditer(text):
        if m.group(1) in found:
            raise ValueError(f"README block {m.group(1)!r} appears twice")
        found[m.group(1)] = m.group(2)
    begins = re.findall(r"<!-- BEGIN generated: ([A-Za-z0-9_.-]+)", text)
    unmatched = [b for b in begins if b not in found]
    if unmatched:
        raise ValueError(f"README block {unmatched[0]!r} has no '<!-- END generated: {unmatched[0]} -->' marker")
    return found


def update_text(text: str, root: str | Path = ".") -> tuple[str, list[str]]:
    """``text`` with every generated block rewritten; also the names of blocks that changed.

    Raises:
        ValueError: a block name not in :data:`BLOCKS`, or malformed markers."""
    current = blocks_in(text)
    unknown = [n for n in current if n not in BLOCKS]
    if unknown:
        raise ValueError(f"README block {unknown[0]!r} is not one of {sorted(BLOCKS)}")
    changed = []

    def sub(m: re.Match) -> str:
        name = m.group(1)
        new = render_block(BLOCKS[name], root)
        if new != m.group(2):
            changed.append(name)
        whole, a, b = m.group(0), m.start(2) - m.start(0), m.end(2) - m.start(0)
        return whole[:a] + new + whole[b:]

    return _BEGIN.sub(sub, text), changed


def check(readme: str | Path = "README.md", root: str | Path = ".") -> list[str]:
    """Names of the README blocks that differ from what :func:`update_text` writes."""
    return update_text(Path(readme).read_text(encoding="utf-8"), root)[1]


def write(readme: str | Path = "README.md", root: str | Path = ".") -> list[str]:
    """Rewrite the README's blocks in place (atomically); returns the names that changed."""
    import os

    from benchmark.harness.cache import atomic_write_text

    readme = Path(readme)
    new, changed = update_text(readme.read_text(encoding="utf-8"), root)
    if changed:
        mode = readme.stat().st_mode & 0o777
        atomic_write_text(readme, new)
        os.chmod(readme, mode)
    return changed


__all__ = ["BLOCKS", "Block", "PUBLISHED", "publish", "provenance", "gnu_time", "gnu_time_cpu", "head_commit", "render_block",
           "blocks_in", "update_text", "check", "write", "machine", "read_timings", "timings_line"]
