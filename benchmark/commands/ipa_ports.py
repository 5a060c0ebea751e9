"""``python -m benchmark.commands.ipa_ports``: the project's morphological, distance and Voronoi
ports against ipa_room_segmentation's originals (the authors' C++, ``make ipa-env``), map by map,
on the SeLRoS release's 30 maps (each map's free space, as Table V's geometric rows).

    python -m benchmark.commands.ipa_ports [--data DIR] [--limit N] [--csv FILE] [--markdown FILE.md]

Per algorithm: how far the two label maps agree (matched IoU of the port's segments against the
original's, over the cells the original labels), segments per room of each, and the paired
differences port - original in matched IoU and PQ against the ground truth, with their 95 %
bootstrap intervals over maps. ``--csv`` keeps the per-map rows; ``--markdown`` writes the table
headed by the command (``results/published/ipa_ports.md``, which docs/baselines.md includes).
No build: one line, exit 2.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.commands import cli

#: the ports and the original each is a port of.
PORTS = {"morphological": ("benchmark.segmenters.morphological", "Morphological"),
         "distance": ("benchmark.segmenters.distance", "DistanceTransform"),
         "voronoi": ("benchmark.segmenters.voronoi", "Voronoi")}


def compare(gts: dict[str, Path], occ: dict[str, Path], params, resolution: float,  # noqa: ANN001
            algorithms: list[str]) -> pd.DataFrame:
    """One row per map and algorithm: agreement, segments and rooms, scores of both."""
    import importlib

    from benchmark.baselines.external import read_gt
    from benchmark.baselines.selros import read_free_space
    from benchmark.metrics import score_instances
    from benchmark.segmenters.ipa import IpaSegmenter
    from envs.maps.gridmap import GridMap

    segs = {a: (getattr(importlib.import_module(PORTS[a][0]), PORTS[a][1])(), IpaSegmenter(a)) for a in algorithms}
    rows = []
    for mid in sorted(gts):
        gt, _ = read_gt(gts[mid], "instance", params, resolution)
        free = read_free_space(occ[mid])
        grid = GridMap(free, resolution, (0.0, 0.0))
        for a, (port, original) in segs.items():
            ours, theirs = np.asarray(port(grid)), np.asarray(original(grid))
            s_ours = score_instances(ours, gt, params, resolution=resolution)
            s_theirs = score_instances(theirs, gt, params, resolution=resolution)
            agree = score_instances(ours, theirs, params, resolution=resolution)
            rooms = max(float(s_ours["n_gt_segments"]), 1.0)
            rows.append({"map": mid, "algorithm": a, "agreement_matched_iou": agree["matched_iou"],
                         "port_segments_per_room": s_ours["n_pred_segments"] / rooms,
                         "original_segments_per_room": s_theirs["n_pred_segments"] / rooms,
                         "port_matched_iou": s_ours["matched_iou"], "original_matched_iou": s_theirs["matched_iou"],
                         "port_pq": s_ours["pq"], "original_pq": s_theirs["pq"]})
    return pd.DataFrame(rows)


def table(df: pd.DataFrame) -> str:
    """The per-algorithm summary as Markdown (percent; intervals over maps)."""
    from benchmark.stats import bootstrap_ci, paired_ci

    def cell(mean: float, lo: float, hi: float, scale: float = 100.0, digits: int = 2) -> str:
        return f"{mean * scale:.{digits}f} [{lo * scale:.{digits}f}, {hi * scale:.{digits}f}]"

    lines = ["| algorithm | maps | agreement (matched IoU) | segments per room: port | original | "
             "matched IoU: port - original | PQ: port - original |",
             "|:--|--:|:--|:--|:--|:--|:--|"]
    for a, g in df.groupby("algorithm", sort=False):
        ag = g["agreement_matched_iou"].to_numpy(float)
        sp, so = g["port_segments_per_room"].to_numpy(float), g["original_segments_per_room"].to_numpy(float)
        lines.append("| " + " | ".join([
            a, str(len(g)), cell(ag.mean(), *bootstrap_ci(ag)), cell(sp.mean(), *bootstrap_ci(sp), scale=1.0),
            cell(so.mean(), *bootstrap_ci(so), scale=1.0),
            cell(*paired_ci(g["port_matched_iou"], g["original_matched_iou"])),
            cell(*paired_ci(g["port_pq"], g["original_pq"]))]) + " |")
    return "\n".join(lines) + (
        "\n\nMean [95 % interval] over maps (percentile bootstrap over maps; the differences paired map by map), "
        "percent except segments per room. Agreement: the port's segments matched (Hungarian on IoU) against the "
        "original's, over the cells the original labels.")


def main(argv: list[str] | None = None) -> int:
    from hydra.utils import instantiate

    from benchmark.baselines.external import _glob_ids
    from benchmark.baselines.selros import (
        GT_FOLDER,
        GT_PATTERN,
        OCCUPANCY_FOLDER,
        OCCUPANCY_PATTERN,
        default_selros_dir,
    )
    from benchmark.commands.selros import _quote, compose_score, ipa_line

    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=None, help="the SeLRoS release folder (default: shared data)")
    ap.add_argument("--limit", type=int, default=None, help="the first N maps")
    ap.add_argument("--algorithms", default=",".join(PORTS), help="comma list (default: all three)")
    ap.add_argument("--csv", type=Path, default=None, help="the per-map rows")
    ap.add_argument("--markdown", type=Path, default=None, help="the table, headed by the command that made it")
    a = ap.parse_args(argv)
    data = a.data or default_selros_dir()
    if not data.is_dir():
        print(f"error: the SeLRoS release is not at {data} (give --data DIR)", file=sys.stderr)
        return 2
    algorithms = [x.strip() for x in a.algorithms.split(",") if x.strip()]
    bad = [x for x in algorithms if x not in PORTS]
    if bad or not algorithms:
        print(f"error: --algorithms {a.algorithms}: expected a comma list of {', '.join(PORTS)}", file=sys.stderr)
        return 2
    try:
        cfg = compose_score(["external=vrf", f"external.pred_dir={_quote(data / 'vrf')}",
                             f"external.gt_dir={_quote(data / GT_FOLDER)}"])
        params, res = instantiate(cfg.metrics), float(instantiate(cfg.external).resolution)
        gts = _glob_ids(data / GT_FOLDER, GT_PATTERN)
        occ = _glob_ids(data / OCCUPANCY_FOLDER, OCCUPANCY_PATTERN)
        ids = sorted(set(gts) & set(occ))[: a.limit]
        df = compare({i: gts[i] for i in ids}, occ, params, res, algorithms)
    except ValueError as e:  # no build, a bad setting: one line
        print(f"error: {e}", file=sys.stderr)
        return 2
    text = table(df) + "\n\n" + ipa_line()
    print(text)
    if a.csv:
        df.to_csv(a.csv, index=False)
    if a.markdown:
        from benchmark.reports.published import write_published

        cmd = "python -m benchmark.commands.ipa_ports" + (f" --limit {a.limit}" if a.limit else "") + (
            f" --algorithms {a.algorithms}" if algorithms != list(PORTS) else "") + f" --markdown {a.markdown}"
        err = write_published(a.markdown, cmd, text)
        if err:
            print(f"error: {err}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
