"""``python -m benchmark.commands.report RUN_DIR [RUN_DIR ...] --out report.html``: a sweep as
one static HTML page (see :mod:`benchmark.reports.html_report`)."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from benchmark.commands import cli
from benchmark.reports.html_report import HOUSES_PER_DATASET, write_report


def main(argv: Sequence[str] | None = None) -> int:
    ap = cli.ArgumentParser(prog="python -m benchmark.commands.report",
                                 description="a sweep as one static HTML page: configurations (sortable), "
                                 "failures, robustness, and ground truth | raw | post-processed maps of houses of every dataset")
    ap.add_argument("run_dirs", nargs="+", type=Path, help="sweep or job folders (results/runs/<name>)")
    ap.add_argument("--out", type=Path, default=Path("report.html"), help="the HTML file to write")
    ap.add_argument("--house", action="append", default=None, help="house id to draw (repeatable)")
    ap.add_argument("--houses-per-dataset", type=int, default=HOUSES_PER_DATASET,
                    help="houses drawn of every dataset in the run when no --house is given")
    ap.add_argument("--last-sweep", action="store_true",
                    help="only the jobs of the last multirun into each folder (its last_sweep.json), not the job "
                         "folders earlier runs left there")
    a = ap.parse_args(argv)
    try:
        out = write_report(a.run_dirs, a.out, a.house, a.houses_per_dataset, last_sweep=a.last_sweep)
    except (FileNotFoundError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except OSError as e:  # a full disk, a read-only folder: one line naming the file
        from benchmark.harness.write_errors import cannot_write

        print(f"error: {cannot_write(e, a.out)}", file=sys.stderr)
        return 2
    print(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
