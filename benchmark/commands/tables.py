"""``python -m benchmark.commands.tables``: the command-line front of :mod:`benchmark.reports.tables`."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from benchmark.reports.tables import TABLES, render


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("paths", nargs="+", help="run folders or metrics.csv files")
    ap.add_argument("--table", action="append", choices=sorted(TABLES),
                    help="table(s) to make (repeatable; default: every table the rows have data for)")
    ap.add_argument("--out", type=Path, default=None, help="folder for .md/.csv/.tex outputs")
    ap.add_argument("--fraction", action="store_true", help="report fractions instead of percent")
    a = ap.parse_args(argv)
    try:
        text = render(a.paths, a.table, a.out, percent=not a.fraction)
    except (FileNotFoundError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
