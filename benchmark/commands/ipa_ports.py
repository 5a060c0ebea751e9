"""``python -m benchmark.commands.ipa_ports``: the project's morphological, distance and Voronoi
ports against ipa_room_segmentation's originals (the authors' C++, ``make ipa-env``), map by map,
on the SeLRoS release, the shared real laser maps and generated houses.

The sets of maps (``--sources``):

* ``selros``: the SeLRoS release's 30 maps (each map's free space, as Table V's geometric rows),
  with their ground truth;
* ``real``: the four real laser maps of the shared data (``real_maps``: Intel, Freiburg 79 and
  101, lab C, at 0.05 m/px; the largest 4-connected part of the free cells as read), which have
  no ground truth: agreement and segment counts only;
* ``synthetic``: generated houses (``env=synthetic`` at its defaults, furnished, seeds
  ``--seed-start`` .. ``--seed-start + --houses - 1``, 0..99 by default), with their ground truth.

    python -m benchmark.commands.ipa_ports [--sources selros,real,synthetic] [--houses N] [--seed-start S]
        [--data DIR] [--real-dir DIR] [--limit N] [--algorithms LIST] [--csv FILE] [--markdown FILE.md]

Per set and algorithm: how far the two label maps agree (matched IoU of the port's segments against
the original's, over the cells the original labels), segments per room of each, and the paired
differences port - original in matched IoU and PQ against the ground truth, with their 95 %
bootstrap intervals over maps; the maps the port splits most and whether the original splits the
same ones; on the real maps one row per map. ``morphological_limits`` is the morphological port
with the original's seed rule and area limits (``rule=limits``, 0.8 and 47 m²), against the same
original: what is left when the rule is the same; ``voronoi_original`` likewise the Voronoi port with
the original's graph, critical-point rule and merging passes (``rule=original``). ``--csv`` keeps
the per-map rows; ``--markdown`` writes the tables headed by the command
(``results/published/ipa_ports.md``, which docs/baselines.md includes, with its per-map rows beside
it as ``ipa_ports.csv``).
No build, no data: one line, exit 2.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.commands import cli

#: the ports: (module, class, settings, the original's algorithm).
PORTS = {"morphological": ("benchmark.segmenters.morphological", "Morphological", {}, "morphological"),
         "morphological_limits": ("benchmark.segmenters.morphological", "Morphological",
                                  {"rule": "limits", "min_seed_area": 0.8, "max_area": 47.0}, "morphological"),
         "distance": ("benchmark.segmenters.distance", "DistanceTransform", {}, "distance"),
         "voronoi": ("benchmark.segmenters.voronoi", "Voronoi", {}, "voronoi"),
         "voronoi_original": ("benchmark.segmenters.voronoi", "Voronoi", {"rule": "original", "min_room_area": 0.0},
                              "voronoi")}
SOURCES = ("selros", "real", "synthetic")
#: the sets' names in the tables.
SOURCE_NAMES = {"selros": "SeLRoS release", "real": "real laser maps", "synthetic": "generated houses"}
#: segments per room above which a map counts as over-split.
OVER_SPLIT = 1.5
#: the per-map columns (``--csv``; the published ``ipa_ports.csv``).
COLUMNS = ["source", "map", "algorithm", "rooms", "port_segments", "original_segments", "agreement_matched_iou",
           "port_matched_iou", "original_matched_iou", "port_pq", "original_pq"]


def compare(maps: Iterable[tuple[str, str, object, np.ndarray | None]], params,  # noqa: ANN001
            algorithms: list[str]) -> pd.DataFrame:
    """One row per map and algorithm (:data:`COLUMNS`): agreement, segments of both and, where
    the map has ground truth, rooms and the scores of both (NaN without).

    Args:
        maps: (source, map id, GridMap, ground-truth instances or None) per map.
        params: the metric settings (segments, areas, matching).
        algorithms: keys of :data:`PORTS`.
    """
    import importlib

    from benchmark.metrics import score_instances
    from benchmark.segmenters.ipa import IpaSegmenter

    ports = {a: getattr(importlib.import_module(PORTS[a][0]), PORTS[a][1])(**PORTS[a][2]) for a in algorithms}
    originals = {PORTS[a][3]: IpaSegmenter(PORTS[a][3]) for a in algorithms}
    rows = []
    for source, mid, grid, gt in maps:
        res = grid.resolution
        theirs_by = {name: np.asarray(seg(grid)) for name, seg in originals.items()}
        for a, port in ports.items():
            ours, theirs = np.asarray(port(grid)), theirs_by[PORTS[a][3]]
            agree = score_instances(ours, theirs, params, resolution=res)
            row = {"source": source, "map": mid, "algorithm": a, "rooms": float("nan"),
                   "port_segments": float(agree["n_pred_segments"]), "original_segments": float(agree["n_gt_segments"]),
                   "agreement_matched_iou": agree["matched_iou"]}
            if gt is not None:
                s_ours = score_instances(ours, gt, params, resolution=res)
                s_theirs = score_instances(theirs, gt, params, resolution=res)
                row.update(rooms=float(s_ours["n_gt_segments"]), port_matched_iou=s_ours["matched_iou"],
                           original_matched_iou=s_theirs["matched_iou"], port_pq=s_ours["pq"],
                           original_pq=s_theirs["pq"])
            rows.append(row)
    return pd.DataFrame(rows, columns=COLUMNS)


def per_room(g: pd.DataFrame, who: str) -> np.ndarray:
    """Segments per room of ``who`` (``port`` or ``original``) on each map (rooms at least 1)."""
    return g[f"{who}_segments"].to_numpy(float) / np.maximum(g["rooms"].to_numpy(float), 1.0)


def _cell(mean: float, lo: float, hi: float, scale: float = 100.0) -> str:
    return f"{mean * scale:.2f} [{lo * scale:.2f}, {hi * scale:.2f}]"


def table(df: pd.DataFrame) -> str:
    """The summary of the sets with ground truth as Markdown, one row per set and algorithm
    (percent; intervals over maps)."""
    from benchmark.stats import bootstrap_ci, paired_ci

    lines = ["| maps | algorithm | n | agreement (matched IoU) | segments per room: port | original | "
             "matched IoU: port - original | PQ: port - original |",
             "|:--|:--|--:|:--|:--|:--|:--|:--|"]
    for (source, a), g in df[df["rooms"].notna()].groupby(["source", "algorithm"], sort=False):
        ag = g["agreement_matched_iou"].to_numpy(float)
        sp, so = per_room(g, "port"), per_room(g, "original")
        lines.append("| " + " | ".join([
            SOURCE_NAMES[source], a, str(len(g)), _cell(ag.mean(), *bootstrap_ci(ag)),
            _cell(sp.mean(), *bootstrap_ci(sp), scale=1.0), _cell(so.mean(), *bootstrap_ci(so), scale=1.0),
            _cell(*paired_ci(g["port_matched_iou"], g["original_matched_iou"])),
            _cell(*paired_ci(g["port_pq"], g["original_pq"]))]) + " |")
    return "\n".join(lines) + (
        "\n\nMean [95 % interval] over maps (percentile bootstrap over maps; the differences paired map by map), "
        "percent except segments per room. Agreement: the port's segments matched (Hungarian on IoU) against the "
        "original's, over the cells the original labels.")


def over_split(df: pd.DataFrame) -> str:
    """Does the original over-split the maps the port over-splits? Per set with ground truth and
    algorithm: the port's most split map (the port's and the original's segments per room on it),
    the maps the port splits into more than :data:`OVER_SPLIT` segments per room and how many of
    them the original splits so too, and the rank correlation of the two per-map counts."""
    lines = ["| maps | algorithm | port's most split map: port / original | maps over "
             f"{OVER_SPLIT} per room: port | original too | original on them (mean) | original over {OVER_SPLIT} "
             "| rank correlation |",
             "|:--|:--|:--|--:|--:|:--|--:|--:|"]
    for (source, a), g in df[df["rooms"].notna()].groupby(["source", "algorithm"], sort=False):
        sp, so = per_room(g, "port"), per_room(g, "original")
        worst = int(np.argmax(sp))
        over = sp > OVER_SPLIT
        rho = pd.Series(sp).corr(pd.Series(so), method="spearman")
        lines.append("| " + " | ".join([
            SOURCE_NAMES[source], a, f"{g['map'].iloc[worst]}: {sp[worst]:.2f} / {so[worst]:.2f}", str(int(over.sum())),
            str(int((over & (so > OVER_SPLIT)).sum())), f"{so[over].mean():.2f}" if over.any() else "–",
            str(int((so > OVER_SPLIT).sum())), "–" if np.isnan(rho) else f"{rho:.2f}"]) + " |")
    return "\n".join(lines) + (
        f"\n\nSegments per room of each map (segments as the metrics count them over the rooms of its ground "
        f"truth). Over-split: more than {OVER_SPLIT} segments per room. Rank correlation: Spearman's, of the port's "
        f"and the original's segments per room over the maps.")


def real_table(df: pd.DataFrame) -> str:
    """The maps without ground truth, one row per map and algorithm."""
    g = df[df["rooms"].isna()]
    lines = ["| map | algorithm | agreement (matched IoU) | segments: port | original |", "|:--|:--|--:|--:|--:|"]
    for r in g.itertuples():
        lines.append(f"| {r.map} | {r.algorithm} | {100 * r.agreement_matched_iou:.2f} | {int(r.port_segments)} | "
                     f"{int(r.original_segments)} |")
    return "\n".join(lines) + (
        "\n\nNo ground truth: agreement (percent) as above, and the segments each makes (as the metrics count them, "
        "the original's over the cells it labels).")


def report(df: pd.DataFrame, sources: list[str], houses: int, seed_start: int) -> str:
    """The tables of :func:`table`, :func:`over_split` and :func:`real_table` for the sets run."""
    parts = []
    gt_sources = [s for s in sources if s != "real"]
    if gt_sources:
        parts += [table(df), "**Over-splitting: the same maps?**", over_split(df)]
    if "real" in sources:
        parts += ["**The real laser maps** (no ground truth)", real_table(df)]
    sets = []
    if "selros" in sources:
        sets.append("SeLRoS release: its 30 maps at 0.02 m/px, each map's free space")
    if "real" in sources:
        sets.append("real laser maps: `real_maps` of the shared data at 0.05 m/px, the largest 4-connected part "
                    "of the free cells")
    if "synthetic" in sources:
        sets.append(f"generated houses: `env=synthetic` at its defaults (0.05 m/px, furnished, the cells reachable "
                    f"from the start), seeds {seed_start}-{seed_start + houses - 1}")
    parts.append("Maps: " + "; ".join(sets) + ". The originals get each map resampled to 0.05 m/px "
                 "(`segmenter=ipa_*`); `morphological_limits`: the morphological port with the original's seed "
                 "rule and limits (`rule=limits`, 0.8 and 47 m²) against the same original; `voronoi_original`: the "
                 "Voronoi port with the original's graph, critical-point rule and merging passes (`rule=original`, "
                 "run at 0.05 m/px) against the same original.")
    return "\n\n".join(parts)


def selros_scoring(data: Path) -> tuple[object, float]:
    """(metric parameters, metres a pixel) of the SeLRoS release at ``data``: the score command's
    ``external=vrf`` configuration over its VRF and ground-truth folders."""
    from hydra.utils import instantiate

    from benchmark.baselines.selros import GT_FOLDER
    from benchmark.commands.selros import _quote, compose_score

    cfg = compose_score(["external=vrf", f"external.pred_dir={_quote(data / 'vrf')}",
                         f"external.gt_dir={_quote(data / GT_FOLDER)}"])
    return instantiate(cfg.metrics), float(instantiate(cfg.external).resolution)


def selros_maps(data: Path, limit: int | None, resolution: float, params  # noqa: ANN001
                ) -> Iterator[tuple[str, str, object, np.ndarray]]:
    from benchmark.baselines.external import _glob_ids, read_gt
    from benchmark.baselines.selros import (
        GT_FOLDER,
        GT_PATTERN,
        OCCUPANCY_FOLDER,
        OCCUPANCY_PATTERN,
        read_free_space,
    )
    from envs.maps.gridmap import GridMap

    gts = _glob_ids(data / GT_FOLDER, GT_PATTERN)
    occ = _glob_ids(data / OCCUPANCY_FOLDER, OCCUPANCY_PATTERN)
    for mid in sorted(set(gts) & set(occ))[:limit]:
        gt, _ = read_gt(gts[mid], "instance", params, resolution)
        yield "selros", mid, GridMap(read_free_space(occ[mid]), resolution, (0.0, 0.0)), gt


def real_maps(folder: Path, limit: int | None) -> Iterator[tuple[str, str, object, None]]:
    from benchmark.commands.map_stats import REAL_MAPS, REAL_RESOLUTION, read_occupancy
    from envs.maps.components import components
    from envs.maps.gridmap import GridMap
    from envs.maps.map_stats import FREE

    for name, (free_min, occupied_max) in list(REAL_MAPS.items())[:limit]:
        if not (folder / name).is_file():
            raise FileNotFoundError(f"real map not found: {folder / name} (give --real-dir DIR)")
        occ, res = read_occupancy(folder / name, REAL_RESOLUTION, free_min, occupied_max)
        lab, n = components(occ == FREE)
        if n == 0:
            raise ValueError(f"{folder / name}: no free cell (free from grey {free_min})")
        largest = lab == int(np.argmax(np.bincount(lab.ravel())[1:])) + 1
        yield "real", name, GridMap(largest, res, (0.0, 0.0)), None


def synthetic_maps(houses: int, seed_start: int, limit: int | None) -> Iterator[tuple[str, str, object, np.ndarray]]:
    from envs.datasets.synthetic import SyntheticEnv

    env = SyntheticEnv(n_houses=houses, seed_start=seed_start)
    for hid in env.house_ids()[:limit]:
        scene = env.scene(hid)
        yield "synthetic", hid, scene.grid, scene.instances


def _progress(maps: Iterable, label: str, total: int) -> Iterable:
    from benchmark.harness.progress import house_progress

    wrap = house_progress(label, workers=1)
    return wrap(maps, total=total) if wrap else maps


def main(argv: list[str] | None = None) -> int:

    from benchmark.baselines.selros import default_selros_dir
    from benchmark.commands.selros import ipa_line
    from benchmark.paths import data_dir

    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("--sources", default=",".join(SOURCES), help="comma list of selros, real, synthetic (default: all)")
    ap.add_argument("--data", type=Path, default=None, help="the SeLRoS release folder (default: shared data)")
    ap.add_argument("--real-dir", type=Path, default=None, help="the real laser maps (default: shared data's real_maps)")
    ap.add_argument("--houses", type=int, default=100, help="generated houses (default 100)")
    ap.add_argument("--seed-start", type=int, default=0, help="the first generated house's seed (default 0)")
    ap.add_argument("--limit", type=int, default=None, help="the first N maps of each set")
    ap.add_argument("--algorithms", default=",".join(PORTS), help=f"comma list of {', '.join(PORTS)} (default: all)")
    ap.add_argument("--csv", type=Path, default=None, help="the per-map rows")
    ap.add_argument("--markdown", type=Path, default=None,
                    help="the tables, headed by the command that made them (the per-map rows beside it, .csv)")
    a = ap.parse_args(argv)
    sources = [x.strip() for x in a.sources.split(",") if x.strip()]
    bad = [x for x in sources if x not in SOURCES]
    if bad or not sources:
        print(f"error: --sources {a.sources}: expected a comma list of {', '.join(SOURCES)}", file=sys.stderr)
        return 2
    algorithms = [x.strip() for x in a.algorithms.split(",") if x.strip()]
    bad = [x for x in algorithms if x not in PORTS]
    if bad or not algorithms:
        print(f"error: --algorithms {a.algorithms}: expected a comma list of {', '.join(PORTS)}", file=sys.stderr)
        return 2
    if a.houses < 1 or a.seed_start < 0 or (a.limit is not None and a.limit < 1):
        print(f"error: --houses {a.houses} --seed-start {a.seed_start} --limit {a.limit}: expected houses >= 1, "
              f"seed-start >= 0, limit >= 1", file=sys.stderr)
        return 2
    data = a.data or default_selros_dir()
    real = a.real_dir or data_dir() / "real_maps"
    for source, folder, flag in (("selros", data, "--data"), ("real", real, "--real-dir")):
        if source in sources and not folder.is_dir():
            print(f"error: the {SOURCE_NAMES[source]} are not at {folder} (give {flag} DIR)", file=sys.stderr)
            return 2
    try:
        params, res = selros_scoring(data)
        parts = []
        for source in sources:
            if source == "selros":
                maps, n = selros_maps(data, a.limit, res, params), 30 if a.limit is None else a.limit
            elif source == "real":
                maps, n = real_maps(real, a.limit), 4 if a.limit is None else min(a.limit, 4)
            else:
                maps, n = synthetic_maps(a.houses, a.seed_start, a.limit), min(a.houses, a.limit or a.houses)
            parts.append(compare(_progress(maps, f"ipa ports · {source}", n), params, algorithms))
        df = pd.concat(parts, ignore_index=True)
    except (ValueError, FileNotFoundError, RuntimeError) as e:  # no build, a bad map, a failed driver: one line
        print(f"error: {e}", file=sys.stderr)
        return 2
    text = report(df, sources, a.houses, a.seed_start) + "\n\n" + ipa_line()
    print(text)
    if a.csv:
        df.to_csv(a.csv, index=False)
    if a.markdown:
        from benchmark.reports.published import write_published

        cmd = ["python -m benchmark.commands.ipa_ports"]
        cmd += [f"--sources {a.sources}"] if sources != list(SOURCES) else []
        cmd += [f"--houses {a.houses}"] if a.houses != 100 else []
        cmd += [f"--seed-start {a.seed_start}"] if a.seed_start else []
        cmd += [f"--limit {a.limit}"] if a.limit else []
        cmd += [f"--algorithms {a.algorithms}"] if algorithms != list(PORTS) else []
        err = write_published(a.markdown, " ".join([*cmd, f"--markdown {a.markdown}"]), text,
                              csv=df.to_csv(index=False, float_format="%.6g"))
        if err:
            print(f"error: {err}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
