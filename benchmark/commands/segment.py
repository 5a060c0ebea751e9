"""``roomseg-segment``: segment your own map, no Python.

    roomseg-segment map=robot.yaml poses=poses.csv frame=ros labels=labels.csv out=DIR
    roomseg-segment map=robot.yaml poses=views.csv frame=ros images=pics/ classifier=cnn out=DIR
    roomseg-segment map=robot.yaml segmenter=voronoi out=DIR
    roomseg-segment ... aggregator=graph_knn postprocess=none gt=gt.png gt_format=label
    roomseg-segment bag=run.bag out=DIR        (a ROS 1 / ROS 2 bag: map, tf, views; docs/own-robot-data.md)

Arguments are Hydra overrides of ``conf/segment.yaml`` (composed with Hydra's compose API:
the bench app's stage groups and ``_target_`` plug-ins work, and no Hydra output folder is
made). Three modes:

* **labels** (``labels=FILE``, default ``classifier=labels``): each view's class name (or class
  probabilities) from the file, placed on the map by the aggregator, then post-processed;
* **images** (``images=DIR`` and ``classifier=cnn|dinov2|vlm``): the pose file's ``image``
  column names each view's picture, the classifier labels it;
* **geometry** (``segmenter=distance|morphological|voronoi``): the geometric baseline on the
  map's free space; rooms without classes.

Outputs in ``out`` (written in a temporary folder beside it, then renamed, so ``out`` holds
a complete set or nothing; ``overwrite=true`` replaces only a folder this command wrote, the
one with a ``.roomseg-segment`` file, and never one that is or holds an input):

* ``labels.png``: index PNG, pixel = class index (``summary.json`` lists the classes), 255 =
  no class (unlabelled or not walkable); 16-bit with 65535 beyond 255 classes (labels/images);
* ``segments.png``: index PNG, pixel = room segment id (``rooms.geojson``'s ``segment``),
  255 / 65535 = none;
* ``labels_color.png`` + ``labels_color_legend.png`` + ``labels_color.json`` (class colours,
  pixel-exact, readable with ``envs.maps.label_png.read_label_png``), or
  ``segments_color.png`` (geometry);
* ``overview.png``: the map in colour with a legend, a scale bar and the views;
* ``segmentation.yaml`` + ``segmentation.png``: a raw-mode ROS ``map_server`` map with the
  input's origin and resolution; cell value = class index (segment id in geometry mode),
  unknown (-1) where none; not written with more than 101 classes / segments;
* ``rooms.geojson``: one polygon per room segment in the input map's frame (metres; ROS
  ``x, y`` for a ROS map), with ``segment``, ``class``, ``area_m2``, ``pixels``;
* ``scores.json`` (with ``gt=``): :mod:`benchmark.metrics` scores on the map's grid;
* ``summary.json``: inputs, counts, per-class areas, timings, files; ``config.yaml``: the
  resolved config.

Bad input gives one line naming the file and the field, and exit status 2.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

#: The output files of each mode (those that are always written).
LABEL_FILES = ("labels.png", "segments.png", "labels_color.png", "labels_color_legend.png", "labels_color.json",
               "rooms.geojson", "summary.json", "config.yaml")
SEGMENT_FILES = ("segments.png", "segments_color.png", "rooms.geojson", "summary.json", "config.yaml")
#: How each ``frame=`` reads a pose file (said in the summary line: the bench app's
#: ``viewpoints=file`` assumes ``sim``, this command ``ros``).
POSE_FRAMES = {"ros": "frame=ros (x, y metres, theta radians CCW from +x)",
               "sim": "frame=sim (x, z metres, yaw degrees clockwise from +z)",
               "pixel": "frame=pixel (row, col, yaw degrees)"}
#: The frame GeoJSON coordinates are in.
GEOJSON_FRAME = "map: x right, y up, metres (ROS map frame; project world x, z)"
#: The file that marks an output folder this command wrote: ``overwrite=true`` replaces only
#: a folder that holds it, and never one that holds or is an input.
MARKER = ".roomseg-segment"
#: The inputs that are files (each must be a regular file: a FIFO or a device is refused
#: before it is opened), and those that are folders or either.
INPUT_FILES, INPUT_FOLDERS = ("map", "poses", "labels", "gt"), ("images", "bag")


def compose_config(overrides: Sequence[str]):
    """``conf/segment.yaml`` composed with ``key=value`` overrides (Hydra's compose API)."""
    from benchmark.config import compose  # noqa: PLC0415

    return compose("segment", overrides)


# --------------------------------------------------------------------------- inputs


def read_map(cfg) -> tuple[Any, tuple[float, float, float], dict]:
    """The input map -> (GridMap, ROS origin (x, y, yaw) for the outputs, description).

    Every image or array is checked against ``max_map_pixels`` on its header before it is
    decoded; the free space is then cut to the reachable area (``reachable``: the components
    holding a view of ``poses``, else the largest; :mod:`envs.maps.reachable`)."""
    from envs.maps.frames import ros_origin_to_grid_origin  # noqa: PLC0415
    from envs.maps.images import image_size  # noqa: PLC0415
    from envs.maps.ros import grid_from_array, occupancy_png, read_npy_map, read_ros_map  # noqa: PLC0415
    from envs.maps.scene import check_max_map_pixels  # noqa: PLC0415

    path = Path(str(cfg.map)).expanduser()
    suffix = path.suffix.lower()
    limit = check_max_map_pixels(cfg.max_map_pixels, "max_map_pixels")
    if suffix in (".yaml", ".yml"):
        m = read_ros_map(path, mode=cfg.map_mode, unknown_as=cfg.unknown_as, max_pixels=limit)
        grid, origin = _reachable(cfg, m.grid), m.origin
        return grid, origin, {"map": str(path), "map_format": "ros", "map_image": str(m.image_path),
                              "map_mode": m.mode, **_reach_info(cfg, m.grid, grid)}
    if cfg.resolution is None:
        raise ValueError(f"{path}: an image or .npy map needs resolution=<metres per pixel> (a ROS YAML carries it)")
    res = float(cfg.resolution)
    if not (np.isfinite(res) and res > 0):
        raise ValueError(f"resolution={cfg.resolution!r} for {path}; expected a positive number of metres per pixel")
    ox, oy = (0.0, 0.0) if cfg.origin is None else (float(cfg.origin[0]), float(cfg.origin[1]))
    if suffix == ".npy":
        arr = read_npy_map(path, limit)
        h = arr.shape[0] if arr.ndim == 2 else 0
        grid = grid_from_array(arr, res, ros_origin_to_grid_origin((ox, oy), h, res), free_value=cfg.free_value)
        fmt = "npy"
    elif suffix in (".png", ".pgm", ".bmp", ".jpg", ".jpeg", ".tif", ".tiff"):
        h = image_size(path, "the map image", limit)[1]
        grid = occupancy_png(path, res, ros_origin_to_grid_origin((ox, oy), h, res), preset=cfg.image_preset,
                             free_thresh=cfg.free_thresh, occupied_thresh=cfg.occupied_thresh,
                             negate=bool(cfg.negate), unknown_as=cfg.unknown_as, max_pixels=limit)
        fmt = "image"
    else:
        raise ValueError(f"map={path}: unknown map type {suffix!r}; expected a ROS .yaml, an image "
                         f"(.png/.pgm/.bmp) or a .npy array")
    reach = _reachable(cfg, grid)
    return reach, (ox, oy, 0.0), {"map": str(path), "map_format": fmt, **_reach_info(cfg, grid, reach)}


def _reachable(cfg, grid):
    """``grid`` with its free space cut to the reachable area of ``cfg.reachable`` (seeds:
    the views of ``cfg.poses`` in ``cfg.frame``, when given)."""
    from envs.maps.pose_files import read_poses  # noqa: PLC0415
    from envs.maps.reachable import check_rule, reachable_mask, seed_cells  # noqa: PLC0415

    rule = check_rule(cfg.reachable, "reachable")
    if rule == "all":
        return grid
    seeds = None
    if rule == "start" and cfg.poses is not None:
        seeds = seed_cells(grid, read_poses(Path(str(cfg.poses)).expanduser(), cfg.frame, grid)[:, :2])
    reach = reachable_mask(grid.walkable, seeds)
    return grid if reach.sum() == grid.walkable.sum() else type(grid)(reach, grid.resolution, grid.origin)


def _reach_info(cfg, before, after) -> dict:
    return {"reachable": str(cfg.reachable), "unreachable_free_px": int(before.walkable.sum() - after.walkable.sum())}


def _pose_ids(path: Path, n: int) -> list[str | None]:
    """The pose file's ``id`` column (None per view without one: labels then pair by pose or order)."""
    from envs.maps.pose_files import read_table  # noqa: PLC0415

    df = read_table(path)
    df.columns = [str(c).strip().lower() for c in df.columns]
    if "id" in df.columns and len(df) == n:
        return [str(v).strip() for v in df["id"].tolist()]
    return [None] * n


def _classes_or_default(cfg) -> None:
    """Image classifiers need a class list before they are built: the paper's seven when
    ``classes`` is null."""
    from omegaconf import OmegaConf  # noqa: PLC0415

    from envs.world.classes import PAPER_CLASSES  # noqa: PLC0415

    if cfg.classes is None:
        OmegaConf.update(cfg, "classes", list(PAPER_CLASSES), force_add=True)


def _is_labels_classifier(cfg) -> bool:
    return str(cfg.classifier.get("_target_", "")).endswith("LabelsFileClassifier")


def read_views(cfg, grid) -> list:
    """The views of ``poses=`` as Observations: with ``labels=``, each view's pose and id (the
    labels file gives its class); with ``images=``, the renderer reads each view's picture.

    Raises:
        ValueError: no pose file, both or neither of labels= / images=, or a classifier that
            does not fit the mode (one line each)."""
    from hydra.utils import instantiate  # noqa: PLC0415
    from omegaconf import OmegaConf  # noqa: PLC0415

    from envs.maps.pose_files import read_poses  # noqa: PLC0415
    from envs.render.observation import Observation  # noqa: PLC0415

    if cfg.poses is None:
        raise ValueError("poses=<pose file> is needed with labels= or images= (or choose a segmenter=)")
    labels_mode = cfg.labels is not None
    if labels_mode and cfg.images is not None:
        raise ValueError(f"labels={cfg.labels} and images={cfg.images}: give one (labels file, or images and an "
                         f"image classifier)")
    if not labels_mode and cfg.images is None:
        raise ValueError("give labels=<labels file>, images=<image folder> (with classifier=cnn|dinov2|vlm), or "
                         "segmenter=distance|morphological|voronoi")
    if labels_mode:
        if not _is_labels_classifier(cfg):
            raise ValueError(f"labels={cfg.labels} needs classifier=labels (got {cfg.classifier._target_}); image "
                             f"classifiers take images=<folder>")
        OmegaConf.update(cfg, "classifier.path", str(cfg.labels))
        if cfg.frame in ("ros", "sim"):
            OmegaConf.update(cfg, "classifier.frame", str(cfg.frame))
        pose_file = Path(str(cfg.poses)).expanduser()
        poses = read_poses(pose_file, cfg.frame, grid)
        ids = _pose_ids(pose_file, len(poses))
        return [Observation(pose=tuple(float(v) for v in p), meta={"id": i} if i is not None else {})
                for p, i in zip(poses, ids)]
    if _is_labels_classifier(cfg):
        raise ValueError(f"images={cfg.images} needs an image classifier: classifier=cnn|dinov2|vlm")
    _classes_or_default(cfg)
    return list(instantiate(cfg.renderer).observations(grid=grid))


def build(cfg, source: str | None = None, frame: str | None = None):
    """The command's :class:`benchmark.method.Method`: the config's stages
    (:func:`benchmark.config.build_method`; those built after the classifier see its classes as
    ``${classes}``), then the ``off_map`` rule for views off the map (``source`` and ``frame``
    name the views in its messages: the pose file, or a bag's view topic)."""
    from hydra.utils import instantiate  # noqa: PLC0415
    from omegaconf import OmegaConf  # noqa: PLC0415

    from benchmark.config import build_method  # noqa: PLC0415
    from benchmark.method import OnMapRule  # noqa: PLC0415

    built: dict = {}

    def stage(group):
        node = cfg.get(group)
        if node is None:
            return None
        if "classifier" in built:  # the later stages' ${classes} are the classifier's (a labels file's)
            OmegaConf.update(cfg, "classes", list(built["classifier"].classes), force_add=True)
        built[group] = instantiate(node)
        return built[group]

    rule = OnMapRule(str(cfg.off_map), source=source or str(cfg.poses), map_name=str(cfg.map),
                     frame=frame or str(cfg.frame))
    return build_method(cfg, stage=stage, transforms=[rule])


# --------------------------------------------------------------------------- outputs


def _segment_colors(n: int) -> np.ndarray:
    """(n, 3) uint8 distinct-looking colours (tab20 cycled)."""
    import matplotlib  # noqa: PLC0415

    cmap = matplotlib.colormaps["tab20"]
    return np.array([[int(255 * v) for v in cmap(i % 20)[:3]] for i in range(n)], np.uint8).reshape(-1, 3)


def _overview(path: Path, grid, rgb: np.ndarray, legend: list[tuple[str, tuple[int, int, int]]],
              poses: np.ndarray | None, title: str) -> None:
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415
    from matplotlib.patches import Patch  # noqa: PLC0415

    from benchmark.reports.plotting import add_scale_bar, draw_poses, save  # noqa: PLC0415

    h, w = grid.shape
    k = max(1, int(np.ceil(max(h, w) / 1000)))  # the figure is ~800 px wide: draw every k-th pixel
    shown = rgb[::k, ::k]
    side = 6.0
    fig, ax = plt.subplots(figsize=(side * min(w / h, 2.0) + 2.2, side * min(h / w, 1.0) + 0.4))
    ax.imshow(shown, interpolation="nearest")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title, fontsize=9)
    add_scale_bar(ax, grid.resolution * k)
    if poses is not None and len(poses):
        r, c = grid.world_to_pixel(poses[:, 0], poses[:, 1])
        step = max(1, len(poses) // 400)  # at most ~400 markers
        draw_poses(ax, r[::step] / k - 0.5, c[::step] / k - 0.5, poses[::step, 2], size=3.0,
                   arrow_px=max(3.0, 0.02 * max(shown.shape)))
    if legend:
        handles = [Patch(color=np.array(col) / 255, label=name.replace("_", " ")) for name, col in legend]
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    save(fig, path)


def _class_areas(post: np.ndarray, classes: Sequence[str], res: float) -> dict[str, float]:
    from envs.maps.segmentation_io import value_counts  # noqa: PLC0415

    counts = value_counts(post, len(classes))
    return {c: round(float(counts[k]) * res * res, 4) for k, c in enumerate(classes)}


def write_outputs(tmp: Path, cfg, grid, ros_origin, labels: np.ndarray | None, segs: np.ndarray,
                  seg_classes: list[str | None] | None, classes: Sequence[str] | None, poses: np.ndarray | None,
                  title: str) -> dict[str, Any]:
    """Write the output set into ``tmp``; returns what the summary records about it."""
    from envs.maps.label_png import write_label_png  # noqa: PLC0415
    from envs.maps.segmentation_io import (  # noqa: PLC0415
        ROS_MAX_VALUES,
        write_index_png,
        write_rooms_geojson,
        write_ros_segmentation,
    )
    from envs.world.classes import UNLABELLED_COLOR, class_colors  # noqa: PLC0415

    info: dict[str, Any] = {}
    write_index_png(tmp / "segments.png", segs)
    extra = {"map": str(cfg.map), "ros_origin": list(ros_origin)}
    write_rooms_geojson(tmp / "rooms.geojson", segs, grid, seg_classes, frame=GEOJSON_FRAME, extra=extra)
    n_seg = int(segs.max()) + 1 if (segs >= 0).any() else 0
    if labels is not None:
        write_index_png(tmp / "labels.png", labels)
        write_label_png(tmp / "labels_color.png", labels, classes, walkable=grid.walkable,
                        resolution=grid.resolution, origin=grid.origin, legend=True)
        ros_values, n_values, what = labels, len(classes), "classes"
        rgb = None
        legend = list(zip(classes, class_colors(classes))) + [("unlabelled (walkable)", UNLABELLED_COLOR)]
    else:
        from PIL import Image  # noqa: PLC0415

        from envs.atomic import atomic_write_bytes  # noqa: PLC0415

        lut = np.vstack([_segment_colors(n_seg), np.zeros((1, 3), np.uint8)])
        rgb = lut[np.where(segs >= 0, segs, n_seg)]
        import io  # noqa: PLC0415

        buf = io.BytesIO()
        Image.fromarray(rgb).save(buf, format="PNG")
        atomic_write_bytes(tmp / "segments_color.png", buf.getvalue())
        ros_values, n_values, what = segs, n_seg, "segments"
        legend = []
    if n_values <= ROS_MAX_VALUES:
        write_ros_segmentation(tmp / "segmentation.yaml", ros_values, grid, ros_origin, image_name="segmentation.png")
        info["ros_map"] = "segmentation.yaml"
    else:
        info["ros_map"] = None
        info["ros_map_skipped"] = (f"{n_values} {what} do not fit a raw ROS map (cell values 0..100); "
                                   f"labels.png / segments.png hold them")
    if cfg.figure:
        if rgb is None:
            from envs.maps.label_png import label_colors_rgb  # noqa: PLC0415

            rgb = label_colors_rgb(labels, classes, grid.walkable)
        _overview(tmp / "overview.png", grid, rgb, legend, poses, title)
    return info


def _scores(cfg, grid, labels: np.ndarray | None, segs: np.ndarray, classes: Sequence[str] | None,
            metric_params) -> dict[str, Any]:
    from benchmark.metrics import describe, score_instances, score_semantic  # noqa: PLC0415
    from envs.maps.ground_truth import describe as describe_gt  # noqa: PLC0415
    from envs.maps.ground_truth import read_ground_truth  # noqa: PLC0415

    opts = dict(cfg.gt_options or {})
    opts.setdefault("max_pixels", cfg.max_map_pixels)
    if cfg.gt_format == "label" and not Path(str(cfg.gt)).expanduser().with_suffix(".json").exists():
        # a class-index PNG (no sidecar naming its classes): its values index the class list
        given = classes if classes is not None else cfg.get("classes")
        opts["classes"] = list(given) if given is not None else None
    gt = read_ground_truth(str(cfg.gt), cfg.gt_format, grid, **opts)
    out: dict[str, Any] = {"gt": str(cfg.gt), "gt_format": cfg.gt_format, "gt_read": describe_gt(gt),
                           "metric_params": describe(metric_params, grid.resolution)}
    if labels is not None and gt.classes is not None:
        # score on the union of the predicted and ground-truth class names (by name)
        names = list(classes) + [c for c in gt.classes if c not in classes]
        remap = np.array([names.index(c) for c in gt.classes], np.int64)
        inst_cls = np.where(gt.instance_classes >= 0, remap[np.maximum(gt.instance_classes, 0)], -1)
        out.update(score_semantic(labels, gt.instances, inst_cls, metric_params, classes=names,
                                  resolution=grid.resolution))
        out["scored_as"] = "semantic"
    else:
        out.update(score_instances(segs, gt.instances, metric_params, resolution=grid.resolution))
        out["scored_as"] = "instances"
    return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in out.items()}


def _inputs(cfg, map_info: dict | None = None) -> list[tuple[str, Path]]:
    """Every input path of the run as ``(key, path)``: ``map`` (and the image its YAML names,
    once read: ``map_info``), ``poses``, ``labels``, ``images``, ``gt`` (and its ``.json``
    class sidecar), ``bag``."""
    from omegaconf import OmegaConf  # noqa: PLC0415

    out = []
    for key in INPUT_FILES + INPUT_FOLDERS:
        if key in cfg and not OmegaConf.is_missing(cfg, key) and cfg.get(key) is not None:
            out.append((key, Path(str(cfg.get(key))).expanduser()))
    if cfg.get("gt") is not None and Path(str(cfg.gt)).expanduser().with_suffix(".json").exists():
        out.append(("gt", Path(str(cfg.gt)).expanduser().with_suffix(".json")))
    if map_info and map_info.get("map_image"):
        out.append(("map", Path(str(map_info["map_image"]))))
    return out


def _check_inputs(inputs: list[tuple[str, Path]]) -> None:
    """Each existing input that must be a file is a regular file (or a link to one), checked
    without opening it (:func:`envs.files.regular_file`); a missing one is left to its
    reader, which names it."""
    from envs.files import regular_file  # noqa: PLC0415

    for key, p in inputs:
        if key in INPUT_FILES and p.exists():
            regular_file(p, key)


def _check_out(out: Path, overwrite: bool, inputs: Sequence[tuple[str, Path]] = ()) -> None:
    """``out`` (resolved) can take the output set: not a file, neither an input nor a folder
    holding one, and, when it exists and is not empty, ``overwrite=true`` and written by this
    command (its :data:`MARKER` file).

    Raises:
        ValueError: one line naming ``out``, the input or the missing marker."""
    if out.exists() and not out.is_dir():
        raise ValueError(f"out={out} is a file; expected a folder to create")
    for key, p in inputs:
        for q in (Path(os.path.abspath(p)), p.resolve()):
            if q == out or out in q.parents:
                raise ValueError(f"out={out} {'is' if q == out else 'holds'} the input {key}={p}; expected an output "
                                 f"folder apart from the inputs (replacing it would delete them)")
    if out.is_dir() and any(out.iterdir()):
        if not overwrite:
            raise ValueError(f"out={out} exists and is not empty; choose a new folder or pass overwrite=true")
        if not (out / MARKER).is_file():
            raise ValueError(f"out={out} exists and was not written by roomseg-segment (it has no {MARKER} file); "
                             f"overwrite=true replaces only an output folder of this command: choose a new folder")


def _readable(folder: Path) -> None:
    """Give the output folder and its files the usual permissions (the temporary folder and
    the atomic writers' temporary files start private): 0o777 / 0o666 less the umask."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(folder, 0o777 & ~umask)
    for p in folder.iterdir():
        os.chmod(p, 0o666 & ~umask)


def _publish(tmp: Path, out: Path) -> None:
    """Move the finished ``tmp`` folder to ``out`` (replacing an old ``out`` only after
    the new set is complete)."""
    from envs.atomic import leftover_prefix  # noqa: PLC0415

    old = None
    if out.exists():
        if not any(out.iterdir()):
            out.rmdir()
        else:
            old = Path(tempfile.mkdtemp(prefix=leftover_prefix(out, "old"), dir=out.parent))
            os.replace(out, old / out.name)
    os.replace(tmp, out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def segment(cfg, argv: Sequence[str] = ()) -> dict[str, Any]:
    """Run the command on a composed config; returns the summary (also in ``summary.json``)."""
    from hydra.utils import instantiate  # noqa: PLC0415
    from omegaconf import OmegaConf  # noqa: PLC0415

    from benchmark.metrics import segments  # noqa: PLC0415
    from envs.atomic import atomic_write_text, clean_leftovers, leftover_prefix  # noqa: PLC0415
    from envs.maps.segmentation_io import COUNT_BAND_ROWS, value_counts  # noqa: PLC0415

    t_all = time.perf_counter()
    timings: dict[str, float] = {}
    out = Path(str(cfg.out)).expanduser().resolve()
    inputs = _inputs(cfg)
    _check_out(out, bool(cfg.overwrite), inputs)
    _check_inputs(inputs)
    if cfg.off_map not in ("error", "drop"):
        raise ValueError(f"off_map={cfg.off_map!r}; expected error or drop")
    t = time.perf_counter()
    bag_views = None
    if cfg.get("bag") is not None:  # a robot's bag instead of map= / poses= (benchmark/commands/segment_bag.py)
        from benchmark.commands.segment_bag import read_bag_inputs  # noqa: PLC0415

        grid, ros_origin, map_info, bag_views = read_bag_inputs(cfg, argv)  # argv: an aggregator= wins
    else:
        grid, ros_origin, map_info = read_map(cfg)
    timings["t_read_map"] = time.perf_counter() - t
    metric_params = instantiate(cfg.metrics)
    summary: dict[str, Any] = {"command": "roomseg-segment " + " ".join(argv), **map_info,
                               "map_shape": list(grid.shape), "resolution": grid.resolution,
                               "ros_origin": list(ros_origin), "walkable_px": int(grid.walkable.sum()),
                               "rooms_frame": GEOJSON_FRAME}
    labels = poses = None
    classes: tuple[str, ...] | None = None
    if cfg.get("segmenter") is not None:
        if cfg.labels is not None or cfg.images is not None:
            raise ValueError("segmenter= runs on the map alone; drop labels= / images= (or drop segmenter=)")
        summary["mode"] = "geometry"
        summary["segmenter"] = str(cfg.segmenter._target_)
        t = time.perf_counter()
        inst = np.asarray(instantiate(cfg.segmenter)(grid))
        timings["t_segment"] = time.perf_counter() - t
        ids = np.unique(inst[(inst >= 0) & grid.walkable])
        remap = np.full(int(inst.max()) + 2 if inst.size and inst.max() >= 0 else 1, -1, np.int64)
        remap[ids] = np.arange(len(ids))
        segs = np.where((inst >= 0) & grid.walkable, remap[np.maximum(inst, 0)], -1).astype(np.int32)
        seg_classes = None
        title = f"{Path(str(cfg.map)).name}: {summary['segmenter'].rsplit('.', 1)[-1]}, {len(ids)} segments"
    else:
        summary["mode"] = "labels" if cfg.labels is not None else "images"
        if bag_views is not None:  # the bag's views (benchmark/commands/segment_bag.py), classified in chunks
            from benchmark.commands.segment_bag import bag_source, classify_bag_views  # noqa: PLC0415

            m = build(cfg, *bag_source(bag_views))
            views, classes, counts = classify_bag_views(cfg, m, bag_views, timings, _is_labels_classifier(cfg),
                                                        lambda: _classes_or_default(cfg))
            summary.update(counts)
        else:
            t = time.perf_counter()
            views = read_views(cfg, grid)
            timings["t_read_views"] = time.perf_counter() - t
            m = build(cfg)
            summary["pose_frame"] = POSE_FRAMES[str(cfg.frame)]
        result = m.run(views, grid, timings=timings)
        if bag_views is None:
            classes = tuple(m.classifier.classes)
            OmegaConf.update(cfg, "classes", list(classes), force_add=True)
        poses, labels = result.poses, result.labels
        summary.update({"n_views": len(result.classified.poses), "n_off_map": int(result.info.get("n_off_map", 0))})
        summary["classes"] = list(classes)
        summary["classifier"] = str(cfg.classifier._target_)
        summary["aggregator"] = str(cfg.aggregator._target_)
        summary["postprocess"] = str(cfg.postprocess._target_) if cfg.get("postprocess") else None
        if hasattr(m.aggregator, "last_used"):
            summary["n_views_used"] = int(m.aggregator.last_used)
        segs = segments(labels, metric_params.connectivity)
        n_seg = int(segs.max()) + 1 if (segs >= 0).any() else 0
        first = np.full(n_seg, -1, np.int64)  # each segment's class (any of its pixels), a band of rows at a time
        for r0 in range(0, segs.shape[0], COUNT_BAND_ROWS):
            band_s, band_l = segs[r0:r0 + COUNT_BAND_ROWS], labels[r0:r0 + COUNT_BAND_ROWS]
            m = band_s >= 0
            first[band_s[m]] = band_l[m]
        seg_classes = [classes[k] for k in first]
        summary["class_area_m2"] = _class_areas(labels, classes, grid.resolution)
        summary["unlabelled_walkable_px"] = int((grid.walkable & (labels < 0)).sum())
        title = (f"{Path(str(cfg.map)).name}: {summary['mode']}, {summary['aggregator'].rsplit('.', 1)[-1]}, "
                 f"{len(poses)} views")
    n_seg = int(segs.max()) + 1 if (segs >= 0).any() else 0
    summary["n_segments"] = n_seg
    areas = value_counts(segs, n_seg) * grid.resolution ** 2
    summary["rooms"] = [{"segment": k, "class": seg_classes[k] if seg_classes else None,
                         "area_m2": round(float(areas[k]), 4)} for k in range(n_seg)]
    out.parent.mkdir(parents=True, exist_ok=True)
    clean_leftovers(out)  # of an earlier run that was killed
    tmp = Path(tempfile.mkdtemp(prefix=leftover_prefix(out, "tmp"), dir=out.parent))
    try:
        t = time.perf_counter()
        # every write names its file when it fails (a full disk): the atomic writers do
        atomic_write_text(tmp / MARKER, "roomseg-segment output folder: overwrite=true may replace it\n")
        summary.update(write_outputs(tmp, cfg, grid, ros_origin, labels, segs, seg_classes, classes, poses, title))
        if bag_views is not None:  # the output bag: map + rooms as MarkerArray (benchmark/commands/segment_bag.py)
            from benchmark.commands.segment_bag import write_bag_output  # noqa: PLC0415

            summary.update(write_bag_output(tmp, cfg, bag_views, labels, segs, classes))
        timings["t_write"] = time.perf_counter() - t
        if cfg.gt is not None:
            t = time.perf_counter()
            scores = _scores(cfg, grid, labels, segs, classes, metric_params)
            timings["t_score"] = time.perf_counter() - t
            atomic_write_text(tmp / "scores.json", json.dumps(scores, indent=1))
            summary["scores"] = {k: scores[k] for k in ("iou", "precision", "recall", "accuracy") if k in scores}
        atomic_write_text(tmp / "config.yaml", OmegaConf.to_yaml(cfg, resolve=True))
        timings["t_total"] = time.perf_counter() - t_all
        summary["timings_s"] = {k: round(v, 4) for k, v in timings.items()}
        summary["out"] = str(out)
        summary["files"] = sorted(p.name for p in tmp.iterdir()) + ["summary.json"]
        atomic_write_text(tmp / "summary.json", json.dumps(summary, indent=1))
        _readable(tmp)
        _check_out(out, bool(cfg.overwrite), _inputs(cfg, map_info))
        _publish(tmp, out)
    except OSError as e:
        shutil.rmtree(tmp, ignore_errors=True)
        if e.filename and e.__cause__ is not None:  # the atomic writers chain the bare error of a full disk:
            raise OSError(e.errno, e.strerror, e.filename) from None  # the line names the file
        raise
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return summary


def check_keys(cfg) -> None:
    """The typed-config check of :mod:`benchmark.harness.typed` on the composed config: a key no
    stage reads (``+agregator=...``), or a stage's key of the wrong type, is one line.

    Raises:
        ConfigError: naming the key and the nearest valid one."""
    from omegaconf import OmegaConf  # noqa: PLC0415

    from benchmark.harness.typed import check_typed  # noqa: PLC0415

    check_typed(OmegaConf.to_container(cfg, resolve=True), "segment")


def _errors() -> tuple[type[BaseException], ...]:
    from omegaconf.errors import OmegaConfBaseException  # noqa: PLC0415

    from benchmark.commands.errors import cli_errors  # noqa: PLC0415

    return (*cli_errors(), OmegaConfBaseException)


def main(argv: Sequence[str] | None = None) -> int:
    """Console entry point; returns the exit status (0 ok, 2 bad input)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        from benchmark.commands.cli import plain  # noqa: PLC0415

        print(plain(__doc__))  # without the docstring's markup (double backticks, :mod: roles)
        return 0 if argv else 2
    from benchmark.commands.errors import one_line  # noqa: PLC0415

    try:
        cfg = compose_config(argv)
        check_keys(cfg)
    except _errors() as e:
        from benchmark.config import valid_keys_hint  # noqa: PLC0415

        print(f"error: {one_line(e)}{valid_keys_hint(e, argv, 'segment')}", file=sys.stderr)
        return 2
    try:
        s = segment(cfg, argv)
    except _errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    line = f"{s['mode']}: {s['n_segments']} segments on {s['map_shape'][1]} x {s['map_shape'][0]} px"
    if "n_views" in s:
        line += f" from {s['n_views']} views ({s['n_off_map']} off the map; poses read as {s['pose_frame']})"
    if "scores" in s:
        line += ", " + ", ".join(f"{k} {100 * v:.1f}" for k, v in s["scores"].items() if v is not None)
    print(f"{line}; {s['timings_s']['t_total']:.2f} s; wrote {s['out']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
