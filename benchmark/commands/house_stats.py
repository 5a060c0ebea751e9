"""``python -m benchmark.commands.house_stats``: the command-line front of :mod:`benchmark.reports.house_stats`."""

from __future__ import annotations

import time
from pathlib import Path

import pandas as pd

from benchmark.commands import cli
from benchmark.paths import procthor_houses
from benchmark.reports.house_stats import grid_figure, stats
from envs.datasets.house_files import load_houses


def main(argv: list[str] | None = None) -> int:
    from envs.datasets.synthetic import generate_house

    default = procthor_houses()
    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("--synthetic", type=int, default=200, help="number of generated houses (seeds 0..N-1)")
    ap.add_argument("--procthor", type=Path, default=default)
    ap.add_argument("--figure", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the table to this Markdown file, headed by the command that made it "
                         "(make docs-numbers: results/published/house_stats.md, which docs/houses.md includes)")
    a = ap.parse_args(argv)
    t = time.perf_counter()
    synth = [generate_house(s) for s in range(a.synthetic)]
    ms = 1e3 * (time.perf_counter() - t) / max(a.synthetic, 1)
    table = {"synthetic": stats(synth)}
    if a.procthor.exists():
        table["ProcTHOR (shared)"] = stats(load_houses(a.procthor))
    md = pd.DataFrame(table).to_markdown()
    print(md)
    if a.out is not None:
        import sys

        from benchmark.reports.published import write_published

        command = f"python -m benchmark.commands.house_stats --synthetic {a.synthetic}"
        if a.procthor != default:
            command += f" --procthor {a.procthor}"
        err = write_published(a.out, f"{command} --out {a.out}", md)
        if err:
            print(f"error: {err}", file=sys.stderr)
            return 2
    print(f"\ngeneration: {ms:.2f} ms per house (mean over {a.synthetic} seeds)")
    if a.figure:
        grid_figure(synth[:8], a.figure)
        print(a.figure)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
