"""``python -m benchmark.commands.figures``: the command-line front of :mod:`benchmark.reports.figures`."""

from __future__ import annotations

import argparse
from pathlib import Path

from benchmark.reports.figures import fig3, fig4, from_run, house_figures


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="the paper's figures (Fig. 3, Fig. 4) from the runner's caches")
    sub = ap.add_subparsers(dest="cmd", required=True)
    helps = {"fig3": "ground truth | raw | post-processed for one house",
             "fig4": "ground truth + viewpoints | graph KNN | vision cone for one house",
             "house": "Fig. 2, 3, 4 and one view's cone for one house into a folder"}
    for name, text in helps.items():
        p = sub.add_parser(name, help=text, description=text + "; trailing key=value arguments are Hydra "
                           "overrides of conf/ (e.g. classifier=objects env.resolution=0.02 run.results_dir=...)")
        p.add_argument("--house-index", type=int, default=80, help="position of the house in the env")
        default_out = "docs/figures" if name == "house" else f"results/figures/{name}.png"
        p.add_argument("--out", type=Path, default=Path(default_out), help="PNG path (house: a folder)")
        if name == "fig4":
            p.add_argument("--max-poses", type=int, default=60, help="viewpoints drawn on the first panel")
        p.add_argument("overrides", nargs="*", help="Hydra overrides, key=value")
    r = sub.add_parser("from-run", help="Fig. 3 and 4 for every configuration of a finished sweep's cached maps")
    r.add_argument("run_dir", type=Path)
    r.add_argument("--house", default=None)
    r.add_argument("--out", type=Path, default=Path("results/figures"))
    a = ap.parse_args(argv)
    try:
        if a.cmd == "fig3":
            paths = [fig3(a.house_index, a.out, a.overrides)]
        elif a.cmd == "fig4":
            paths = [fig4(a.house_index, a.out, a.overrides, a.max_poses)]
        elif a.cmd == "house":
            paths = house_figures(a.house_index, a.out, a.overrides)
        else:
            paths = from_run(a.run_dir, a.out, a.house)
    except (ValueError, FileNotFoundError, RuntimeError) as e:
        print(f"error: {e}")
        return 2
    for p in paths:
        print(p)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
