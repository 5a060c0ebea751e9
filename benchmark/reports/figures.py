"""The paper's figures, in fixed class colours with a legend and a scale bar on every map.

* Fig. 3: ground truth | raw prediction | post-processed, for one house.
* Fig. 4: ground truth with sample viewpoints | graph KNN | vision cone, for one house.
* Fig. 2: the autotrace path and its sampled viewpoints on the map; and one view's cone
  with the objects it sees.

Fig. 3 and Fig. 4 are drawn from the runner's caches: the command composes the Hydra
config of ``conf/`` with the given overrides, runs the house through
:class:`benchmark.harness.pipeline.Pipeline` (which reuses cached renders, classifications and
label maps, and computes and caches whatever is missing) and draws the cached maps::

    python -m benchmark.commands.figures fig3 --house-index 80 --out docs/figures/fig3.png
    python -m benchmark.commands.figures fig4 --house-index 80 --out docs/figures/fig4.png classifier=objects
    python -m benchmark.commands.figures house --house-index 80 --out docs/figures   # Fig. 2, 3, 4 + one view
    python -m benchmark.commands.figures from-run results/runs/bench --out DIR       # every config of a sweep

Defaults: ``env=procthor_shared classifier=oracle`` (80 % accuracy), Fig. 3 with
``aggregator=vision_cone postprocess=default``, Fig. 4 with ``postprocess=none`` (the
aggregators' raw output). The figure functions take arrays only.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from benchmark.reports.plotting import add_legend, draw_poses, save, show_map
from envs.maps.scene import Scene

#: dots per inch of the Fig. 3 / Fig. 4 PNGs (their pixel size is ``figure_size(...) * DPI``).
DPI = 110
#: height of one map panel, inches; its width follows the map's aspect ratio (clipped).
PANEL_H = 4.2
_TITLE_H, _LEGEND_W = 0.45, 1.45

FIG3_DEFAULTS = {"env": "procthor_shared", "classifier": "oracle", "aggregator": "vision_cone",
                 "postprocess": "default"}
FIG4_DEFAULTS = {"env": "procthor_shared", "classifier": "oracle", "postprocess": "none"}


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
    add_legend(leg, scene.classes, loc="center left", bbox_to_anchor=(0.0, 0.5))
    return fig, axes


def _save_fixed(fig, path: str | Path, title: str) -> None:
    """Title, then save at :data:`DPI` without cropping (the PNG is exactly figure_size * DPI)."""
    fig.suptitle(title, fontsize=9, y=1 - 0.12 / fig.get_figheight())
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def _check_map(name: str, labels: np.ndarray, scene: Scene) -> np.ndarray:
    labels = np.asarray(labels)
    if labels.shape != scene.grid.shape:
        raise ValueError(f"{name} label map has shape {labels.shape}, expected the scene's map shape "
                         f"{scene.grid.shape}")
    return labels.astype(np.int32)


def figure_postprocess(scene: Scene, raw: np.ndarray, post: np.ndarray, path: str | Path, title: str = "") -> None:
    """Fig. 3: ground truth | raw prediction | post-processed. ``raw`` and ``post`` are (H, W)
    label maps on ``scene.grid``; writes a PNG of ``figure_size(scene.grid.shape) * DPI`` px."""
    raw, post = _check_map("raw", raw, scene), _check_map("post-processed", post, scene)
    fig, axes = _panels(scene)
    res, walk, cls = scene.grid.resolution, scene.grid.walkable, scene.classes
    show_map(axes[0], scene.semantic, cls, walk, res, "ground truth")
    show_map(axes[1], raw, cls, walk, res, "raw prediction")
    show_map(axes[2], post, cls, walk, res, "post-processed")
    _save_fixed(fig, path, title or scene.house_id)


def figure_aggregators(scene: Scene, poses: np.ndarray, knn: np.ndarray, cone: np.ndarray, path: str | Path,
                       proba: np.ndarray | None = None, max_poses: int = 60, title: str = "") -> None:
    """Fig. 4: ground truth with sample viewpoints | graph KNN | vision cone.

    ``poses`` (N, 3) [x, z, yaw_deg]; up to ``max_poses`` of them, evenly spread, are drawn
    with heading arrows, coloured by their predicted class when ``proba`` (N, C) is given.
    ``knn`` and ``cone`` are (H, W) label maps on ``scene.grid``."""
    from envs.world.classes import class_colors

    knn, cone = _check_map("graph KNN", knn, scene), _check_map("vision cone", cone, scene)
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    if proba is not None and len(proba) != len(poses):
        raise ValueError(f"proba has {len(proba)} rows, expected one per pose ({len(poses)})")
    fig, axes = _panels(scene)
    res, walk, cls = scene.grid.resolution, scene.grid.walkable, scene.classes
    show_map(axes[0], scene.semantic, cls, walk, res, f"ground truth + viewpoints ({len(poses)} views)")
    if len(poses):
        pick = np.unique(np.linspace(0, len(poses) - 1, min(max_poses, len(poses))).astype(int))
        r, c = scene.grid.world_to_pixel(poses[pick, 0], poses[pick, 1])
        colors = None
        if proba is not None:
            colors = np.array(class_colors(cls))[np.argmax(proba[pick], axis=1)] / 255
        draw_poses(axes[0], r - 0.5, c - 0.5, poses[pick, 2], colors=colors, size=14)
    show_map(axes[1], knn, cls, walk, res, "graph KNN")
    show_map(axes[2], cone, cls, walk, res, "vision cone")
    _save_fixed(fig, path, title or scene.house_id)


def figure_autotrace(scene: Scene, paths: Sequence[np.ndarray], poses: np.ndarray, path: str | Path,
                     labels: np.ndarray | None = None) -> None:
    """Fig. 2: the autotrace path and its viewpoints, coloured by a per-point label if given."""
    from envs.world.classes import class_colors

    fig, ax = plt.subplots(figsize=(7, 6))
    ax.imshow(scene.grid.walkable, cmap="gray", interpolation="nearest")
    for cnt in paths:
        closed = np.vstack([cnt, cnt[:1]])
        ax.plot(closed[:, 1], closed[:, 0], color="tab:blue", lw=0.8)
    r, c = scene.grid.world_to_pixel(poses[:, 0], poses[:, 1])
    colors = None if labels is None else np.array(class_colors(scene.classes))[labels] / 255
    draw_poses(ax, r - 0.5, c - 0.5, poses[:, 2], colors=colors, size=10, arrow_px=5)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(f"{scene.house_id}: autotrace path, {len(poses)} poses", fontsize=10)
    from benchmark.reports.plotting import add_scale_bar

    add_scale_bar(ax, scene.grid.resolution, color="tab:red")
    if labels is not None:
        add_legend(ax, scene.classes, unlabelled=False)
    save(fig, path)


def figure_view(scene: Scene, pose, path: str | Path, fov: float = 90.0, max_range: float = 6.0,
                occluder_height: float = 1.2) -> None:
    """One view: the floor cells its camera sees, and the objects it sees with their share of rays."""
    from envs.render.floorplan import occluders, view_from

    v = view_from(scene, occluders(scene, occluder_height), pose, fov, max_range / scene.grid.resolution)
    fig, ax = plt.subplots(figsize=(8, 6.5))
    show_map(ax, scene.semantic, scene.classes, scene.grid.walkable, scene.grid.resolution,
             f"{scene.house_id}: one view ({fov:g} deg, {max_range:g} m)")
    seen = np.zeros(scene.grid.shape, bool)
    seen[v.rows, v.cols] = True
    overlay = np.zeros((*scene.grid.shape, 4))
    overlay[seen] = (1, 1, 1, 0.55)
    ax.imshow(overlay, interpolation="nearest")
    r, c = scene.grid.world_to_pixel(pose[0], pose[1])
    draw_poses(ax, np.array([r - 0.5]), np.array([c - 0.5]), np.array([pose[2]]), size=40, arrow_px=12)
    for k, n in sorted(v.object_rays.items(), key=lambda t: -t[1]):
        o = scene.objects[k]
        cr, cc = scene.grid.world_to_pixel(*o.center)
        corners = np.array([scene.grid.world_to_pixel(x, z) for x, z in o.corners()])
        ax.fill(corners[:, 1] - 0.5, corners[:, 0] - 0.5, facecolor="none", edgecolor="k", lw=1.2)
        ax.text(cc, cr, f"{o.object_type}\n{n / max(v.n_rays, 1):.0%}", fontsize=7, ha="center", va="center",
                bbox=dict(facecolor="white", alpha=0.8, pad=1, lw=0))
    add_legend(ax, scene.classes)
    save(fig, path)


def merge_overrides(defaults: dict[str, str], overrides: Sequence[str]) -> list[str]:
    """Hydra overrides: ``defaults`` (group -> option) unless ``overrides`` sets the same key."""
    for o in overrides:
        if "=" not in o:
            raise ValueError(f"override {o!r} is not of the form key=value (e.g. classifier=objects)")
    given = {o.split("=", 1)[0].lstrip("+~") for o in overrides}
    return [f"{k}={v}" for k, v in defaults.items() if k not in given] + list(overrides)


def compose_config(overrides: Sequence[str]):
    """The root config of ``conf/`` with Hydra ``overrides`` -> (config, group choices)."""
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from benchmark.harness.runner import CONF_DIR

    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        full = compose(config_name="config", overrides=list(overrides), return_hydra_config=True)
    choices = {k: (str(v) if v is not None else "") for k, v in full.hydra.runtime.choices.items()
               if not k.startswith("hydra")}
    cfg = OmegaConf.masked_copy(full, [k for k in full if k != "hydra"])
    return cfg, choices


def house_maps(overrides: Sequence[str], house_index: int) -> tuple[Scene, dict[str, np.ndarray], dict[str, str]]:
    """Run house number ``house_index`` of the configured env through the cached pipeline.

    Returns (scene, maps, names): ``maps`` holds the cached ``raw`` and ``post`` (H, W) label
    maps, ``poses`` (N, 3) and ``proba`` (N, C); ``names`` the stage names. Cached stages are
    reused; missing ones are computed and cached (``run.cache_dir``)."""
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
    if not pipe.maps_path(hid).exists():
        pipe.force = set(pipe.force) | {"score"}
    row = pipe.run_house(hid)
    if row.get("status") != "ok":
        raise RuntimeError(f"house {hid!r} failed in the pipeline: {row.get('error')}")
    maps = load_npz(pipe.maps_path(hid))
    maps["raw"], maps["post"] = maps["raw"].astype(np.int32), maps["post"].astype(np.int32)
    return pipe.env.scene(hid), maps, dict(pipe.names)


def _describe(names: dict[str, str], cfg_acc: float | None = None) -> str:
    clf = names["classifier"] + (f" at {cfg_acc:.0%} accuracy" if cfg_acc is not None else "")
    return f"{names['env']}, {names['viewpoints']}, {names['renderer']}, {clf}"


def fig3(house_index: int, out: str | Path, overrides: Sequence[str] = ()) -> Path:
    """Fig. 3 for one house and configuration (defaults :data:`FIG3_DEFAULTS`) -> ``out`` PNG."""
    ov = merge_overrides(FIG3_DEFAULTS, overrides)
    cfg, _ = compose_config(ov)
    if cfg.get("postprocess") is None or str(cfg.postprocess.get("_target_", "")).endswith("NoPostProcess"):
        raise ValueError("fig3 compares raw and post-processed maps: it needs a post-processing config "
                         "(postprocess=default), not postprocess=none")
    scene, maps, names = house_maps(ov, house_index)
    acc = cfg.classifier.get("accuracy")
    title = (f"{scene.house_id}: {_describe(names, acc)}, {names['aggregator']}, "
             f"post-processing {names['postprocess']}")
    figure_postprocess(scene, maps["raw"], maps["post"], out, title)
    return Path(out)


def fig4(house_index: int, out: str | Path, overrides: Sequence[str] = (), max_poses: int = 60) -> Path:
    """Fig. 4 for one house and configuration (defaults :data:`FIG4_DEFAULTS`): the same views
    aggregated by ``aggregator=graph_knn`` and ``aggregator=vision_cone`` -> ``out`` PNG."""
    if any(o.lstrip("+~").split("=", 1)[0] == "aggregator" for o in overrides):
        raise ValueError("fig4 draws both graph_knn and vision_cone; do not override aggregator=")
    ov = merge_overrides(FIG4_DEFAULTS, overrides)
    cfg, _ = compose_config(ov)
    scene, knn, names = house_maps([*ov, "aggregator=graph_knn"], house_index)
    _, cone, _ = house_maps([*ov, "aggregator=vision_cone"], house_index)
    which = "post" if names["postprocess"] != "none" else "raw"
    title = (f"{scene.house_id}: {_describe(names, cfg.classifier.get('accuracy'))}, "
             f"post-processing {names['postprocess']}; viewpoints coloured by predicted class")
    figure_aggregators(scene, knn["poses"], knn[which], cone[which], out, knn["proba"], max_poses, title)
    return Path(out)


def house_figures(house_index: int, out: Path, overrides: Sequence[str] = ()) -> list[Path]:
    """Fig. 2 (autotrace), Fig. 3, Fig. 4 and one view's cone for one house into folder ``out``:
    ``fig2_autotrace.png``, ``fig3.png``, ``fig4.png``, ``view_cone.png``."""
    from hydra.utils import instantiate

    out = Path(out)
    paths = [fig3(house_index, out / "fig3.png", overrides), fig4(house_index, out / "fig4.png", overrides)]
    cfg, _ = compose_config(merge_overrides(FIG4_DEFAULTS, overrides))
    env = instantiate(cfg.env)
    hid = env.house_ids()[house_index]
    scene, house = env.scene(hid), env.house(hid)
    at = instantiate(cfg.viewpoints)
    poses = at.generate(scene)
    if hasattr(at, "path"):
        clf = instantiate(cfg.classifier)
        if hasattr(clf, "setup"):
            clf.setup([hid])
        obs = instantiate(cfg.renderer).render(house, scene, poses[::3])
        proba = clf.predict_proba(obs)
        figure_autotrace(scene, at.path(scene.grid), poses[::3], out / "fig2_autotrace.png",
                         np.argmax(proba, axis=1))
        paths.insert(0, out / "fig2_autotrace.png")
        n_seen = [len(o.objects) for o in obs]
        figure_view(scene, poses[::3][int(np.argmax(n_seen))], out / "view_cone.png")
        paths.append(out / "view_cone.png")
    return paths


def from_run(run_dir: Path, out: Path, house: str | None = None) -> list[Path]:
    """Fig. 3 and Fig. 4 for one house from a sweep's cached maps (the first house if none given)."""
    from hydra.utils import instantiate
    from omegaconf import OmegaConf

    from benchmark.harness.cache import load_npz
    from benchmark.harness.store import find_jobs, safe_name

    jobs = []
    for job in find_jobs([run_dir]):
        jobs.append((job.config(), job.summary(), pd.read_csv(job.metrics_path), job))
    written = []
    scenes: dict[tuple, Scene] = {}

    def maps_for(job, hid):
        try:
            p = job.maps_path(hid)  # the run store knows the entry (key, house content)
        except KeyError:
            return None
        return load_npz(p) if p.exists() else None

    def scene_for(cfg, hid):
        key = (OmegaConf.to_yaml(cfg.env), hid)
        if key not in scenes:
            scenes[key] = instantiate(cfg.env).scene(hid)
        return scenes[key]

    # one house per dataset: the first house every job of that dataset scored
    ok_by_env: dict[str, list[set]] = {}
    for _, summary, df, _ in jobs:
        ok_by_env.setdefault(summary["names"]["env"], []).append(set(df.loc[df["status"] == "ok", "house_id"]))
    picks = {env: house or (sorted(set.intersection(*ids)) or [None])[0] for env, ids in ok_by_env.items()}
    groups: dict[tuple, dict[str, tuple]] = {}
    for cfg, summary, _, job in jobs:
        names = summary["names"]
        pick = picks.get(names["env"])
        if names.get("segmenter") or pick is None:
            continue
        m = maps_for(job, pick)
        if m is None:
            continue
        label = "_".join(names[k] for k in ("env", "classifier", "aggregator", "postprocess"))
        if names["postprocess"] != "none":
            path = out / f"fig3_{safe_name(pick)}_{label}.png"
            figure_postprocess(scene_for(cfg, pick), m["raw"], m["post"], path, f"{pick}: {label}")
            written.append(path)
        key = (names["env"], names["classifier"], names["postprocess"])
        groups.setdefault(key, {})[names["aggregator"]] = (cfg, m)
    for (env, clf, post), by_agg in groups.items():
        pick = picks[env]
        if "graph_knn" in by_agg and "vision_cone" in by_agg:
            cfg, mk = by_agg["graph_knn"]
            _, mc = by_agg["vision_cone"]
            path = out / f"fig4_{safe_name(pick)}_{env}_{clf}_{post}.png"
            figure_aggregators(scene_for(cfg, pick), mk["poses"], mk["post"], mc["post"], path, mk["proba"],
                               title=f"{pick}: {env}, {clf}, post-processing {post}")
            written.append(path)
    return written
