"""``python -m benchmark.commands.selros`` (also ``python -m benchmark.commands.baselines table5``):
Table V on the SeLRoS release: the SeLRoS and VRF outputs (presets conf/scoring/external/selros.yaml,
vrf.yaml), the geometric baselines run on each map's occupancy image, and the sanity rows,
all scored against the release's ground truth.

    python -m benchmark.commands.selros [--data DIR] [--resolution 0.02] [--out DIR] [--no-geometric]
        [--occupancy-dir DIR --occupancy-pattern '{id}_map.png'] [metrics.key=value ...]
        [--rose2 CHECKOUT] [--ipa [ALGORITHMS]] [--method NAME=DIR ... --method-pattern '{id}.png']
        [--markdown FILE.md]

``--rose2`` adds a ROSE² row run here (``make rose2-env``), ``--ipa`` the rows of
ipa_room_segmentation's algorithms run here (``make ipa-env``; VRF beside the row scored from the
release's VRF outputs); ``--method`` puts your own method's
maps (a folder of instance-coloured PNGs, one per map) in the same table: one command, one
Table V (``table5.md``, ``.csv``, ``.tex`` with ``--out``). ``--markdown FILE`` writes the table
headed by the command that made it (``make docs-numbers``: ``results/published/selros_table5.md``).

Map ids come from the ground-truth file names by the rule ``--gt-pattern`` (default
``{id}_ground_truth.png``: ``office_a_ground_truth.png`` is ``office_a``). Trailing
``metrics.*`` arguments are Hydra overrides of the shared ``metrics`` group (e.g.
``metrics.connectivity=8 metrics.min_segment_m2=0.05``).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pandas as pd

from benchmark.commands import cli


def compose_score(overrides: list[str]):
    """conf/scoring/score.yaml composed with Hydra ``overrides`` (no app run)."""
    from benchmark.config import compose

    return compose("score", overrides)


def _quote(v) -> str:
    """A value as a quoted Hydra override string (braces, spaces and commas stay literal)."""
    return "'" + str(v).replace("\\", "\\\\").replace("'", "\\'") + "'"


def main(argv: list[str] | None = None) -> int:
    from hydra.utils import instantiate

    from benchmark.baselines.external import MapSample, _glob_ids, failures, report, summary_table
    from benchmark.baselines.selros import (
        GT_FOLDER,
        GT_PATTERN,
        OCCUPANCY_FOLDER,
        OCCUPANCY_PATTERN,
        default_selros_dir,
        geometric_rows,
    )

    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=None, help="the SeLRoS release folder (default: shared data)")
    ap.add_argument("--resolution", type=float, default=None, help="metres per pixel (default: the presets', 0.02)")
    ap.add_argument("--gt-pattern", default=GT_PATTERN, help="ground-truth file rule with {id}")
    ap.add_argument("--occupancy-dir", type=Path, default=None,
                    help=f"occupancy maps for the geometric baselines (default: DATA/{OCCUPANCY_FOLDER})")
    ap.add_argument("--occupancy-pattern", default=None, help=f"their file rule (default {OCCUPANCY_PATTERN})")
    ap.add_argument("--no-geometric", action="store_true", help="leave out the geometric baselines")
    ap.add_argument("--method", action="append", default=[], metavar="NAME=DIR",
                    help="another method's maps to score beside them (instance-coloured PNGs named by "
                         "--method-pattern; repeatable), e.g. --method mine=results/my_maps")
    ap.add_argument("--method-pattern", default="{id}.png", help="file rule of --method maps (default {id}.png)")
    ap.add_argument("--rose2", default=os.environ.get("ROOMSEG_ROSE2"),
                    help="a ROSE2 checkout: add its row, run here (make rose2-env; default $ROOMSEG_ROSE2)")
    ap.add_argument("--rose2-python", default=None, help="the ROSE2 environment's python (default .venv-rose2)")
    ap.add_argument("--ipa", nargs="?", const="all", default=None, metavar="ALGORITHMS",
                    help="add ipa_room_segmentation's rows (the authors' C++, run here from the make ipa-env build): "
                         "all (the default) or a comma list of morphological,distance,voronoi,semantic,vrf")
    ap.add_argument("--no-sanity", action="store_true", help="leave out one_room, gt_geometry and grid")
    ap.add_argument("--out", type=Path, default=None,
                    help="folder for metrics.csv, table5.md/.csv/.tex and table5.html (written as a set)")
    ap.add_argument("--page-maps", type=int, default=3, help="maps drawn on table5.html (default 3)")
    ap.add_argument("--markdown", type=Path, default=None,
                    help="also write the table and its notes to this Markdown file, headed by the command that "
                         "made it, with a line naming the ROSE2 commit of its ROSE² row (make docs-numbers: "
                         "results/published/selros_table5.md, which docs/baselines.md includes)")
    a, rest = ap.parse_known_args(argv)
    bad = [r for r in rest if not r.startswith("metrics.")]
    if bad:
        print(f"error: unknown arguments {bad}; metric options are Hydra overrides like metrics.connectivity=8",
              file=sys.stderr)
        return 2
    data = a.data or default_selros_dir()
    if not data.is_dir():
        from benchmark.harness.hints import fetch_command

        root = data.parent if a.data and data.name == "selros" else (None if a.data else default_selros_dir().parent)
        print(f"error: the SeLRoS release is not at {data}: get it with: {fetch_command('selros', root)} "
              f"(or give --data DIR)", file=sys.stderr)
        return 2
    try:
        common = [f"external.gt_dir={_quote(data / GT_FOLDER)}", f"external.gt_pattern={_quote(a.gt_pattern)}", *rest]
        if a.resolution is not None:
            common.append(f"external.resolution={a.resolution}")
        frames, params, res = [], None, None
        gts = _glob_ids(data / GT_FOLDER, a.gt_pattern)
        keep = MapSample(frozenset(sorted(gts)[:max(a.page_maps, 0)])) if a.out else None
        others = []
        for spec in a.method:
            name, eq, folder = spec.partition("=")
            if not (eq and name and folder):
                raise ValueError(f"--method {spec!r}: expected NAME=DIR (a folder of the method's maps)")
            others.append(("rose2", Path(folder), [f"external.method={_quote(name)}",
                                                   f"external.pred_pattern={_quote(a.method_pattern)}"]))
        for preset, folder, extra in (("selros", data / "selros", []), ("vrf", data / "vrf", []), *others):
            cfg = compose_score([f"external={preset}", f"external.pred_dir={_quote(folder)}", *common, *extra])
            method, params = instantiate(cfg.external), instantiate(cfg.metrics)
            res = method.resolution
            frames.append(method.score(params, sanity=not a.no_sanity and preset == "selros" and not extra,
                                       grid_size=float(cfg.grid_size), keep=keep))
        if not a.no_geometric:
            occ_dir = a.occupancy_dir or data / OCCUPANCY_FOLDER
            occ = _glob_ids(occ_dir, a.occupancy_pattern or OCCUPANCY_PATTERN)
            segs = None
            if a.rose2 or a.ipa:
                from benchmark.segmenters.distance import DistanceTransform
                from benchmark.segmenters.morphological import Morphological
                from benchmark.segmenters.voronoi import Voronoi

                segs = {"morphological": Morphological(), "distance": DistanceTransform(), "voronoi": Voronoi()}
            if a.rose2:
                from benchmark.segmenters.rose2 import Rose2

                segs["rose2"] = Rose2(checkout=a.rose2, python=a.rose2_python)
            if a.ipa:
                from benchmark.segmenters.ipa import ALGORITHMS, IpaSegmenter

                names = list(ALGORITHMS) if a.ipa == "all" else [n.strip() for n in a.ipa.split(",") if n.strip()]
                for name in names:  # an unknown name or no build: one line, exit 2
                    segs[f"ipa_{name}"] = IpaSegmenter(name)
            frames.append(geometric_rows(gts, occ, params, res, segmenters=segs, keep=keep))
    except Exception as e:
        cause = e.__cause__ if type(e).__name__ == "InstantiationException" and e.__cause__ else e
        if isinstance(cause, (FileNotFoundError, ValueError)):
            print(f"error: {cause}", file=sys.stderr)
            return 2
        raise
    df = pd.concat(frames, ignore_index=True)
    df.attrs["unpaired"] = []
    note = f"; geometric baselines on {a.occupancy_dir or 'the VRF outputs'}' free space."
    extra = None
    if a.out:
        from benchmark.metrics import describe
        from benchmark.reports.scores_page import build_scores_page

        methods = list(dict.fromkeys(df["method"]))
        extra = {"table5.html": build_scores_page(summary_table(df), failures(df), keep.gt, keep.pred, methods,
                                                  f"Table V: every method on {data}",
                                                  "Metrics: " + describe(params, res, colours=True) + note)}
    try:
        text = report(df, params, a.out, note=note, resolution=res, extra=extra)
    except OSError as e:  # a full disk, a read-only folder: one line naming the file
        from benchmark.harness.write_errors import cannot_write

        print(f"error: {cannot_write(e, a.out)}", file=sys.stderr)
        return 2
    if a.markdown is not None:
        from benchmark.reports.published import write_published

        err = write_published(a.markdown, published_command(a, rest),
                              text + "\n" + rose2_line(a.rose2) + (("\n" + ipa_line()) if a.ipa else ""))
        if err:
            print(f"error: {err}", file=sys.stderr)
            return 2
    return 0


def rose2_line(checkout: str | None) -> str:
    """The line under a published table that says where its ROSE² rows come from, or why it has none."""
    if not checkout:
        return ("No ROSE² row: no ROSE2 checkout was given (`--rose2 CHECKOUT` or `ROOMSEG_ROSE2=CHECKOUT`, "
                "after `make rose2-env`).")
    from benchmark.segmenters.rose2 import checkout_words

    return f"ROSE² rows: run here from {checkout_words(checkout)} (`ROOMSEG_ROSE2` or `--rose2`)."


def ipa_line() -> str:
    """The line under a published table that says which ipa_room_segmentation build its ipa rows ran from."""
    from benchmark.segmenters.ipa import ipa_build

    b = ipa_build()
    vrf = ("VRF with the OpenCV 2 weak hypotheses (IPA_VRF_FIX=1)" if b["vrf_fix"] else "VRF as published") \
        if b["vrf"] else "no VRF"
    return f"ipa rows: run here from ipa_coverage_planning at commit {b['ipa_commit'][:8]} (`make ipa-env`; {vrf})."


def published_command(a, overrides: list[str]) -> str:  # noqa: ANN001 - the parsed arguments
    """The command line that writes ``a.markdown`` again (defaults left out; the ROSE2 checkout, a
    local path, is named by :func:`rose2_line` instead)."""
    parts = ["python -m benchmark.commands.selros"]
    for flag, value in (("--data", a.data), ("--resolution", a.resolution), ("--occupancy-dir", a.occupancy_dir),
                        ("--occupancy-pattern", a.occupancy_pattern)):
        if value is not None:
            parts.append(f"{flag} {value}")
    from benchmark.baselines.selros import GT_PATTERN

    if a.gt_pattern != GT_PATTERN:
        parts.append(f"--gt-pattern '{a.gt_pattern}'")
    if getattr(a, "ipa", None):
        parts.append("--ipa" if a.ipa == "all" else f"--ipa {a.ipa}")
    parts += [f"--method {m}" for m in a.method]
    if a.method and a.method_pattern != "{id}.png":
        parts.append(f"--method-pattern '{a.method_pattern}'")
    parts += [flag for flag, on in (("--no-geometric", a.no_geometric), ("--no-sanity", a.no_sanity)) if on]
    return " ".join([*parts, *overrides, f"--markdown {a.markdown}"])


if __name__ == "__main__":
    raise SystemExit(main())
