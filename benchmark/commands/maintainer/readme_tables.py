"""``python -m benchmark.commands.maintainer.readme_tables``: the README's generated results blocks
(:mod:`benchmark.reports.readme_tables`).

    python -m benchmark.commands.maintainer.readme_tables publish results/runs/bench --name bench [--time FILE]
    python -m benchmark.commands.maintainer.readme_tables publish RUN --name bench --timings DIR   # make bench-publish
    python -m benchmark.commands.maintainer.readme_tables write     # rewrite the blocks of README.md and the docs pages
    python -m benchmark.commands.maintainer.readme_tables check     # exit 1 and name the blocks that differ
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from benchmark.commands import cli
from benchmark.reports.readme_tables import BLOCK_FILES, check, publish, write


def main(argv: Sequence[str] | None = None) -> int:
    ap = cli.ArgumentParser(from_root=True, description="README results blocks from published runs (results/published/)")
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("publish", help="copy a finished run's per-house metrics into results/published/<name>")
    p.add_argument("run_dir", type=Path)
    p.add_argument("--name", required=True, help="published name (e.g. bench)")
    p.add_argument("--time", type=Path, default=None, help="GNU time output, -f '%%e %%M' (wall s, peak KiB)")
    p.add_argument("--compile-time", type=Path, default=None,
                   help="GNU time output of make setup's numba compile step before the run, into an empty numba "
                        "cache (a fresh clone's)")
    p.add_argument("--timings", type=Path, default=None, metavar="DIR",
                   help="repeated fresh-clone runs, one folder each (1/, 2/, ...) holding compile.txt, empty.txt, "
                        "filled.txt (GNU time '%%e %%M') and empty.load, filled.load (/proc/loadavg at each run's "
                        "end), as make bench-publish writes them; the timing block shows their medians and ranges")
    p.add_argument("--command", default="make bench", help="the command that made the run (recorded)")
    p.add_argument("--columns", default=None,
                   help="robustness: keep these columns only, every job's rows in one metrics.csv "
                        "(the robustness benchmark's published run)")
    for name, text in (("write", "rewrite the README's generated blocks"),
                       ("check", "exit 1 when a README block differs from what write would write")):
        q = sub.add_parser(name, help=text)
        q.add_argument("--readme", type=Path, action="append", default=None,
                       help="a file with generated blocks (repeatable); default: " + ", ".join(BLOCK_FILES))
    a = ap.parse_args(argv)
    try:
        if a.cmd == "publish":
            from benchmark.reports.readme_tables import ROBUSTNESS_COLUMNS

            columns = ROBUSTNESS_COLUMNS if a.columns == "robustness" else (a.columns.split(",") if a.columns else None)
            print(publish(a.run_dir, a.name, ".", a.time, a.command, columns, a.compile_time, a.timings))
        elif a.cmd == "write":
            for f in a.readme or [Path(f) for f in BLOCK_FILES]:
                changed = write(f, ".")
                print(f"{f}: " + (f"rewrote {', '.join(changed)}" if changed else "every block up to date"))
        else:
            stale = 0
            for f in a.readme or [Path(f) for f in BLOCK_FILES]:
                changed = check(f, ".")
                if changed:
                    print(f"{f}: block(s) {', '.join(changed)} differ from the published runs; "
                          "run `make readme-tables`", file=sys.stderr)
                    stale += 1
                else:
                    print(f"{f}: every block up to date")
            if stale:
                return 1
    except (FileNotFoundError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
