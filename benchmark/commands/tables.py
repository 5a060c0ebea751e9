"""``python -m benchmark.commands.tables``: the command-line front of :mod:`benchmark.reports.tables`.

Every ``metrics.csv`` under the given paths is checked first (a truncated or malformed file,
or a share outside [0, 1], is refused with one line naming it), and the rows are grouped by
run (a job's ``run.name``; the folder name for files that are not runner jobs): one run gives
the tables as before; several runs give one section per run (and ``--out DIR/<run>/`` per
run), never one table mixing them. Within a run each (configuration, house) is counted once,
the newest job's row (benchmark.reports.tables.load_rows). What was read, and the
older rows set aside, is said on stderr. A sweep folder that holds jobs its last multirun did
not run (an earlier, larger sweep) is said so on stderr and under every table;
``--last-sweep`` reads the last multirun's jobs alone (what ``make bench`` does). With ``--out``, the set of files is written as a
whole (temporary folder + rename): an interrupted command leaves the old set or the new one,
never a part.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from benchmark.commands import cli
from benchmark.harness.store import METRICS, Job, iter_metric_files, safe_name, sweep_scope
from benchmark.reports.sweep_jobs import partial_sweep_lines
from benchmark.reports.tables import TABLES, load_rows, render
from envs.atomic import atomic_folder


def main(argv: Sequence[str] | None = None) -> int:
    ap = cli.ArgumentParser(prog="python -m benchmark.commands.tables", description=__doc__.split("\n\n")[0])
    ap.add_argument("paths", nargs="+", help="run folders or metrics.csv files")
    ap.add_argument("--table", action="append", choices=sorted(TABLES),
                    help="table(s) to make (repeatable; default: every table the rows have data for)")
    ap.add_argument("--out", type=Path, default=None, help="folder for .md/.csv/.tex outputs")
    ap.add_argument("--fraction", action="store_true", help="report fractions instead of percent")
    ap.add_argument("--last-sweep", action="store_true",
                    help="read only the jobs of the last multirun into each folder (its last_sweep.json), not "
                         "the job folders earlier runs left there")
    a = ap.parse_args(argv)
    try:
        scope = sweep_scope(a.paths, a.last_sweep)
        if scope.note:
            print(f"note: {scope.note}", file=sys.stderr)
        runs = _runs(scope.files)
        rows = {}
        for name, files in runs.items():
            rows[name] = load_rows(files)  # refuses a truncated or malformed file; newest row per house
            where = sorted({str(f.parent.parent if f.parent.parent.name != "runs" else f.parent) for f in files})
            print(f"read run {name!r}: {len(files)} metrics file(s), {rows[name].attrs['n_read']} rows "
                  f"({', '.join(where)[:200]})", file=sys.stderr)
            if rows[name].attrs["set_aside"]:
                print(f"run {name!r}: {rows[name].attrs['set_aside']}", file=sys.stderr)
            for line in partial_sweep_lines(files):  # a sweep whose jobs did not all finish: never read silently
                print(f"run {name!r}: {line}", file=sys.stderr)

        def make(out: Path | None) -> str:
            if len(runs) == 1:
                name, files = next(iter(runs.items()))
                return render(files, a.table, out, percent=not a.fraction, rows=rows[name], scope_note=scope.note)
            return "\n".join(f"## Run {name}\n\n" + render(files, a.table, out / safe_name(name) if out else None,
                                                              percent=not a.fraction, rows=rows[name],
                                                              scope_note=scope.note)
                             for name, files in runs.items())

        if a.out is None:
            text = make(None)
        else:
            with atomic_folder(a.out) as tmp:
                text = make(tmp)
    except (FileNotFoundError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        from benchmark.harness.write_errors import cannot_write

        print(f"error: {cannot_write(e, a.out)}", file=sys.stderr)
        return 2
    print(text)
    return 0


def _runs(paths: Sequence[str | Path]) -> dict[str, list[Path]]:
    """The metrics files under ``paths`` grouped by run, in the order first found."""
    out: dict[str, list[Path]] = {}
    files = list(iter_metric_files(paths))
    if not files:
        raise FileNotFoundError(f"no metrics.csv under {[str(p) for p in paths]}")
    for f in files:
        name = Job(f.parent).run_name() if f.name == METRICS else f.stem
        out.setdefault(name, []).append(f)
    return out


if __name__ == "__main__":
    raise SystemExit(main())
