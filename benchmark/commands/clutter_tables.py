"""``python -m benchmark.commands.clutter_tables``: the geometric segmenters (distance,
morphological, Voronoi) under each map reading and reachable-area setting, on the furnished
offices of :mod:`benchmark.commands.clutter_example`, its hand-made two-room office, and the
first shared ProcTHOR houses; and what the reachable area removes from those houses and from
generated ones. The tables docs/maps-and-clutter.md includes (``make docs-numbers``).

Every row is a run of the project's runner (:func:`benchmark.harness.runner.run`, the
configuration a ``roomseg-bench`` sweep composes) into a temporary folder; the tables are means
over maps (percent; ``segments - rooms`` as a count), segments and rooms summed, and the
largest predicted segment's share of the segmented area (saved instance maps), its largest
value over the maps. The reachable-area table compares each house's scene under
``env.reachable=all`` and ``start``.
"""

from __future__ import annotations

import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.commands import cli
from benchmark.commands.errors import cli_errors, one_line

SEGMENTERS = ("distance", "morphological", "voronoi")

#: (maps, reading label, overrides) of the office rows, in the order shown.
OFFICE_SETTINGS = (
    ("furnished", "`ros` (default)", ()),
    ("furnished", "`white_only`", ("env.image_preset=white_only",)),
    ("furnished", "`white_only`, `reachable=all`, `min_room_area=0`",
     ("env.image_preset=white_only", "env.reachable=all", "segmenter.min_room_area=0")),
    ("furnished", "`free_thresh=0.25`, `reachable=all`, `min_room_area=0`",
     ("env.free_thresh=0.25", "env.reachable=all", "segmenter.min_room_area=0")),
    ("empty", "`ros` (default)", ()),
)
#: (label, overrides) of the hand-made two-room office's rows (read with white_only).
HAND_MADE_SETTINGS = (("`white_only`, `reachable=all`", ("env.reachable=all",)),
                      ("`white_only` (defaults: `reachable=start`)", ()))
#: (label, overrides) of the ProcTHOR rows.
HOUSE_SETTINGS = (("`env.reachable=all`", ("env.reachable=all",)), ("defaults (`start`)", ()))

METRICS = ("iou", "matched_iou", "pq", "ipa_recall", "ipa_precision")


def _run(overrides: list[str], work: Path, name: str) -> pd.DataFrame:
    """One runner job in ``work``: its rows, with ``largest`` (the largest predicted segment's
    share of the predicted segments' area, per map) added."""
    from benchmark.config import compose_job
    from benchmark.harness.runner import run
    from benchmark.harness.store import Job
    from envs.npz import load_npz

    cfg, choices = compose_job([*overrides, "run.progress=false", "run.workers=1", "run.save_maps=true",
                                f"run.results_dir={work / 'results'}", f"run.cache_dir={work / 'cache'}"])
    with warnings.catch_warnings():  # the grey and reachable-area warnings: what the tables show
        warnings.simplefilter("ignore", UserWarning)
        df = run(cfg, work / "jobs" / name, choices)
    bad = df[df["status"] != "ok"]
    if len(bad):
        raise RuntimeError(f"{name}: house {bad.iloc[0]['house_id']} failed: {bad.iloc[0]['error']}")
    job = Job(Path(df.attrs["job_dir"]))
    largest = []
    for hid in df["house_id"]:
        inst = load_npz(job.maps_path(str(hid)))["instances"]
        sizes = np.bincount(inst[inst >= 0].ravel())
        largest.append(float(sizes.max() / sizes.sum()) if sizes.sum() else np.nan)
    return df.assign(largest=largest)


def _maps_overrides(folder: Path) -> list[str]:
    return ["env=maps", f"env.dir={folder}", "env.maps='{id}.png'", "env.image_resolution=0.05",
            "env.gt_format=rooms_white"]


def segmenter_rows(work: Path, offices: int, seed: int, houses: int) -> pd.DataFrame:
    """One row per (part, maps, reading, segmenter, map): the runner's metrics and ``largest``.

    Args:
        work: an empty folder for the maps, runs and caches.
        offices: generated offices (``clutter_example`` seeds ``seed`` ..).
        seed: the first office's seed.
        houses: the first shared ProcTHOR houses (0: none).
    """
    from benchmark.commands.clutter_example import two_room_office, write_office, write_offices

    write_offices(work / "offices", offices, seed)
    write_office(work / "two_rooms", "office", two_room_office())
    jobs = []
    for maps, reading, extra in OFFICE_SETTINGS:
        jobs += [("offices", maps, reading, seg, [*_maps_overrides(work / "offices" / maps), *extra])
                 for seg in SEGMENTERS]
    for reading, extra in HAND_MADE_SETTINGS:
        jobs += [("two_rooms", "furnished", reading, seg, [*_maps_overrides(work / "two_rooms" / "furnished"),
                                                           "env.image_preset=white_only", *extra])
                 for seg in SEGMENTERS]
    if houses:
        for reading, extra in HOUSE_SETTINGS:
            jobs += [("procthor", "shared houses", reading, seg, ["env=procthor_shared", f"run.limit={houses}",
                                                                 *extra]) for seg in SEGMENTERS]
    frames = []
    for k, (part, maps, reading, seg, overrides) in enumerate(jobs):
        df = _run([*overrides, f"segmenter={seg}"], work, f"job{k:02d}")
        frames.append(df.assign(part=part, maps=maps, reading=reading, segmenter=seg))
    return pd.concat(frames, ignore_index=True)


def reachable_rows(houses: int) -> pd.DataFrame:
    """One row per house of the first ``houses`` shared ProcTHOR houses and of ``houses``
    generated ones: whether its start pose is off the walkable cells and how far (metres, cell
    centres), and what ``env.reachable=start`` removes against ``all`` (walkable cells, rooms)."""
    from hydra.utils import instantiate
    from scipy import ndimage

    from benchmark.config import compose
    from envs.maps.reachable import start_points

    rows = []
    for dataset, env_name, extra in (("ProcTHOR (shared)", "procthor_shared", [f"env.stop={houses}"]),
                                     ("synthetic", "synthetic", [f"env.n_houses={houses}"])):
        envs = {rule: instantiate(compose("config", [f"env={env_name}", f"env.reachable={rule}", *extra]).env)
                for rule in ("all", "start")}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            for hid in envs["all"].house_ids()[:houses]:
                full, cut = envs["all"].scene(hid), envs["start"].scene(hid)
                walk = np.asarray(full.grid.walkable, bool)
                xz = start_points(envs["all"].house(hid).data)
                off, dist_m = False, 0.0
                if xz is not None:
                    r, c = full.grid.world_to_cell(xz[:, 0], xz[:, 1])
                    r, c = int(np.asarray(r)[0]), int(np.asarray(c)[0])
                    off = not (full.grid.in_bounds(r, c) and walk[r, c])
                    if off and full.grid.in_bounds(r, c):
                        dist_m = float(ndimage.distance_transform_edt(~walk)[r, c] * full.grid.resolution)
                removed = int(walk.sum() - np.asarray(cut.grid.walkable, bool).sum())
                rooms = set(np.unique(full.instances[full.instances >= 0]).tolist())
                kept = set(np.unique(cut.instances[cut.instances >= 0]).tolist())
                rows.append({"dataset": dataset, "house": hid, "start_off": off, "start_dist_m": dist_m,
                             "removed_share": removed / max(int(walk.sum()), 1), "rooms": len(rooms),
                             "rooms_removed": len(rooms - kept)})
    return pd.DataFrame(rows)


def _table(df: pd.DataFrame, keys: list[str]) -> str:
    """Means over maps of one part's rows, one line per ``keys`` combination (first-seen order)."""
    from benchmark.reports.formatting import METRIC_LABELS

    g = df.groupby(keys, sort=False)
    out = (g[list(METRICS)].mean() * 100.0).map(lambda v: f"{v:.2f}")
    out.insert(0, "segments / rooms", g["n_pred_segments"].sum().astype(int).astype(str) + " / " +
               g["n_gt_segments"].sum().astype(int).astype(str))
    out["segments − rooms"] = g["count_error"].mean().map(lambda v: f"{v:+.2f}".replace("-", "−"))
    out["largest segment %"] = (g["largest"].max() * 100.0).map(lambda v: f"{v:.2f}")
    out = out.rename(columns={m: METRIC_LABELS[m] for m in METRICS})
    return out.reset_index().to_markdown(index=False, disable_numparse=True,
                                         colalign=("left",) * len(keys) + ("right",) * out.shape[1])


def report(seg: pd.DataFrame, reach: pd.DataFrame | None) -> str:
    """The command's Markdown: a table per part with its note, then the reachable-area table."""
    out = []
    parts = [("offices", ["maps", "reading", "segmenter"],
              "Furnished offices (`clutter_example`, {n} maps, {r} rooms) and the same maps without furniture"),
             ("two_rooms", ["reading", "segmenter"], "The hand-made two-room office with a desk island ({n} map)"),
             ("procthor", ["reading", "segmenter"], "The first {n} shared ProcTHOR houses ({r} rooms)")]
    for part, keys, title in parts:
        d = seg[seg["part"] == part]
        if d.empty:
            continue
        first = d[(d[keys[:-1]] == d[keys[:-1]].iloc[0]).all(axis=1) & (d["segmenter"] == d["segmenter"].iloc[0])]
        out += [f"**{title.format(n=len(first), r=int(first['n_gt_segments'].sum()))}**", "", _table(d, keys), ""]
    out += ["Means over maps, percent; segments and rooms summed over maps; segments − rooms: mean per map; "
            "largest segment: the largest predicted segment's share of the segmented area, its largest value "
            "over the maps. Geometric segmenters at their defaults (`min_room_area` 1.0 m²) unless the reading "
            "says otherwise.", ""]
    if reach is not None and len(reach):
        g = reach.groupby("dataset", sort=False)
        table = pd.DataFrame({
            "houses": g.size().astype(str),
            "start off the walkable cells": g["start_off"].sum().astype(int).astype(str),
            "farthest start from them (m)": g["start_dist_m"].max().map(lambda v: f"{v:.2f}"),
            "houses with cells removed": (g["removed_share"].apply(lambda s: int((s > 0).sum()))).astype(str),
            "removed, mean %": g["removed_share"].mean().map(lambda v: f"{100 * v:.2f}"),
            "removed, max %": g["removed_share"].max().map(lambda v: f"{100 * v:.2f}"),
            "rooms removed": g["rooms_removed"].sum().astype(str) + " of " + g["rooms"].sum().astype(str),
        })
        out += ["**What the reachable area removes** (`env.reachable=start` against `all`)", "",
                table.reset_index().to_markdown(index=False, disable_numparse=True, colalign=("left",) + ("right",) * table.shape[1]), "",
                "Removed: share of a house's walkable cells; rooms removed: rooms left with no cell. Distance "
                "between cell centres.", ""]
    return "\n".join(out)


def published_command(a) -> str:  # noqa: ANN001 - the parsed arguments
    """The command line that makes the published file."""
    parts = ["python -m benchmark.commands.clutter_tables", f"--offices {a.offices}", f"--houses {a.houses}"]
    if a.seed:
        parts.append(f"--seed {a.seed}")
    if a.out is not None:
        parts.append(f"--out {a.out}")
    return " ".join(parts)


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("--offices", type=int, default=7, help="generated furnished offices (clutter_example)")
    ap.add_argument("--seed", type=int, default=0, help="the first office's seed")
    ap.add_argument("--houses", type=int, default=40,
                    help="first N shared ProcTHOR houses, and N generated houses for the reachable-area table "
                         "(0: neither)")
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the tables to this Markdown file, headed by the command that made them "
                         "(make docs-numbers: results/published/clutter_tables.md, which docs/maps-and-clutter.md "
                         "includes)")
    a = ap.parse_args(argv)
    try:
        if a.offices < 1 or a.seed < 0 or a.houses < 0:
            raise ValueError(f"--offices {a.offices} / --seed {a.seed} / --houses {a.houses}: expected offices >= 1, "
                             f"seed >= 0 and houses >= 0")
        with tempfile.TemporaryDirectory(prefix="roomseg-clutter-tables-") as tmp:
            seg = segmenter_rows(Path(tmp), a.offices, a.seed, a.houses)
        text = report(seg, reachable_rows(a.houses) if a.houses else None)
    except (*cli_errors(), RuntimeError) as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    if a.out is not None:
        from benchmark.reports.published import write_published

        err = write_published(a.out, published_command(a), text)
        if err:
            print(f"error: {err}", file=sys.stderr)
            return 2
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
