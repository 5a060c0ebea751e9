"""``python -m benchmark.commands.figures``: the command-line front of :mod:`benchmark.reports.figures`."""

from __future__ import annotations

import sys
from pathlib import Path

from benchmark.commands import cli
from benchmark.reports.figures import fig3, fig4, from_run, house_figures
from benchmark.reports.plotting import parse_formats


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(from_root=True, description="the paper's figures (Fig. 2, 3, 4) from the runner's caches")
    sub = ap.add_subparsers(dest="cmd", required=True)
    helps = {"fig3": "ground truth | raw | post-processed for one house",
             "fig4": "ground truth + viewpoints | graph KNN | vision cone for one house",
             "house": "Fig. 2, 3, 4 and one view's cone for one house into a folder"}
    fmt_help = "comma-separated file formats: png, pdf, svg (default png)"
    for name, text in helps.items():
        p = sub.add_parser(name, help=text, description=text + "; trailing key=value arguments are Hydra "
                           "overrides of conf/ (e.g. classifier=objects env.resolution=0.02 run.results_dir=...)")
        p.add_argument("--house-index", type=int, default=80, help="position of the house in the env")
        default_out = "results/figures/house" if name == "house" else f"results/figures/{name}.png"
        p.add_argument("--out", type=Path, default=Path(default_out),
                       help="file path (its suffix is replaced by each --format); house: a folder")
        p.add_argument("--format", default=None, help=fmt_help)
        if name == "fig4":
            p.add_argument("--max-poses", type=int, default=60, help="viewpoints drawn on the first panel")
        p.add_argument("overrides", nargs="*", help="Hydra overrides, key=value")
    r = sub.add_parser("from-run", help="Fig. 3 and 4 for every configuration of a finished sweep's saved maps")
    r.add_argument("run_dir", type=Path)
    r.add_argument("--house", action="append", default=None,
                   help="house id to draw (repeatable; default: the first house every job scored)")
    r.add_argument("--out", type=Path, default=Path("results/figures"))
    r.add_argument("--format", default=None, help=fmt_help)
    r.add_argument("--last-sweep", action="store_true",
                   help="only the jobs of the last multirun into the folder (its last_sweep.json)")
    r.add_argument("--jobs", type=int, default=None,
                   help="figures drawn at once in worker processes (default ROOMSEG_JOBS, else the cores this process may run on)")
    a = ap.parse_args(argv)
    try:
        formats = parse_formats(a.format) if a.format else None
        if a.cmd == "fig3":
            paths = fig3(a.house_index, a.out, a.overrides, formats)
        elif a.cmd == "fig4":
            paths = fig4(a.house_index, a.out, a.overrides, a.max_poses, formats)
        elif a.cmd == "house":
            paths = house_figures(a.house_index, a.out, a.overrides, formats)
        else:
            # the set is replaced as a whole: a run killed mid-way leaves the old figures, never a mix
            from envs.atomic import atomic_folder

            with atomic_folder(a.out) as tmp:
                paths = from_run(a.run_dir, tmp, a.house, formats, a.jobs, last_sweep=a.last_sweep)
                if not paths:
                    raise FileNotFoundError(f"no saved maps to draw in {a.run_dir} (run with run.save_maps=true)")
            paths = [a.out / p.relative_to(tmp) for p in paths]
    except (ValueError, FileNotFoundError, RuntimeError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except OSError as e:  # a full disk, a read-only folder: one line naming the file
        from benchmark.harness.write_errors import cannot_write

        print(f"error: {cannot_write(e, a.out)}", file=sys.stderr)
        return 2
    for p in paths:
        print(p)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
