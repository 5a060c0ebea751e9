"""The paper's figures, in fixed class colours with a legend and a scale bar.

* Fig. 3: ground truth | raw prediction | post-processed, for one house.
* Fig. 4: ground truth with sample viewpoints | graph KNN | vision cone, for one house.
* Fig. 2: the autotrace path and its sampled viewpoints on the map; and one view's cone
  with the objects it sees.

``python -m benchmark.figures house --house-index 80 --out docs/figures`` runs the offline
pipeline (autotrace, floorplan renderer, oracle classifier at ``--accuracy``) on a shared
house and draws them all. ``python -m benchmark.figures from-run results/runs/bench --out DIR``
draws Fig. 3 and Fig. 4 from a sweep's cached label maps (``run.save_maps``).
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Sequence
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from benchmark.plotting import add_legend, draw_poses, save, show_map
from envs.scene import Scene


def figure_postprocess(scene: Scene, raw: np.ndarray, post: np.ndarray, path: str | Path, title: str = "") -> None:
    """Fig. 3: ground truth | raw prediction | post-processed."""
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.8))
    res, walk, cls = scene.grid.resolution, scene.grid.walkable, scene.classes
    show_map(axes[0], scene.semantic, cls, walk, res, "ground truth")
    show_map(axes[1], raw, cls, walk, res, "raw prediction")
    show_map(axes[2], post, cls, walk, res, "post-processed")
    add_legend(axes[2], cls)
    fig.suptitle(title or scene.house_id, fontsize=10)
    save(fig, path)


def figure_aggregators(scene: Scene, poses: np.ndarray, knn: np.ndarray, cone: np.ndarray, path: str | Path,
                       proba: np.ndarray | None = None, max_poses: int = 60, title: str = "") -> None:
    """Fig. 4: ground truth with sample viewpoints | graph KNN | vision cone."""
    from envs.classes import class_colors

    fig, axes = plt.subplots(1, 3, figsize=(14, 4.8))
    res, walk, cls = scene.grid.resolution, scene.grid.walkable, scene.classes
    show_map(axes[0], scene.semantic, cls, walk, res, "ground truth + viewpoints")
    pick = np.linspace(0, len(poses) - 1, min(max_poses, len(poses))).astype(int) if len(poses) else []
    r, c = scene.grid.world_to_pixel(poses[pick, 0], poses[pick, 1])
    colors = None
    if proba is not None:
        colors = np.array(class_colors(cls))[np.argmax(proba[pick], axis=1)] / 255
    draw_poses(axes[0], r - 0.5, c - 0.5, poses[pick, 2], colors=colors, size=14)
    show_map(axes[1], knn, cls, walk, res, "graph KNN")
    show_map(axes[2], cone, cls, walk, res, "vision cone")
    add_legend(axes[2], cls)
    fig.suptitle(title or scene.house_id, fontsize=10)
    save(fig, path)


def figure_autotrace(scene: Scene, paths: Sequence[np.ndarray], poses: np.ndarray, path: str | Path,
                     labels: np.ndarray | None = None) -> None:
    """Fig. 2: the autotrace path and its viewpoints, coloured by a per-point label if given."""
    from envs.classes import class_colors

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
    from benchmark.plotting import add_scale_bar

    add_scale_bar(ax, scene.grid.resolution, color="tab:red")
    if labels is not None:
        add_legend(ax, scene.classes, unlabelled=False)
    save(fig, path)


def figure_view(scene: Scene, pose, path: str | Path, fov: float = 90.0, max_range: float = 6.0,
                occluder_height: float = 1.2) -> None:
    """One view: the floor cells its camera sees, and the objects it sees with their share of rays."""
    from envs.floorplan import occluders, view_from

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


def house_figures(house_index: int, out: Path, accuracy: float = 0.8, houses: Path | None = None) -> list[Path]:
    """Run the offline pipeline on one shared house and draw Fig. 2, 3 and 4."""
    from benchmark.aggregators.graph_knn import GraphKNN
    from benchmark.aggregators.vision_cone import VisionCone
    from benchmark.classifiers.oracle import OracleClassifier
    from benchmark.postprocess import PostProcess
    from benchmark.viewpoints import Autotrace
    from envs.floorplan import FloorplanRenderer
    from envs.house import load_houses
    from envs.scene import rasterise_house

    houses = houses or Path(os.environ.get("ROOMSEG_SHARED_DATA", "../shared/data")) / \
        "procthor/procthor-10k-uniform-hard-val.jsonl.gz"
    found = load_houses(houses, house_index, house_index + 1)
    if not found:
        raise ValueError(f"{houses} has no house at index {house_index}")
    house = found[0]
    scene = rasterise_house(house)
    at = Autotrace()
    poses = at.generate(scene)
    obs = FloorplanRenderer().render(house, scene, poses)
    proba = OracleClassifier(accuracy=accuracy).predict_proba(obs)
    knn = GraphKNN()(scene.grid, poses, proba)
    cone = VisionCone()(scene.grid, poses, proba)
    post = PostProcess()(cone, scene.grid)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / "fig2_autotrace.png", out / "fig3_postprocess.png", out / "fig4_aggregators.png",
             out / "view_cone.png"]
    tag = f"{scene.house_id}, oracle classifier at {accuracy:.0%} accuracy"
    figure_autotrace(scene, at.path(scene.grid), poses[::3], paths[0], np.argmax(proba[::3], axis=1))
    figure_postprocess(scene, cone, post, paths[1], f"{tag}, vision cone")
    figure_aggregators(scene, poses, knn, cone, paths[2], proba, title=tag)
    n_seen = [len(o.objects) for o in obs]
    figure_view(scene, poses[int(np.argmax(n_seen))], paths[3])
    return paths


def from_run(run_dir: Path, out: Path, house: str | None = None) -> list[Path]:
    """Fig. 3 and Fig. 4 for one house from a sweep's cached maps (the first house if none given)."""
    from hydra.utils import instantiate
    from omegaconf import OmegaConf

    from benchmark.cache import load_npz, read_json, safe_name

    jobs = []
    for cfg_path in sorted(Path(run_dir).rglob("resolved_config.yaml")):
        job = cfg_path.parent
        if not (job / "summary.json").exists() or not (job / "metrics.csv").exists():
            continue
        cfg = OmegaConf.load(cfg_path)
        summary = read_json(job / "summary.json")
        df = pd.read_csv(job / "metrics.csv")
        jobs.append((cfg, summary, df))
    if not jobs:
        raise FileNotFoundError(f"no finished run (resolved_config.yaml + summary.json) under {run_dir}")
    written = []
    scenes: dict[tuple, Scene] = {}

    def maps_for(cfg, summary, hid):
        p = Path(cfg.run.results_dir) / "cache" / "maps" / summary["keys"]["score"] / f"{safe_name(hid)}.npz"
        return load_npz(p) if p.exists() else None

    def scene_for(cfg, hid):
        key = (OmegaConf.to_yaml(cfg.env), hid)
        if key not in scenes:
            scenes[key] = instantiate(cfg.env).scene(hid)
        return scenes[key]

    # one house per dataset: the first house every job of that dataset scored
    ok_by_env: dict[str, list[set]] = {}
    for _, summary, df in jobs:
        ok_by_env.setdefault(summary["names"]["env"], []).append(set(df.loc[df["status"] == "ok", "house_id"]))
    picks = {env: house or (sorted(set.intersection(*ids)) or [None])[0] for env, ids in ok_by_env.items()}
    groups: dict[tuple, dict[str, tuple]] = {}
    for cfg, summary, _ in jobs:
        names = summary["names"]
        pick = picks.get(names["env"])
        if names.get("segmenter") or pick is None:
            continue
        m = maps_for(cfg, summary, pick)
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="the paper's figures")
    sub = ap.add_subparsers(dest="cmd", required=True)
    h = sub.add_parser("house", help="run the offline pipeline on a shared house and draw Fig. 2-4")
    h.add_argument("--house-index", type=int, default=80)
    h.add_argument("--accuracy", type=float, default=0.8, help="oracle classifier accuracy")
    h.add_argument("--houses", type=Path, default=None)
    h.add_argument("--out", type=Path, default=Path("docs/figures"))
    r = sub.add_parser("from-run", help="Fig. 3 and 4 from a sweep's cached maps")
    r.add_argument("run_dir", type=Path)
    r.add_argument("--house", default=None)
    r.add_argument("--out", type=Path, default=Path("results/figures"))
    a = ap.parse_args(argv)
    paths = house_figures(a.house_index, a.out, a.accuracy, a.houses) if a.cmd == "house" else \
        from_run(a.run_dir, a.out, a.house)
    for p in paths:
        print(p)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
