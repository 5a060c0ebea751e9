"""``roomseg bag-info``: what a ROS bag holds and what ``roomseg-segment bag=`` would use.

    roomseg bag-info run.bag
    roomseg bag-info run_ros2/ view_topic=/room_label min_distance_m=0.5
    roomseg bag-info run.mcap --json
    roomseg bag-info images.bag classifier=cnn

Lists the storage, time span, topics (type, message count, frame of the first message), the
tf edges, every map message's stamp, then reads the bag as ``roomseg-segment bag=...`` would
(the ``bag_options`` given as ``key=value``, as in ``conf/segment.yaml``'s ``bag_options``;
also ``classes=[...]``, ``classifier=`` and ``aggregator=`` as given to ``roomseg-segment``):
the map used (size, resolution, origin, frame, stamp), the view topic and kind, the pose
source, the camera frame, the views in the bag and those kept by the subsampling, the class
list of label views and where it comes from, and the aggregator. Exit 0 when
``roomseg-segment`` with those arguments can use the bag, 2 (with the one-line reason) when
it cannot: an image bag needs ``classifier=cnn|dinov2|vlm`` (the default, labels, refuses it).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from dataclasses import fields, replace

import yaml


def parse_options(items: Sequence[str]):
    """``key=value`` items (``bag_options.`` prefix optional) -> BagOptions.

    Raises:
        ValueError: an unknown key or an item without ``=`` (one line listing the keys)."""
    from envs.bags.read import BagOptions  # noqa: PLC0415

    opt = BagOptions()
    names = [f.name for f in fields(BagOptions)]
    for item in items:
        key, eq, value = item.partition("=")
        key = key.removeprefix("bag_options.")
        if not eq or key not in names:
            raise ValueError(f"{item!r}: expected key=value with a key of {names}")
        v = yaml.safe_load(value) if value != "" else None
        if key == "classes" and v is not None:
            v = tuple(str(c) for c in v)
        opt = replace(opt, **{key: v})
    return opt


#: ``roomseg-segment`` arguments bag-info takes besides ``bag_options`` (what they change).
SEGMENT_KEYS = ("classifier", "aggregator")


def split_items(items: Sequence[str]) -> tuple[list[str], dict[str, str]]:
    """(``bag_options`` items, {``classifier`` / ``aggregator``: option name})."""
    rest, seg = [], {}
    for item in items:
        key, eq, value = item.partition("=")
        if eq and key in SEGMENT_KEYS:
            seg[key] = value.strip()
        else:
            rest.append(item)
    return rest, seg


def would_use(path: str, opt, classifier: str | None = None, aggregator: str | None = None) -> dict:
    """What ``roomseg-segment bag=path`` would read (a full first pass over the bag), with
    ``classifier=`` / ``aggregator=`` as given to it (None: its defaults).

    Raises:
        BagError: a bag the segmenter cannot use with those arguments: image views with the
            labels classifier, label views with an image classifier, a view's class outside
            the class list (one line each)."""
    from dataclasses import replace  # noqa: PLC0415

    from envs.bags.info import bag_classes  # noqa: PLC0415
    from envs.bags.read import read_bag  # noqa: PLC0415
    from envs.bags.source import BagError, stamp_s  # noqa: PLC0415
    from envs.bags.views import aggregator_for, check_label_names  # noqa: PLC0415
    from envs.world.classes import PAPER_CLASSES  # noqa: PLC0415

    own = bag_classes(path) if opt.classes is None else None
    v = read_bag(path, opt if own is None else replace(opt, classes=own[1]))
    h, w = v.map.values.shape
    t = v.topics
    where = f"{path} {t['views'].name}"
    labels_classifier = classifier in (None, "labels")
    classes = source = None
    if v.kind == "images" and labels_classifier:
        raise BagError(f"{where}: the views are images ({v.view_type}); roomseg-segment needs an image classifier: "
                       f"classifier=cnn|dinov2|vlm (the default, classifier=labels, refuses images)")
    if v.kind == "labels":
        if not labels_classifier:
            raise BagError(f"{where}: the views are labels ({v.view_type}); use classifier=labels (got "
                           f"classifier={classifier}), or bag_options.view_topic=<an image topic>")
        if opt.classes is not None:
            classes, source = tuple(opt.classes), "classes="
        elif own is not None:
            classes, source = own[1], f"the bag's LabelInfo on {own[0]}"
        else:
            classes, source = tuple(PAPER_CLASSES), "the paper's seven, the default"
        check_label_names(v.labels, classes, where, source)
    agg = (f"{aggregator} (aggregator= given)" if aggregator else
           "{}: {}".format(*aggregator_for(v.kind)))
    return {"map_topic": t["map"].name, "map_cells": [w, h], "resolution": v.map.resolution,
            "ros_origin": list(v.map.ros_origin), "map_frame": v.map_frame, "n_map_messages": v.n_map_messages,
            "map_stamp_ns": int(v.map.stamp_ns), "map_stamp": stamp_s(int(v.map.stamp_ns)),
            "map_chosen_by": ("the last map" if opt.map_stamp is None
                              else f"the last map at or before bag_options.map_stamp={opt.map_stamp}"),
            "walkable_px": int(v.grid.walkable.sum()), "view_topic": t["views"].name, "view_kind": v.kind,
            "view_type": v.view_type,
            "pose_source": t["poses"].name if t.get("poses") is not None else "tf " + ", ".join(t["tf"]),
            "camera_frame": v.camera_frame, "camera_hfov_deg": v.hfov_deg, "n_views": int(len(v.stamps)),
            "n_kept": int(len(v.kept)), "subsample": [opt.min_distance_m, opt.min_turn_deg],
            "classes": None if classes is None else list(classes), "classes_from": source, "aggregator": agg}


def main(argv: Sequence[str] | None = None) -> int:
    """Console entry point: 0 when the segmenter can use the bag, 2 otherwise."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(__doc__)
        return 0 if argv else 2
    from benchmark.commands.errors import cli_errors, one_line  # noqa: PLC0415
    from envs.bags.info import bag_contents, format_contents  # noqa: PLC0415

    as_json = "--json" in argv
    args = [a for a in argv if a != "--json"]
    path, items = args[0], args[1:]
    try:
        items, seg = split_items(items)
        opt = parse_options(items)
        info = bag_contents(path)
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    use, err = None, None
    try:
        use = would_use(path, opt, seg.get("classifier"), seg.get("aggregator"))
    except cli_errors() as e:
        err = one_line(e)
    if as_json:
        print(json.dumps({**info, "segmenter": use, "error": err}, indent=1))
    else:
        print("\n".join(format_contents(info)))
        if use is not None:
            print(f"roomseg-segment bag={path} would use: map {use['map_topic']} ({use['map_cells'][0]} x "
                  f"{use['map_cells'][1]} cells, {use['resolution']} m, origin {use['ros_origin'][:2]}, frame "
                  f"{use['map_frame']}, stamp {use['map_stamp']}: {use['map_chosen_by']}); views {use['view_topic']} "
                  f"({use['view_kind']}, {use['view_type']}), poses from {use['pose_source']}, camera "
                  f"{use['camera_frame']}" + (f" ({use['camera_hfov_deg']:.1f} deg wide)" if use["camera_hfov_deg"]
                                              else "")
                  + f"; {use['n_kept']} of {use['n_views']} views kept (every {use['subsample'][0]} m or "
                    f"{use['subsample'][1]} deg)")
            if use["classes"] is not None:
                print(f"classes {use['classes']} ({use['classes_from']})")
            print(f"aggregator {use['aggregator']}")
    if err is not None:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
