"""``roomseg bag-info``: what a ROS bag holds and what ``roomseg-segment bag=`` would use.

    roomseg bag-info run.bag
    roomseg bag-info run_ros2/ view_topic=/room_label min_distance_m=0.5
    roomseg bag-info run.mcap --json

Lists the storage, time span, topics (type, message count, frame of the first message), the
tf edges, then reads the bag as ``roomseg-segment bag=...`` would (the ``bag_options`` given
as ``key=value``, as in ``conf/segment.yaml``'s ``bag_options``): the map (size, resolution,
origin, frame), the view topic and kind, the pose source, the camera frame, the views in the
bag and those kept by the subsampling. Exit 0 when the segmenter can use the bag, 2 (with
the one-line reason) when it cannot.
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


def would_use(path: str, opt) -> dict:
    """What ``roomseg-segment bag=path`` would read (a full first pass over the bag)."""
    from envs.bags.read import read_bag  # noqa: PLC0415

    v = read_bag(path, opt)
    h, w = v.map.values.shape
    t = v.topics
    return {"map_topic": t["map"].name, "map_cells": [w, h], "resolution": v.map.resolution,
            "ros_origin": list(v.map.ros_origin), "map_frame": v.map_frame, "n_map_messages": v.n_map_messages,
            "walkable_px": int(v.grid.walkable.sum()), "view_topic": t["views"].name, "view_kind": v.kind,
            "view_type": v.view_type,
            "pose_source": t["poses"].name if t.get("poses") is not None else "tf " + ", ".join(t["tf"]),
            "camera_frame": v.camera_frame, "camera_hfov_deg": v.hfov_deg, "n_views": int(len(v.stamps)),
            "n_kept": int(len(v.kept)), "subsample": [opt.min_distance_m, opt.min_turn_deg]}


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
        opt = parse_options(items)
        info = bag_contents(path)
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    use, err = None, None
    try:
        use = would_use(path, opt)
    except cli_errors() as e:
        err = one_line(e)
    if as_json:
        print(json.dumps({**info, "segmenter": use, "error": err}, indent=1))
    else:
        print("\n".join(format_contents(info)))
        if use is not None:
            print(f"roomseg-segment bag={path} would use: map {use['map_topic']} ({use['map_cells'][0]} x "
                  f"{use['map_cells'][1]} cells, {use['resolution']} m, origin {use['ros_origin'][:2]}, frame "
                  f"{use['map_frame']}, {use['n_map_messages']} message(s)); views {use['view_topic']} "
                  f"({use['view_kind']}, {use['view_type']}), poses from {use['pose_source']}, camera "
                  f"{use['camera_frame']}" + (f" ({use['camera_hfov_deg']:.1f} deg wide)" if use["camera_hfov_deg"]
                                              else "")
                  + f"; {use['n_kept']} of {use['n_views']} views kept (every {use['subsample'][0]} m or "
                    f"{use['subsample'][1]} deg)")
    if err is not None:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
