"""``roomseg-segment bag=run.bag``: a robot's recording as the inputs of ``roomseg-segment``.

The glue between :mod:`envs.bags` and :mod:`benchmark.commands.segment`: the map of the bag
replaces ``map=``, its views replace ``poses=`` + ``labels=`` / ``images=``, and after the
outputs are written a bag with the segmented map and the rooms is written beside them
(:mod:`envs.bags.write`). The method is the same as for files: per-view labels go through
:func:`benchmark.classifiers.labels_file.table_probabilities` as a labels file's rows do,
images through the configured image classifier (``benchmark.method.classify``, in chunks of
``bag_options.chunk`` decoded images, so memory does not grow with the number of views).

Defaults that follow the bag (:func:`read_bag_inputs`): the class list of label views is
``classes=``, else the bag's own ``vision_msgs/LabelInfo``, else the paper's seven (never the
labels seen); the aggregator is ``graph_knn`` for place labels and ``vision_cone`` for camera
images (:func:`envs.bags.views.aggregator_for`), unless ``aggregator=`` is given.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

#: Output bag name per format.
OUT_NAMES = {"ros1": "segmentation.bag", "mcap": "segmentation.mcap"}


def bag_options(cfg, own_classes: tuple[str, ...] | None = None):
    """``cfg.bag`` -> :class:`envs.bags.read.BagOptions` (``classes``: the config's, else
    ``own_classes``, the bag's LabelInfo list, which ROS 1 Classification2D ids index)."""
    from envs.bags.read import BagOptions  # noqa: PLC0415
    from envs.maps.scene import check_max_map_pixels  # noqa: PLC0415

    b = cfg.bag_options
    classes = tuple(str(c) for c in cfg.classes) if cfg.get("classes") is not None else own_classes
    return BagOptions(map_topic=b.map_topic, map_stamp=b.map_stamp, view_topic=b.view_topic, pose_topic=b.pose_topic,
                      camera_info_topic=b.camera_info_topic, map_frame=b.map_frame, camera_frame=b.camera_frame,
                      camera_axis=str(b.camera_axis), min_distance_m=float(b.min_distance_m),
                      min_turn_deg=float(b.min_turn_deg), tf_tolerance_s=float(b.tf_tolerance_s),
                      tf_max_gap_s=float(b.tf_max_gap_s), max_clock_jump_s=float(b.max_clock_jump_s),
                      free_max=int(b.free_max), unknown_as=str(cfg.unknown_as), classes=classes,
                      max_map_pixels=check_max_map_pixels(cfg.max_map_pixels, "max_map_pixels"))


def explicit(argv, group: str) -> bool:
    """``argv`` (the command's overrides) sets ``group`` or one of its keys."""
    for item in argv:
        key = str(item).partition("=")[0].lstrip("+~")
        if key == group or key.startswith(group + "."):
            return True
    return False


def choose_aggregator(cfg, kind: str, argv) -> str:
    """Set ``cfg.aggregator`` to the one for the views' ``kind`` unless ``argv`` names one;
    returns the line that says which and why (:data:`envs.bags.views.AGGREGATOR_FOR`)."""
    from omegaconf import OmegaConf  # noqa: PLC0415

    from benchmark.config import compose  # noqa: PLC0415
    from envs.bags.views import aggregator_for  # noqa: PLC0415

    if explicit(argv, "aggregator"):
        given = [str(i).partition("=")[2] for i in argv if str(i).partition("=")[0].lstrip("+") == "aggregator"]
        return f"{given[-1] if given else cfg.aggregator._target_.rsplit('.', 1)[-1]} (aggregator= given)"
    name, why = aggregator_for(kind)
    node = compose("segment", [f"aggregator={name}"]).aggregator
    if str(node._target_) != str(cfg.aggregator._target_):
        OmegaConf.update(cfg, "aggregator", node, merge=False)
    return f"{name}: {why} (aggregator=... to choose another)"


def label_classes(cfg, own) -> tuple[tuple[str, ...], str]:
    """The class list of label views and where it came from: ``classes=``, else the bag's
    LabelInfo ``own`` (topic, names), else the paper's seven; never the labels seen."""
    from envs.world.classes import PAPER_CLASSES  # noqa: PLC0415

    if cfg.get("classes") is not None:
        return tuple(str(c) for c in cfg.classes), "classes="
    if own is not None:
        return tuple(own[1]), f"the bag's LabelInfo on {own[0]}"
    return tuple(PAPER_CLASSES), "the paper's seven, the default"


def read_bag_inputs(cfg, argv=()) -> tuple[Any, tuple[float, float, float], dict, Any]:
    """The bag's map and views -> (GridMap cut to the reachable area, ROS origin, description,
    :class:`envs.bags.read.BagViews`). Sets ``cfg.classes`` for label views and the aggregator
    for the views (see the module doc; ``argv``: the command's overrides, an ``aggregator=``
    among them wins)."""
    from omegaconf import OmegaConf  # noqa: PLC0415

    from envs.bags.read import read_bag  # noqa: PLC0415
    from envs.maps.reachable import check_rule, reachable_mask, seed_cells  # noqa: PLC0415

    path = Path(str(cfg.bag)).expanduser()
    for key in ("poses", "labels", "images"):
        if cfg.get(key) is not None:
            raise ValueError(f"bag={path} and {key}={cfg.get(key)}: the bag gives the views; drop {key}=")
    if not OmegaConf.is_missing(cfg, "map"):
        raise ValueError(f"bag={path} and map={cfg.map}: the bag gives the map; drop map=")
    OmegaConf.update(cfg, "map", str(path))
    geometry = cfg.get("segmenter") is not None
    own = None
    if not geometry and cfg.get("classes") is None:
        from envs.bags.info import bag_classes  # noqa: PLC0415

        own = bag_classes(path)
    views = read_bag(path, bag_options(cfg, None if own is None else own[1]), need_views=not geometry,
                     progress=bool(cfg.bag_options.progress))
    grid = views.grid
    rule = check_rule(cfg.reachable, "reachable")
    reach = grid
    if rule != "all":
        seeds = seed_cells(grid, views.poses[:, :2]) if (rule == "start" and len(views.kept)) else None
        mask = reachable_mask(grid.walkable, seeds)
        if mask.sum() != grid.walkable.sum():
            reach = type(grid)(mask, grid.resolution, grid.origin)
    t = views.topics
    info = {"map": str(path), "map_format": "bag", "bag": str(path), "map_topic": t["map"].name,
            "map_frame": views.map_frame, "map_stamp_ns": int(views.map.stamp_ns),
            "n_map_messages": views.n_map_messages, "reachable": str(cfg.reachable),
            "unreachable_free_px": int(grid.walkable.sum() - reach.walkable.sum())}
    if not geometry:
        info.update({"view_topic": t["views"].name, "view_type": views.view_type, "camera_frame": views.camera_frame,
                     "pose_source": t["poses"].name if t.get("poses") is not None else "tf " + ", ".join(t["tf"]),
                     "n_bag_views": int(len(views.stamps)), "n_kept_views": int(len(views.kept)),
                     "subsample": {"min_distance_m": float(cfg.bag_options.min_distance_m),
                                   "min_turn_deg": float(cfg.bag_options.min_turn_deg)},
                     "camera_hfov_deg": views.hfov_deg})
        if views.kind == "labels":
            from envs.bags.views import check_label_names  # noqa: PLC0415

            classes, source = label_classes(cfg, own)
            check_label_names(views.labels, classes, f"{path} {t['views'].name}", source)
            OmegaConf.update(cfg, "classes", list(classes), force_add=True)
            info["classes_from"] = source
        info["aggregator_choice"] = choose_aggregator(cfg, views.kind, argv)
        print(f"aggregator {info['aggregator_choice']}")
    return reach, views.map.ros_origin, info, views


def _label_table(labels: list, classes: tuple[str, ...] | None):
    """The labels as a labels file's table: a ``label`` column of names, or (class scores)
    one column per class, a class a message does not name scoring 0; the columns are
    ``classes`` (then any other name, which the table check refuses) or the sorted names."""
    import pandas as pd  # noqa: PLC0415

    if all(isinstance(v, str) for v in labels):
        return pd.DataFrame({"label": labels})
    seen = {k for v in labels for k in ([v] if isinstance(v, str) else v)}
    names = list(classes) + sorted(seen - set(classes)) if classes is not None else sorted(seen)
    rows = [{n: (1.0 if v == n else 0.0) for n in names} if isinstance(v, str) else {n: v.get(n, 0.0) for n in names}
            for v in labels]
    df = pd.DataFrame(rows, columns=names)
    df.columns = [c.strip().lower() for c in df.columns]
    return df


def bag_source(views) -> tuple[str, str]:
    """(the views' name, their frame) for the off-map rule's messages."""
    return (f"{views.path} {views.topics['views'].name}", f"bag ({views.map_frame} <- {views.camera_frame})")


def classify_bag_views(cfg, method, views, timings: dict, labels_classifier: bool, default_classes):
    """The kept views of the bag, classified: per-view labels as a labels file's rows are
    (:func:`benchmark.classifiers.labels_file.table_probabilities`), images by the Method's
    own classify step in chunks of ``bag_options.chunk`` decoded images.

    Args:
        labels_classifier: ``classifier=labels`` is chosen (the views must be labels then).
        default_classes: fills ``classes`` for an image classifier when the config has none.

    Returns:
        (:class:`benchmark.method.Classified` of the K kept views (world poses), the classes,
        the summary's counts)."""
    from omegaconf import OmegaConf  # noqa: PLC0415

    from benchmark.classifiers.labels_file import table_probabilities  # noqa: PLC0415
    from benchmark.method import Classified  # noqa: PLC0415
    from envs.bags.read import iter_images  # noqa: PLC0415
    from envs.render.observation import Observation  # noqa: PLC0415

    topic = views.topics["views"].name
    where = Path(f"{views.path} {topic}")
    poses = views.poses
    t = time.perf_counter()
    if views.kind == "labels":
        if not labels_classifier:
            raise ValueError(f"{where}: the views are labels ({views.view_type}); use classifier=labels (got "
                             f"{cfg.classifier._target_}), or bag.view_topic=<an image topic>")
        given = tuple(str(c) for c in cfg.classes) if cfg.get("classes") is not None else None
        proba, classes = table_probabilities(_label_table(views.labels, given), where, given)
        timings["t_read_views"] = time.perf_counter() - t
    else:
        if labels_classifier:
            raise ValueError(f"{where}: the views are images ({views.view_type}); choose an image classifier: "
                             f"classifier=cnn|dinov2|vlm")
        default_classes()
        if bool(cfg.bag_options.fov_from_camera_info) and views.hfov_deg is not None and "fov" in cfg.aggregator:
            OmegaConf.update(cfg, "aggregator.fov", round(float(views.hfov_deg), 6))
        classes = tuple(method.classifier.classes)
        proba = np.zeros((len(poses), len(classes)))
        for chunk in iter_images(views, int(cfg.bag_options.chunk), progress=bool(cfg.bag_options.progress)):
            idx = [k for k, _ in chunk]
            obs = [Observation(pose=tuple(float(v) for v in poses[k]), image=img,
                               meta={"id": f"{topic}@{int(views.stamps[views.kept[k]])}"}) for k, img in chunk]
            proba[idx] = method.classify(obs).proba
        timings["t_read_views"] = time.perf_counter() - t
        timings["t_classify"] = 0.0  # classification is inside the chunked read above
    OmegaConf.update(cfg, "classes", list(classes), force_add=True)
    counts = {"mode": views.kind, "pose_frame": bag_source(views)[1]}
    return Classified(np.asarray(poses, float), proba), tuple(classes), counts


def write_bag_output(tmp: Path, cfg, views, labels: np.ndarray | None, segs: np.ndarray,
                     classes) -> dict[str, Any]:
    """The output bag into ``tmp`` (``segmentation.bag`` for a ROS 1 input, ``segmentation.mcap``
    for a ROS 2 one, or ``bag_options.out_format``); returns what the summary records."""
    from envs.bags.write import rviz_colors, write_segmentation_bag  # noqa: PLC0415
    from envs.maps.segmentation_io import ROS_MAX_VALUES  # noqa: PLC0415

    fmt = str(cfg.bag_options.out_format)
    if fmt == "none":
        return {"bag_out": None}
    if fmt == "auto":
        fmt = "ros1" if views.path.is_file() and views.path.suffix.lower() == ".bag" else "mcap"
    values = labels if labels is not None else segs
    n_values = len(classes) if labels is not None else (int(segs.max()) + 1 if (segs >= 0).any() else 0)
    rooms = json.loads((tmp / "rooms.geojson").read_text())
    # the room outlines in their class's colour in /segmentation_rviz (RViz: Map display, costmap scheme)
    colors = dict(zip(classes, rviz_colors(len(classes)))) if classes is not None else {}
    seg = values if n_values <= ROS_MAX_VALUES else None
    name = OUT_NAMES.get(fmt, f"segmentation.{fmt}")
    write_segmentation_bag(tmp / name, fmt, views.map_frame, int(views.map.stamp_ns), views.map.resolution,
                           views.map.ros_origin, views.map.values, seg, rooms, colors)
    return {"bag_out": name, "bag_topics": ["/map"] + (["/segmentation", "/segmentation_rviz"] if seg is not None
                                                       else []) + ["/rooms"]}
