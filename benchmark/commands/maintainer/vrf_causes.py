"""``python -m benchmark.commands.maintainer.vrf_causes``: why the authors' VRF (``segmenter=ipa_vrf``,
``make ipa-env``) returns one segment or none on many SeLRoS maps, map by map.

Two causes are known (docs/baselines.md, "How far the two VRF rows agree"):

1. **resolution**: the segmenter resamples the release's 0.02 m/px maps to the authors' 0.05 m/px
   (``segmenter.resolution``), where the VRF's pixel distances are 2.5 times longer in metres and a
   small room holds fewer field nodes;
2. **one class**: after inference the authors keep a class's regions only when that class has more
   than one region in the map (``map_contours.size() > 1`` in their
   ``voronoi_random_field_segmentation.cpp``), so a map whose field nodes are all labelled one
   class keeps at most its one region (none when it has no hole).

Each map runs twice, at the authors' 0.05 m/px (as the harness runs it) and at the map's own
resolution, and each run is scored against the release's ground truth (segments and matched IoU as
Table V counts them). How the inference labelled the field nodes comes from the driver's chatter
(``native/ipa/roomseg_vrf_labels.h``; a build made before it says nothing: "unknown", run
``make ipa-env`` again).

    python -m benchmark.commands.maintainer.vrf_causes [--data DIR] [--limit N] [--csv FILE] [--markdown OUT.md]

``--markdown`` writes the per-map table and its summary headed by the command
(``results/published/vrf_causes.md``, which docs/baselines.md includes; ``make docs-numbers``),
with the per-map rows beside it (``.csv``). No build or no data: one line, exit 2; a map the
driver fails on is a row saying so, and the exit status is 1.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd

from benchmark.commands import cli

#: the field-node classes of the authors' VRF, in their order (room, hallway, doorway).
CLASSES = ("room", "hallway", "doorway")
#: the two runs of each map: the authors' working resolution and the map's own.
RUNS = ("authors", "own")
#: the per-map columns (``--csv``; the published ``vrf_causes.csv``): for each run its working
#: resolution, segments, matched IoU and field nodes per class (NaN: unknown), and why a map failed.
COLUMNS = ["map", "rooms"] + [f"{run}_{what}" for run in RUNS for what in
                              ("resolution", "segments", "matched_iou", *(f"nodes_{c}" for c in CLASSES))] + ["error"]
#: at most this many segments: the maps the causes are looked for on.
FEW = 1


def one_class(row: pd.Series | dict, run: str) -> str | None:
    """The class every field node of ``run`` got ("room", "hallway", "doorway"), "" when the
    nodes got more than one class, None when the driver did not say (or the map failed)."""
    counts = [row.get(f"{run}_nodes_{c}") for c in CLASSES]
    if any(v is None or pd.isna(v) for v in counts):
        return None
    used = [c for c, v in zip(CLASSES, counts, strict=True) if v > 0]
    return used[0] if len(used) == 1 else ""


def _one_class_cell(row: pd.Series, run: str) -> str:
    c = one_class(row, run)
    return "unknown" if c is None else ("no" if c == "" else f"yes ({c})")


def _nodes_cell(row: pd.Series, run: str) -> str:
    counts = [row.get(f"{run}_nodes_{c}") for c in CLASSES]
    return "–" if any(pd.isna(v) for v in counts) else " / ".join(str(int(v)) for v in counts)


def _int_cell(v) -> str:  # noqa: ANN001 - a number or NaN
    return "–" if pd.isna(v) else str(int(v))


def _pct_cell(v) -> str:  # noqa: ANN001
    return "–" if pd.isna(v) else f"{100 * v:.2f}"


def _res(df: pd.DataFrame, run: str) -> str:
    values = df[f"{run}_resolution"].dropna().unique()
    return f"{values[0]:g}" if len(values) == 1 else run


def summary(df: pd.DataFrame) -> str:
    """The maps per cause: of the maps with at most :data:`FEW` segment at the authors'
    resolution, how many had every field node labelled one class there (cause 2), how many
    split into more segments at the map's own resolution (cause 1), both, neither, and for how
    many the build did not say."""
    ok = df[df["error"].fillna("") == ""]
    few = ok[ok["authors_segments"] <= FEW]
    a, own = _res(df, "authors"), _res(df, "own")
    single = [one_class(r, "authors") for _, r in few.iterrows()]
    unknown = sum(c is None for c in single)
    cls = np.array([bool(c) for c in single], bool)
    more = (few["own_segments"] > few["authors_segments"]).to_numpy(bool)
    parts = [f"{len(few)} of the {len(ok)} maps end with at most {FEW} segment at {a} m/px "
             f"({int((few['rooms'] > 1).sum())} of them with more than one room in the ground truth)"]
    if len(few):
        known = np.array([c is not None for c in single], bool)
        parts.append(f"every field node one class there (cause 2): {int((cls & known).sum())}; "
                     f"more segments at {own} m/px (cause 1): {int(more.sum())}; both: {int((cls & more).sum())}; "
                     f"neither: {int((known & ~cls & ~more).sum())}"
                     + (f"; the build did not say how the nodes were labelled on {unknown}" if unknown else ""))
    own_single = [one_class(r, "own") for _, r in ok.iterrows()]
    parts.append(f"over all {len(ok)} maps, more segments at {own} m/px than at {a} m/px on "
                 f"{int((ok['own_segments'] > ok['authors_segments']).sum())}, at most {FEW} segment at {own} m/px on "
                 f"{int((ok['own_segments'] <= FEW).sum())}, every field node one class at {a} m/px on "
                 f"{sum(bool(one_class(r, 'authors')) for _, r in ok.iterrows())} and at {own} m/px on "
                 f"{sum(bool(c) for c in own_single)}")
    failed = len(df) - len(ok)
    return "**Maps per cause**: " + "; ".join(parts) + "." + (f" {failed} map(s) failed (below)." if failed else "")


def table(df: pd.DataFrame) -> str:
    """The per-map table (Markdown), :func:`summary` and what the columns are."""
    a, own = _res(df, "authors"), _res(df, "own")
    lines = [f"| map | rooms | segments at {a} | at {own} | field nodes at {a}: room / hallway / doorway | one class "
             f"| at {own}: room / hallway / doorway | one class | matched IoU at {a} | at {own} |",
             "|:--|--:|--:|--:|--:|:--|--:|:--|--:|--:|"]
    for _, r in df.iterrows():
        if r["error"] and not pd.isna(r["error"]):
            lines.append(f"| {r['map']} | {_int_cell(r['rooms'])} | failed | | | | | | | |")
            continue
        lines.append("| " + " | ".join([
            str(r["map"]), _int_cell(r["rooms"]), _int_cell(r["authors_segments"]), _int_cell(r["own_segments"]),
            _nodes_cell(r, "authors"), _one_class_cell(r, "authors"), _nodes_cell(r, "own"),
            _one_class_cell(r, "own"), _pct_cell(r["authors_matched_iou"]), _pct_cell(r["own_matched_iou"])]) + " |")
    notes = [summary(df), (
        f"The authors' VRF (`segmenter=ipa_vrf`, their default parameters) on each SeLRoS map's free space, run at "
        f"{a} m/px (the map resampled, as the harness runs it) and at {own} m/px (the map's own, "
        f"`segmenter.resolution={own}`). Rooms: the ground truth's; segments and matched IoU (percent) against it as "
        f"Table V counts them. Field nodes: how the inference labelled the conditional field's nodes (the driver's "
        f"`roomseg field nodes` line); one class: every node got that class, where the authors keep a class's "
        f"regions only when it has more than one (`map_contours.size() > 1`).")]
    errors = [f"- {r['map']}: {r['error']}" for _, r in df.iterrows() if r["error"] and not pd.isna(r["error"])]
    return "\n".join(lines) + "\n\n" + "\n\n".join(notes) + ("\n\n" + "\n".join(errors) if errors else "")


def run_maps(maps: Iterable[tuple[str, str, object, np.ndarray]], params, own: float) -> pd.DataFrame:  # noqa: ANN001
    """One row per map (:data:`COLUMNS`): the VRF at the authors' resolution and at ``own``.

    Args:
        maps: (source, map id, GridMap, ground-truth instances) per map
            (:func:`benchmark.commands.ipa_ports.selros_maps`).
        params: the metric settings.
        own: the maps' own metres per pixel.
    """
    from benchmark.metrics import score_instances
    from benchmark.segmenters.ipa import IPA_RESOLUTION, IpaSegmenter

    segs = {"authors": IpaSegmenter("vrf", resolution=IPA_RESOLUTION), "own": IpaSegmenter("vrf", resolution=own)}
    rows = []
    for _, mid, grid, gt in maps:
        row: dict = {"map": mid, "rooms": float("nan"), "error": ""}
        try:
            for run, seg in segs.items():
                s = score_instances(np.asarray(seg(grid)), gt, params, resolution=grid.resolution)
                nodes = seg.last_field_nodes or {}
                row.update({"rooms": float(s["n_gt_segments"]), f"{run}_resolution": seg.resolution,
                            f"{run}_segments": float(s["n_pred_segments"]), f"{run}_matched_iou": s["matched_iou"],
                            **{f"{run}_nodes_{c}": float(nodes.get(c, float("nan"))) for c in CLASSES}})
        except RuntimeError as e:  # the driver failed or timed out on this map: a row saying so
            row["error"] = str(e)
        rows.append(row)
    return pd.DataFrame(rows, columns=COLUMNS)


def main(argv: list[str] | None = None) -> int:
    from benchmark.baselines.selros import default_selros_dir
    from benchmark.commands.ipa_ports import selros_maps, selros_scoring
    from benchmark.commands.selros import ipa_line
    from benchmark.harness.progress import house_progress

    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=None, help="the SeLRoS release folder (default: shared data)")
    ap.add_argument("--limit", type=int, default=None, help="the first N maps")
    ap.add_argument("--csv", type=Path, default=None, help="the per-map rows")
    ap.add_argument("--markdown", type=Path, default=None,
                    help="the table, headed by the command that made it (the per-map rows beside it, .csv)")
    a = ap.parse_args(argv)
    if a.limit is not None and a.limit < 1:
        print(f"error: --limit {a.limit}: expected a number of maps >= 1", file=sys.stderr)
        return 2
    data = a.data or default_selros_dir()
    if not data.is_dir():
        print(f"error: the SeLRoS release is not at {data} (give --data DIR)", file=sys.stderr)
        return 2
    try:
        params, res = selros_scoring(data)
        maps = selros_maps(data, a.limit, res, params)
        wrap = house_progress("vrf causes · selros", workers=1)
        df = run_maps(wrap(maps, total=a.limit or 30) if wrap else maps, params, res)
        build = ipa_line()
    except (ValueError, FileNotFoundError) as e:  # no build, no VRF in it, a bad map: one line
        print(f"error: {e}", file=sys.stderr)
        return 2
    if df.empty:
        print(f"error: no SeLRoS map with ground truth and occupancy image in {data}", file=sys.stderr)
        return 2
    text = table(df) + "\n\n" + build
    print(text)
    if a.csv:
        df.to_csv(a.csv, index=False)
    if a.markdown:
        from benchmark.reports.published import write_published

        cmd = ["python -m benchmark.commands.maintainer.vrf_causes"] + ([f"--data {a.data}"] if a.data else []) \
            + ([f"--limit {a.limit}"] if a.limit else [])
        err = write_published(a.markdown, " ".join([*cmd, f"--markdown {a.markdown}"]), text,
                              csv=df.to_csv(index=False, float_format="%.6g"))
        if err:
            print(f"error: {err}", file=sys.stderr)
            return 2
    return 1 if (df["error"] != "").any() else 0


if __name__ == "__main__":
    raise SystemExit(main())
