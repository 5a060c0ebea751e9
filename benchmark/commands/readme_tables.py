"""``python -m benchmark.commands.readme_tables``: the README's generated results blocks
(:mod:`benchmark.reports.readme_tables`).

    python -m benchmark.commands.readme_tables publish results/runs/bench --name bench [--time FILE]
    python -m benchmark.commands.readme_tables write     # rewrite README.md's blocks
    python -m benchmark.commands.readme_tables check     # exit 1 and name the blocks that differ
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from benchmark.reports.readme_tables import check, publish, write


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="README results blocks from published runs (results/published/)")
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("publish", help="copy a finished run's per-house metrics into results/published/<name>")
    p.add_argument("run_dir", type=Path)
    p.add_argument("--name", required=True, help="published name (e.g. bench)")
    p.add_argument("--time", type=Path, default=None, help="GNU time output, -f '%%e %%M' (wall s, peak KiB)")
    p.add_argument("--compile-time", type=Path, default=None,
                   help="GNU time output of make setup's numba compile step before the run, into an empty numba "
                        "cache (a fresh clone's)")
    p.add_argument("--command", default="make bench", help="the command that made the run (recorded)")
    p.add_argument("--columns", default=None,
                   help="robustness: keep these columns only, every job's rows in one metrics.csv "
                        "(the robustness benchmark's published run)")
    for name, text in (("write", "rewrite the README's generated blocks"),
                       ("check", "exit 1 when a README block differs from what write would write")):
        q = sub.add_parser(name, help=text)
        q.add_argument("--readme", type=Path, default=Path("README.md"))
    a = ap.parse_args(argv)
    try:
        if a.cmd == "publish":
            from benchmark.reports.readme_tables import ROBUSTNESS_COLUMNS

            columns = ROBUSTNESS_COLUMNS if a.columns == "robustness" else (a.columns.split(",") if a.columns else None)
            print(publish(a.run_dir, a.name, ".", a.time, a.command, columns, a.compile_time))
        elif a.cmd == "write":
            changed = write(a.readme, ".")
            print(f"{a.readme}: " + (f"rewrote {', '.join(changed)}" if changed else "every block up to date"))
        else:
            changed = check(a.readme, ".")
            if changed:
                print(f"{a.readme}: block(s) {', '.join(changed)} differ from the published runs; "
                      "run `make readme-tables`", file=sys.stderr)
                return 1
            print(f"{a.readme}: every block up to date")
    except (FileNotFoundError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
