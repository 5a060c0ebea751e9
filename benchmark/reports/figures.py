"""The paper's figures, in fixed colour-blind-safe class colours, with room borders, a legend
and a scale bar on every map, titled in words, as PNG, PDF and/or SVG.

* Fig. 3: ground truth | raw prediction | post-processed, for one house.
* Fig. 4: ground truth with sample viewpoints | graph KNN | vision cone, for one house.
* Fig. 2: the autotrace path and its sampled viewpoints on the map; and one view's cone
  with the objects it sees (numbered on the map, listed beside it: no label overlaps).

Fig. 3 and Fig. 4 are drawn from the runner's caches: the command composes the Hydra
config of ``conf/`` with the given overrides, runs the house through
:class:`benchmark.harness.pipeline.Pipeline` (which reuses cached renders, classifications and
label maps, and computes and caches whatever is missing) and draws the cached maps::

    python -m benchmark.commands.figures fig3 --house-index 80 --out docs/figures/fig3.png
    python -m benchmark.commands.figures fig4 --house-index 80 --out docs/figures/fig4.png classifier=objects
    python -m benchmark.commands.figures house --house-index 80 --out docs/figures   # Fig. 2, 3, 4 + one view
    python -m benchmark.commands.figures from-run results/runs/bench --out DIR --house ID --format png,pdf

Defaults: ``env=procthor_shared classifier=oracle`` (80 % accuracy), Fig. 3 with
``aggregator=vision_cone postprocess=default``, Fig. 4 with ``postprocess=none`` (the
aggregators' raw output). The figure functions take arrays only; each returns the files
it wrote (``path`` with each requested format's suffix).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from benchmark.reports.formatting import finite_float
from benchmark.reports.plotting import (
    PNG_DPI,
    add_legend,
    add_scale_bar,
    draw_poses,
    save,
    show_map,
)
from envs.maps.scene import Scene

#: dots per inch of the PNGs (their pixel size is ``figure_size(...) * DPI``).
DPI = PNG_DPI
#: height of one map panel, inches; its width follows the map's aspect ratio (clipped).
PANEL_H = 3.6
_TITLE_H, _LEGEND_W = 0.55, 1.85

FIG3_DEFAULTS = {"env": "procthor_shared", "classifier": "oracle", "aggregator": "vision_cone",
                 "postprocess": "default"}
FIG4_DEFAULTS = {"env": "procthor_shared", "classifier": "oracle", "postprocess": "none"}

#: stage options in words (titles).
DATASET_WORDS = {"procthor_shared": "ProcTHOR (shared val)", "procthor": "ProcTHOR-10k", "synthetic": "generated",
                 "architecthor": "ArchitecTHOR", "maps": "user map"}
CLASSIFIER_WORDS = {"objects": "objects classifier", "objects_procthor": "objects classifier (ProcTHOR-trained)",
                    "oracle": "oracle classifier", "cnn": "ResNet-50", "dinov2": "DINOv2 + MLP", "vlm": "Qwen2.5-VL"}
AGGREGATOR_WORDS = {"graph_knn": "graph KNN", "vision_cone": "vision cone", "euclidean_knn": "Euclidean KNN"}


def describe(names: Mapping[str, str], oracle_accuracy: float | None = None,
             view_accuracy: float | None = None, aggregator: bool = True, post: bool = True) -> str:
    """A configuration in words, e.g. ``oracle classifier (set to 80 % accuracy, 78 % of views
    right), vision cone, post-processed``.

    ``oracle_accuracy``: the oracle's configured accuracy (0-1); ``view_accuracy``: the share
    of this house's views classified right (0-1); either may be None or NaN (left out).
    """
    clf = CLASSIFIER_WORDS.get(names.get("classifier", ""), names.get("classifier", ""))
    acc = []
    if oracle_accuracy is not None and not math.isnan(oracle_accuracy):
        acc.append(f"set to {oracle_accuracy:.0%} accuracy")
    if view_accuracy is not None and not math.isnan(view_accuracy):
        acc.append(f"{view_accuracy:.0%} of views right")
    parts = [clf + (f" ({', '.join(acc)})" if acc else "")]
    if aggregator and names.get("aggregator"):
        parts.append(AGGREGATOR_WORDS.get(names["aggregator"], names["aggregator"]))
    if post and names.get("postprocess") is not None:
        parts.append("no post-processing" if names["postprocess"] in ("none", "") else
                     ("post-processed" if names["postprocess"] == "default" else f"post-processing {names['postprocess']}"))
    return ", ".join(parts).replace("%", " %").replace("  %", " %")


def house_title(names: Mapping[str, str], house_id: str) -> str:
    """``<dataset in words> house <id>``."""
    env = names.get("env", "")
    return f"{DATASET_WORDS.get(env, env)} house {house_id}"


def view_accuracy(row: Mapping) -> float | None:
    """The share of a house's views whose class is right: against the room each view sees
    (``view_accuracy_seen``) where the row has it, else against the room it stands in."""
    for k in ("view_accuracy_seen", "view_accuracy"):
        v = finite_float(row.get(k))
        if v is not None:
            return v
    return None


def figure_size(map_shape: tuple[int, int], n_panels: int = 3) -> tuple[float, float]:
    """(width, height) in inches of a figure of ``n_panels`` maps of ``map_shape`` (H, W) pixels
    side by side, with a title row and a legend column."""
    h, w = map_shape
    panel_w = float(np.clip(PANEL_H * w / max(h, 1), 0.45 * PANEL_H, 1.8 * PANEL_H))
    return n_panels * panel_w + _LEGEND_W, PANEL_H + _TITLE_H


def _panels(scene: Scene, n: int = 3):
    """A fixed-size figure with ``n`` map axes and a legend axis at the right."""
    fw, fh = figure_size(scene.grid.shape, n)
    fig = plt.figure(figsize=(fw, fh), dpi=DPI)
    gs = fig.add_gridspec(1, n + 1, width_ratios=[(fw - _LEGEND_W) / n] * n + [_LEGEND_W],
                          left=0.01, right=0.99, bottom=0.02, top=PANEL_H / fh - 0.02, wspace=0.04)
    axes = [fig.add_subplot(gs[0, i]) for i in range(n)]
    leg = fig.add_subplot(gs[0, n])
    leg.axis("off")
    add_legend(leg, scene.classes, loc="center left", bbox_to_anchor=(0.0, 0.5),
               extra=[("border between rooms", (25, 25, 25))])
    return fig, axes


def _save_fixed(fig, path: str | Path, title: str, formats: Sequence[str] | None = None) -> list[Path]:
    """Title (wrapped to the figure width), then save at :data:`DPI` without cropping (the PNG
    is exactly figure_size * DPI)."""
    import textwrap

    chars = max(int(fig.get_figwidth() * 72 / 5.2), 30)  # 9 pt text: about 5.2 pt per character
    fig.suptitle("\n".join(textwrap.wrap(title, chars)[:2]), fontsize=9, y=1 - 0.06 / fig.get_figheight(),
                 va="top")
    return save(fig, path, formats, tight=False)


def _check_map(name: str, labels: np.ndarray, scene: Scene) -> np.ndarray:
    labels = np.asarray(labels)
    if labels.shape != scene.grid.shape:
        raise ValueError(f"{name} label map has shape {labels.shape}, expected the scene's map shape "
                         f"{scene.grid.shape}")
    return labels.astype(np.int32)


def figure_postprocess(scene: Scene, raw: np.ndarray, post: np.ndarray, path: str | Path, title: str = "",
                       formats: Sequence[str] | None = None) -> list[Path]:
    """Fig. 3: ground truth | raw prediction | post-processed. ``raw`` and ``post`` are (H, W)
    label maps on ``scene.grid``; the ground truth shows borders between room instances.

    Returns:
        the files written: ``path`` (or ``path`` with each of ``formats``), the PNG
        ``figure_size(scene.grid.shape) * DPI`` pixels.
    """
    raw, post = _check_map("raw", raw, scene), _check_map("post-processed", post, scene)
    fig, axes = _panels(scene)
    res, walk, cls = scene.grid.resolution, scene.grid.walkable, scene.classes
    show_map(axes[0], scene.semantic, cls, walk, res, "ground truth", segments=scene.instances)
    show_map(axes[1], raw, cls, walk, res, "raw prediction")
    show_map(axes[2], post, cls, walk, res, "post-processed")
    return _save_fixed(fig, path, title or scene.house_id, formats)


def figure_aggregators(scene: Scene, poses: np.ndarray, knn: np.ndarray, cone: np.ndarray, path: str | Path,
                       proba: np.ndarray | None = None, max_poses: int = 60, title: str = "",
                       formats: Sequence[str] | None = None) -> list[Path]:
    """Fig. 4: ground truth with sample viewpoints | graph KNN | vision cone.

    ``poses`` (N, 3) [x, z, yaw_deg]; up to ``max_poses`` of them, evenly spread, are drawn
    with heading arrows, coloured by their predicted class when ``proba`` (N, C) is given.
    ``knn`` and ``cone`` are (H, W) label maps on ``scene.grid``.

    Returns:
        the files written.
    """
    from envs.world.classes import class_colors

    knn, cone = _check_map("graph KNN", knn, scene), _check_map("vision cone", cone, scene)
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    if proba is not None and len(proba) != len(poses):
        raise ValueError(f"proba has {len(proba)} rows, expected one per pose ({len(poses)})")
    fig, axes = _panels(scene)
    res, walk, cls = scene.grid.resolution, scene.grid.walkable, scene.classes
    n_drawn = min(max_poses, len(poses))
    show_map(axes[0], scene.semantic, cls, walk, res, f"ground truth, {n_drawn} of {len(poses)} views",
             segments=scene.instances)
    if len(poses):
        pick = np.unique(np.linspace(0, len(poses) - 1, n_drawn).astype(int))
        r, c = scene.grid.world_to_pixel(poses[pick, 0], poses[pick, 1])
        colors = None
        if proba is not None:
            colors = np.array(class_colors(cls))[np.argmax(proba[pick], axis=1)] / 255
        draw_poses(axes[0], r - 0.5, c - 0.5, poses[pick, 2], colors=colors, size=14)
    show_map(axes[1], knn, cls, walk, res, "graph KNN")
    show_map(axes[2], cone, cls, walk, res, "vision cone")
    return _save_fixed(fig, path, title or scene.house_id, formats)


def figure_autotrace(scene: Scene, paths: Sequence[np.ndarray], poses: np.ndarray, path: str | Path,
                     labels: np.ndarray | None = None, title: str = "",
                     formats: Sequence[str] | None = None) -> list[Path]:
    """Fig. 2: the autotrace path (``paths``: (M, 2) row/col contours) and its viewpoints
    (``poses`` (N, 3)), coloured by a per-point class index ``labels`` (N,) if given.

    Returns:
        the files written.
    """
    from envs.world.classes import class_colors

    fig, ax = plt.subplots(figsize=(6.5, 5.5))
    ax.imshow(scene.grid.walkable, cmap="gray", interpolation="nearest")
    for cnt in paths:
        closed = np.vstack([cnt, cnt[:1]])
        ax.plot(closed[:, 1], closed[:, 0], color="#0072B2", lw=0.8)
    r, c = scene.grid.world_to_pixel(poses[:, 0], poses[:, 1])
    colors = None if labels is None else np.array(class_colors(scene.classes))[labels] / 255
    draw_poses(ax, r - 0.5, c - 0.5, poses[:, 2], colors=colors, size=10, arrow_px=5)
    ax.set_xticks([])
    ax.set_yticks([])
    import textwrap

    ax.set_title("\n".join(textwrap.wrap(title or f"{scene.house_id}: autotrace path, {len(poses)} viewpoints", 80)),
                 fontsize=9)
    add_scale_bar(ax, scene.grid.resolution, color="white")
    if labels is not None:
        add_legend(ax, scene.classes, unlabelled=False)
    return save(fig, path, formats)


def place_labels(anchors: np.ndarray, size: tuple[float, float], bounds: tuple[float, float, float, float]
                 ) -> np.ndarray:
    """Non-overlapping positions for boxes of ``size`` (w, h) near ``anchors`` (N, 2) x, y.

    Greedy: each box in turn takes the first of a spiral of offsets around its anchor that
    overlaps no box placed before and stays inside ``bounds`` (x0, y0, x1, y1); when none
    does, the free candidate nearest the anchor in a wider search. Returns (N, 2) centres.
    """
    w, h = size
    x0, y0, x1, y1 = bounds
    offsets = [(0.0, 0.0)]
    for ring in range(1, 40):
        for k in range(8 * ring):
            a = 2 * np.pi * k / (8 * ring)
            offsets.append((ring * w * 0.6 * np.cos(a), ring * h * 0.9 * np.sin(a)))
    placed: list[tuple[float, float]] = []
    for ax_, ay in np.asarray(anchors, float).reshape(-1, 2):
        best = None
        for dx, dy in offsets:
            cx = float(np.clip(ax_ + dx, x0 + w / 2, x1 - w / 2))
            cy = float(np.clip(ay + dy, y0 + h / 2, y1 - h / 2))
            if all(abs(cx - px) >= w or abs(cy - py) >= h for px, py in placed):
                best = (cx, cy)
                break
        placed.append(best if best is not None else (float(ax_), float(ay)))
    return np.array(placed).reshape(-1, 2)


def figure_view(scene: Scene, pose, path: str | Path, fov: float = 90.0, max_range: float = 6.0,
                occluder_height: float = 1.2, formats: Sequence[str] | None = None) -> list[Path]:
    """One view: the floor cells its camera sees (lightened), the objects it sees outlined and
    numbered on the map (numbers placed so that none overlaps another), and beside the map
    the list ``number. object type: share of rays``.

    ``pose`` (x, z, yaw_deg). Returns the files written.
    """
    from envs.render.floorplan import occluders, view_from

    v = view_from(scene, occluders(scene, occluder_height), pose, fov, max_range / scene.grid.resolution)
    fig = plt.figure(figsize=(9.0, 5.6))
    gs = fig.add_gridspec(1, 2, width_ratios=[3.2, 1.3], wspace=0.03, left=0.01, right=0.99, top=0.92, bottom=0.02)
    ax, side = fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[0, 1])
    show_map(ax, scene.semantic, scene.classes, scene.grid.walkable, scene.grid.resolution,
             f"{scene.house_id}: what one camera sees ({fov:g}° field of view, up to {max_range:g} m)",
             segments=scene.instances)
    seen = np.zeros(scene.grid.shape, bool)
    seen[v.rows, v.cols] = True
    overlay = np.zeros((*scene.grid.shape, 4))
    overlay[seen] = (1, 1, 1, 0.55)
    ax.imshow(overlay, interpolation="nearest")
    r, c = scene.grid.world_to_pixel(pose[0], pose[1])
    draw_poses(ax, np.array([r - 0.5]), np.array([c - 0.5]), np.array([pose[2]]), size=40, arrow_px=12)
    items = sorted(v.object_rays.items(), key=lambda t: -t[1])
    h_px, w_px = scene.grid.shape
    centres = []
    for k, _ in items:
        o = scene.objects[k]
        corners = np.array([scene.grid.world_to_pixel(x, z) for x, z in o.corners()])
        ax.fill(corners[:, 1] - 0.5, corners[:, 0] - 0.5, facecolor="none", edgecolor="k", lw=1.0)
        cr, cc = scene.grid.world_to_pixel(*o.center)
        centres.append((cc, cr))
    box = (0.045 * max(h_px, w_px), 0.04 * max(h_px, w_px))  # label box in map pixels (w, h)
    spots = place_labels(np.array(centres, float).reshape(-1, 2), box, (0, 0, w_px, h_px))
    for i, ((cx, cy), (sx, sy)) in enumerate(zip(centres, spots), start=1):
        if abs(sx - cx) + abs(sy - cy) > 1:
            ax.plot([cx, sx], [cy, sy], color="k", lw=0.5)
        ax.text(sx, sy, str(i), fontsize=6, ha="center", va="center",
                bbox=dict(boxstyle="circle,pad=0.15", facecolor="white", edgecolor="k", lw=0.5))
    ax.set_xlim(-0.5, w_px - 0.5)
    ax.set_ylim(h_px - 0.5, -0.5)
    side.axis("off")
    lines = [f"{i:>2}. {scene.objects[k].object_type}: {n / max(v.n_rays, 1):.0%}"
             for i, (k, n) in enumerate(items, start=1)]
    side.text(0.0, 1.0, "objects seen (share of rays)\n" + "\n".join(lines[:40]) +
              (f"\n... and {len(lines) - 40} more" if len(lines) > 40 else ""),
              va="top", ha="left", fontsize=7, family="monospace", transform=side.transAxes)
    add_legend(side, scene.classes, loc="lower left", bbox_to_anchor=(0.0, 0.0),
               extra=[("seen by the camera", (245, 245, 245))])
    return save(fig, path, formats)


def merge_overrides(defaults: dict[str, str], overrides: Sequence[str]) -> list[str]:
    """Hydra overrides: ``defaults`` (group -> option) unless ``overrides`` sets the same key."""
    for o in overrides:
        if "=" not in o:
            raise ValueError(f"override {o!r} is not of the form key=value (e.g. classifier=objects)")
    given = {o.split("=", 1)[0].lstrip("+~") for o in overrides}
    return [f"{k}={v}" for k, v in defaults.items() if k not in given] + list(overrides)


def compose_config(overrides: Sequence[str]):
    """The root config of ``conf/`` with Hydra ``overrides`` -> (config, group choices)."""
    from benchmark.config import compose_job

    return compose_job(overrides)


def house_maps(overrides: Sequence[str], house_index: int
               ) -> tuple[Scene, dict[str, np.ndarray], dict[str, str], dict]:
    """Run house number ``house_index`` of the configured env through the cached pipeline.

    Returns (scene, maps, names, row): ``maps`` holds the cached ``raw`` and ``post`` (H, W)
    label maps, ``poses`` (N, 3) and ``proba`` (N, C); ``names`` the stage names; ``row`` the
    house's metrics row. Cached stages are reused; missing ones are computed and cached
    (``run.cache_dir``)."""
    from benchmark.harness.cache import load_npz
    from benchmark.harness.runner import build_pipeline

    cfg, choices = compose_config(overrides)
    if cfg.get("segmenter") is not None:
        raise ValueError("figures need a classifier + aggregator configuration, not segmenter=...")
    cfg.run.save_maps = True
    pipe = build_pipeline(cfg, choices)
    ids = pipe.env.house_ids()
    if not 0 <= house_index < len(ids):
        raise ValueError(f"--house-index {house_index} is out of range: env {choices.get('env')!r} has "
                         f"{len(ids)} houses (0..{len(ids) - 1})")
    hid = ids[house_index]
    if hasattr(pipe.classifier, "setup"):
        pipe.classifier.setup([hid])
    if not pipe.entry("maps", hid).exists():
        pipe.force = set(pipe.force) | {"score"}
    row = pipe.run_house(hid)
    if row.get("status") != "ok":
        raise RuntimeError(f"house {hid!r} failed in the pipeline: {row.get('error')}")
    maps = load_npz(pipe.entry("maps", hid))
    maps["raw"], maps["post"] = maps["raw"].astype(np.int32), maps["post"].astype(np.int32)
    return pipe.env.scene(hid), maps, dict(pipe.names), row


def fig3(house_index: int, out: str | Path, overrides: Sequence[str] = (),
         formats: Sequence[str] | None = None) -> list[Path]:
    """Fig. 3 for one house and configuration (defaults :data:`FIG3_DEFAULTS`).

    Returns:
        the files written (``out``, or ``out`` with each of ``formats``)."""
    ov = merge_overrides(FIG3_DEFAULTS, overrides)
    cfg, _ = compose_config(ov)
    if cfg.get("postprocess") is None or str(cfg.postprocess.get("_target_", "")).endswith("NoPostProcess"):
        raise ValueError("fig3 compares raw and post-processed maps: it needs a post-processing config "
                         "(postprocess=default), not postprocess=none")
    scene, maps, names, row = house_maps(ov, house_index)
    title = (f"{house_title(names, scene.house_id)}: "
             f"{describe(names, finite_float(cfg.classifier.get('accuracy')), view_accuracy(row), post=False)}"
             f"; post-processing '{names['postprocess']}'")
    return figure_postprocess(scene, maps["raw"], maps["post"], out, title, formats)


def fig4(house_index: int, out: str | Path, overrides: Sequence[str] = (), max_poses: int = 60,
         formats: Sequence[str] | None = None) -> list[Path]:
    """Fig. 4 for one house and configuration (defaults :data:`FIG4_DEFAULTS`): the same views
    aggregated by ``aggregator=graph_knn`` and ``aggregator=vision_cone``.

    Returns:
        the files written."""
    if any(o.lstrip("+~").split("=", 1)[0] == "aggregator" for o in overrides):
        raise ValueError("fig4 draws both graph_knn and vision_cone; do not override aggregator=")
    ov = merge_overrides(FIG4_DEFAULTS, overrides)
    cfg, _ = compose_config(ov)
    scene, knn, names, row = house_maps([*ov, "aggregator=graph_knn"], house_index)
    _, cone, _, _ = house_maps([*ov, "aggregator=vision_cone"], house_index)
    which = "post" if names["postprocess"] != "none" else "raw"
    title = (f"{house_title(names, scene.house_id)}: "
             f"{describe(names, finite_float(cfg.classifier.get('accuracy')), view_accuracy(row), aggregator=False)}"
             f"; viewpoints coloured by predicted class")
    return figure_aggregators(scene, knn["poses"], knn[which], cone[which], out, knn["proba"], max_poses, title,
                              formats)


def house_figures(house_index: int, out: Path, overrides: Sequence[str] = (),
                  formats: Sequence[str] | None = None) -> list[Path]:
    """Fig. 2 (autotrace), Fig. 3, Fig. 4 and one view's cone for one house into folder ``out``:
    ``fig2_autotrace``, ``fig3``, ``fig4``, ``view_cone`` (.png, or each of ``formats``).

    Returns:
        the files written."""
    from hydra.utils import instantiate

    out = Path(out)
    paths = [*fig3(house_index, out / "fig3.png", overrides, formats),
             *fig4(house_index, out / "fig4.png", overrides, formats=formats)]
    cfg, choices = compose_config(merge_overrides(FIG4_DEFAULTS, overrides))
    env = instantiate(cfg.env)
    hid = env.house_ids()[house_index]
    scene, house = env.scene(hid), env.house(hid)
    at = instantiate(cfg.viewpoints)
    poses = at.generate(scene)
    if hasattr(at, "path"):
        from benchmark.config import build_method
        from benchmark.method import Context

        m = build_method(cfg)
        if hasattr(m.classifier, "setup"):
            m.classifier.setup([hid])
        obs = instantiate(cfg.renderer).render(house, scene, poses[::3])
        proba = m.classify(obs, Context(scene=scene, house_id=hid)).proba
        names = {"env": choices.get("env", ""), "classifier": choices.get("classifier", "")}
        title = (f"{house_title(names, hid)}: autotrace path and every third of its {len(poses)} viewpoints, "
                 f"coloured by the {describe(names, finite_float(cfg.classifier.get('accuracy')), aggregator=False, post=False)}")
        paths[:0] = figure_autotrace(scene, at.path(scene.grid), poses[::3], out / "fig2_autotrace.png",
                                     np.argmax(proba, axis=1), title, formats)
        n_seen = [len(o.objects) for o in obs]
        paths += figure_view(scene, poses[::3][int(np.argmax(n_seen))], out / "view_cone.png", formats=formats)
    return paths


def from_run(run_dir: Path, out: Path, houses: Sequence[str] | str | None = None,
             formats: Sequence[str] | None = None, workers: int | None = None, last_sweep: bool = False) -> list[Path]:
    """Fig. 3 (every configuration with post-processing) and Fig. 4 (every classifier x
    post-processing with both graph KNN and vision cone) from a finished sweep's saved maps.

    ``houses``: house ids to draw (per dataset, those the dataset has); default the first
    house every job of a dataset scored. Maps are read through the run store
    (:meth:`benchmark.harness.store.Job.maps_path`). ``workers``: figures drawn at once, in
    forked worker processes (None: ``ROOMSEG_JOBS``, else the cores this process may run on; 1: in this
    process). ``last_sweep``: only the jobs of the last multirun into ``run_dir`` (its
    ``last_sweep.json``, :func:`benchmark.harness.store.sweep_scope`).

    Returns:
        the files written.

    Raises:
        ValueError: a requested house that no job of the run scored.
    """
    from hydra.utils import instantiate
    from omegaconf import OmegaConf

    from benchmark.harness.cache import load_npz
    from benchmark.harness.store import RUN_SUMMARY_MAPPINGS, find_jobs, safe_name, sweep_scope
    from benchmark.reports.tables import read_rows

    if isinstance(houses, str):
        houses = [houses]
    jobs = []
    for job in find_jobs(sweep_scope([run_dir], True).files if last_sweep else [run_dir]):
        df = read_rows(job.metrics_path)  # the checks of every reader of rows: one line naming the file
        df["house_id"] = df["house_id"].astype(str)
        jobs.append((job, job.config(), job.summary(RUN_SUMMARY_MAPPINGS), df))
    scenes: dict[tuple, Scene] = {}

    def scene_for(cfg, hid):
        key = (OmegaConf.to_yaml(cfg.env), hid)
        if key not in scenes:
            scenes[key] = instantiate(cfg.env).scene(hid)
        return scenes[key]

    ok_by_env: dict[str, list[set]] = {}
    for _, _, summary, df in jobs:
        if summary["names"].get("segmenter"):
            continue
        ok_by_env.setdefault(summary["names"]["env"], []).append(set(df.loc[df["status"] == "ok", "house_id"]))
    if houses:
        scored = set().union(*(s for sets in ok_by_env.values() for s in sets)) if ok_by_env else set()
        missing = [h for h in houses if h not in scored]
        if missing:
            raise ValueError(f"--house {missing[0]!r}: no job of {run_dir} scored it; scored houses are e.g. "
                             f"{sorted(scored)[:3]}")
        picks = {env: [h for h in houses if any(h in s for s in sets)] for env, sets in ok_by_env.items()}
    else:
        picks = {env: (sorted(set.intersection(*ids)) or [])[:1] for env, ids in ok_by_env.items()}
    tasks: list[Callable[[], list[Path]]] = []
    groups: dict[tuple, dict[str, tuple]] = {}
    for job, cfg, summary, df in jobs:
        names = summary["names"]
        if names.get("segmenter"):
            continue
        for hid in picks.get(names["env"], []):
            row = df[df["house_id"] == hid]
            if row.empty or row["status"].iloc[0] != "ok":
                continue
            try:
                p = job.maps_path(hid)
            except KeyError:
                continue
            if not p.exists():
                continue
            m = load_npz(p)
            row = row.iloc[0].to_dict()
            acc = finite_float(row.get("oracle_accuracy"))
            slug = "_".join(names[k] for k in ("env", "classifier", "aggregator", "postprocess"))
            if acc is not None:
                slug = slug.replace(f"_{names['classifier']}_", f"_{names['classifier']}{acc:g}_", 1)
            if names["postprocess"] != "none":
                title = (f"{house_title(names, hid)}: {describe(names, acc, view_accuracy(row), post=False)}"
                         f"; post-processing '{names['postprocess']}'")
                tasks.append(partial(figure_postprocess, scene_for(cfg, hid), m["raw"], m["post"],
                                     out / f"fig3_{safe_name(hid)}_{slug}.png", title, formats))
            key = (names["env"], names["classifier"], acc, names["postprocess"], hid)
            groups.setdefault(key, {})[names["aggregator"]] = (cfg, m, row, names)
    for (env, clf, acc, post, hid), by_agg in groups.items():
        if "graph_knn" in by_agg and "vision_cone" in by_agg:
            cfg, mk, row, names = by_agg["graph_knn"]
            _, mc, _, _ = by_agg["vision_cone"]
            title = (f"{house_title(names, hid)}: "
                     f"{describe(names, acc, view_accuracy(row), aggregator=False)}; "
                     f"viewpoints coloured by predicted class")
            which = "post" if post != "none" else "raw"
            clf_slug = clf + (f"{acc:g}" if acc is not None else "")
            tasks.append(partial(figure_aggregators, scene_for(cfg, hid), mk["poses"], mk[which], mc[which],
                                 out / f"fig4_{safe_name(hid)}_{env}_{clf_slug}_{post}.png", mk["proba"],
                                 title=title, formats=formats))
    from benchmark.harness.processes import run_forked

    return [p for paths in run_forked(tasks, workers) for p in paths]


