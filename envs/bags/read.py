"""Read a bag into the project's contracts: the map (a :class:`~envs.maps.gridmap.GridMap` with
its ROS origin, resolution and frame), the views' poses (world ``x, z, yaw``, as
:func:`envs.maps.pose_files.read_poses` gives them) and per view a label or an image.

Two streaming passes, one message in memory at a time:

1. map, tf, pose topic, camera info and the views' stamps (and labels): the views' camera
   poses are looked up at their stamps, then subsampled by distance and turn;
2. (images only) :func:`iter_images` decodes the kept images, in chunks.

Topics and frames default to what the bag holds (:func:`choose_topics`): the one topic of
each type, the map's frame from the map message, the camera frame from the views' header.
"""

from __future__ import annotations

import math
import unicodedata
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from envs.bags.occupancy import (
    FREE_MAX,
    MapMessage,
    grid_from_map,
    map_before,
    map_frame_of,
    map_message,
    map_stamp_ns,
)
from envs.bags.source import MAX_MESSAGE_BYTES, Bag, BagError, Topic, header_ns, open_bag, stamp_s
from envs.bags.transforms import TfBuffer, forward_axis, planar_pose
from envs.bags.views import (
    CAMERA_INFO_TYPES,
    IMAGE_TYPES,
    LABEL_TYPES,
    MAP_TYPES,
    POSE_TYPES,
    TF_TYPES,
    VIEW_TYPES,
    decode_image,
    horizontal_fov_deg,
    subsample,
    view_label,
)
from envs.maps.frames import ros_to_world
from envs.maps.gridmap import GridMap
from envs.maps.scene import MAX_MAP_PIXELS

#: The longest class name a label message may carry, in UTF-8 bytes.
MAX_LABEL_BYTES = 128
#: What a class name may hold besides letters, digits and combining marks (of any script).
NAME_PUNCTUATION = " _-.,'()/&+:"


@dataclass(frozen=True)
class BagOptions:
    """How to read a bag (``bag_options.*`` in ``conf/segment.yaml``); None = found from the bag."""

    map_topic: str | None = None
    map_stamp: float | None = None          # seconds: the last map at or before it (None: the last map)
    view_topic: str | None = None           # labels (String / Classification) or images
    pose_topic: str | None = None           # PoseStamped / PoseWithCovarianceStamped / Odometry instead of tf
    camera_info_topic: str | None = None
    map_frame: str | None = None
    camera_frame: str | None = None
    camera_axis: str = "auto"               # auto | x | z: the camera's viewing axis in its frame
    min_distance_m: float = 1.0             # subsampling (autotrace: 1 m between points)
    min_turn_deg: float = 90.0              # ... and 90 degrees between headings
    tf_tolerance_s: float = 0.1
    tf_max_gap_s: float = 2.0
    max_clock_jump_s: float = 1.0           # header stamp minus record time may change by at most this
    free_max: int = FREE_MAX
    unknown_as: str = "obstacle"
    classes: tuple[str, ...] | None = None  # names indexed by ROS 1 Classification2D ids
    max_map_pixels: int | None = MAX_MAP_PIXELS  # the largest OccupancyGrid (width x height cells); None: no limit
    max_message_bytes: int = MAX_MESSAGE_BYTES   # the largest serialised message decoded

    def __post_init__(self):
        """Each number in its range: one line naming the option, the value and the range."""
        for key in ("min_distance_m", "min_turn_deg", "tf_tolerance_s", "tf_max_gap_s", "max_clock_jump_s"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v >= 0):
                raise ValueError(f"bag_options.{key}={v!r}; expected a finite number >= 0")
        for key in ("max_map_pixels", "max_message_bytes"):
            v = getattr(self, key)
            if (v is not None or key == "max_message_bytes") and (isinstance(v, bool) or not isinstance(v, int)
                                                                   or v <= 0):
                raise ValueError(f"{key}={v!r}; expected a positive integer")


@dataclass
class BagViews:
    """What :func:`read_bag` found.

    Attributes:
        path: the bag.
        map: the map message used; grid: its walkable grid.
        topics: the topics used, by role (``map``, ``views``, ``tf``, ``poses``, ``camera_info``).
        kind: ``labels`` or ``images``; view_type: the views' message type.
        map_frame, camera_frame: the frames the poses are in / of.
        stamps: (N,) int64 ns, every view's stamp; record: (N,) its record time.
        poses_ros: (N, 3) every view's ROS ``x, y, theta`` in the map frame.
        kept: (K,) indices of the views kept by the subsampling.
        labels: per kept view, a class name or ``{class: score}`` (labels only).
        hfov_deg: the camera's horizontal field of view from CameraInfo, or None.
    """

    path: Path
    map: MapMessage
    grid: GridMap
    topics: dict[str, Any]
    kind: str
    view_type: str
    map_frame: str
    camera_frame: str
    stamps: np.ndarray
    record: np.ndarray
    poses_ros: np.ndarray
    kept: np.ndarray
    labels: list = field(default_factory=list)
    hfov_deg: float | None = None
    n_map_messages: int = 0

    @property
    def poses(self) -> np.ndarray:
        """(K, 3) world ``x, z, yaw`` (degrees) of the kept views."""
        p = self.poses_ros[self.kept]
        x, z, yaw = ros_to_world(p[:, 0], p[:, 1], p[:, 2])
        return np.column_stack([x, z, yaw]).reshape(-1, 3)


def _pick(bag: Bag, given: str | None, types: Sequence[str], role: str, option: str, required: bool = True) -> Topic | None:
    topics = bag.topics
    if given:
        t = topics.get(given)
        if t is None:
            raise BagError(f"{bag.path}: {option}={given}: no such topic; topics are "
                           f"{sorted(f'{k} ({v.msgtype})' for k, v in topics.items())}")
        if t.msgtype not in types:
            raise BagError(f"{bag.path}: {option}={given} has type {t.msgtype}; expected {' or '.join(types)}")
        return t
    found = [t for t in topics.values() if t.msgtype in types and t.count > 0]
    if len(found) == 1:
        return found[0]
    if len(found) > 1:
        raise BagError(f"{bag.path}: {len(found)} {role} topics {sorted(t.name for t in found)}; choose one with "
                       f"{option}=<topic>")
    if required:
        raise BagError(f"{bag.path}: no {role} topic (type {' or '.join(types)}); topics are "
                       f"{sorted(f'{k} ({v.msgtype})' for k, v in topics.items())}")
    return None


def choose_topics(bag: Bag, opt: BagOptions, need_views: bool = True) -> dict[str, Any]:
    """The topic of each role (see the module doc), checked against the bag's topics.

    Raises:
        BagError: a named topic that is missing or of the wrong type, a role with no topic,
            or several candidates (one line naming the bag and the option to set)."""
    out: dict[str, Any] = {"map": _pick(bag, opt.map_topic, MAP_TYPES, "map", "bag_options.map_topic")}
    if not need_views:
        return out
    if opt.view_topic:
        out["views"] = _pick(bag, opt.view_topic, VIEW_TYPES, "view", "bag_options.view_topic")
    else:
        labels = _pick(bag, None, LABEL_TYPES, "label", "bag_options.view_topic", required=False)
        out["views"] = labels or _pick(bag, None, IMAGE_TYPES, "view (label or image)", "bag_options.view_topic")
    out["tf"] = [t.name for t in bag.topics.values() if t.msgtype in TF_TYPES]
    out["poses"] = _pick(bag, opt.pose_topic, POSE_TYPES, "pose", "bag_options.pose_topic",
                         required=False) if (opt.pose_topic or not out["tf"]) else None
    if out["poses"] is None and not out["tf"]:
        raise BagError(f"{bag.path}: no tf (/tf, /tf_static) and no pose topic (PoseStamped, "
                       f"PoseWithCovarianceStamped, Odometry); the views cannot be placed")
    out["camera_info"] = (_pick(bag, opt.camera_info_topic, CAMERA_INFO_TYPES, "camera info", "bag_options.camera_info_topic",
                                required=False)
                          if out["views"].msgtype in IMAGE_TYPES or opt.camera_info_topic else None)
    return out


def _shown(name: str, most: int = 40) -> str:
    """A class name for a message: quoted and escaped (a NUL, a direction override show as
    ``\\x00``, ``\\u202e``), cut to ``most`` characters."""
    return repr(name[:most]) + ("..." if len(name) > most else "")


def class_name_problem(name: str) -> str | None:
    """Why ``name`` cannot be a class name, or None: over :data:`MAX_LABEL_BYTES` UTF-8 bytes,
    or a character that is not a letter, digit, combining mark or one of
    :data:`NAME_PUNCTUATION` (a control or format character such as NUL or U+202E, ``<``)."""
    n = len(name.encode("utf-8", "replace"))
    if n > MAX_LABEL_BYTES:
        return f"is {n} bytes, over the limit of {MAX_LABEL_BYTES} bytes a class name"
    for ch in name:
        if not (unicodedata.category(ch)[0] in "LMN" or ch in NAME_PUNCTUATION):
            return (f"holds {ch!r} (U+{ord(ch):04X}); expected letters, digits, spaces and "
                    f"{NAME_PUNCTUATION.strip()!r}")
    return None


def check_label(label: str | dict[str, float], classes: Sequence[str] | None, where: str) -> str | dict[str, float]:
    """A view's label (a class name, or class scores) bounded before it is kept: each name is
    one of ``classes`` (class scores by name, case and spaces aside, as a labels file's
    columns), or a class name (:func:`class_name_problem`). Whether a name is in the class list
    is checked once all labels are read (``envs.bags.views.check_label_names``).

    Raises:
        BagError: one line naming ``where`` (topic and stamp), the name (cut short) and what
            was expected."""
    names = [label] if isinstance(label, str) else list(label)
    known = set() if classes is None else set(classes) | {c.strip().lower() for c in classes}
    for name in names:
        if name in known or name.strip().lower() in known:
            continue
        why = class_name_problem(name)
        if why is not None:
            raise BagError(f"{where}: class name {_shown(name)} {why}")
    return label


def _check_map_size(msg: Any, limit: int | None, where: str) -> None:
    """An OccupancyGrid's declared width x height against the map-size limit (the limit of
    image maps, ``max_map_pixels``, 20 M cells), before its cells are read.

    Raises:
        BagError: over the limit (one line naming the message, the size and the limit)."""
    w, h = int(msg.info.width), int(msg.info.height)
    if limit is not None and w * h > limit:
        raise BagError(f"{where}: OccupancyGrid of {w} x {h} = {w * h} cells, over the map-size limit of {limit} "
                       f"pixels (max_map_pixels); expected a smaller map, or raise max_map_pixels")


def _tf_add(tf: TfBuffer, path: Path, *sample) -> None:
    """:meth:`TfBuffer.add` with the bag named in its error (a non-finite transform, a frame
    with two parents: the topic, edge and stamp are in the message)."""
    try:
        tf.add(*sample)
    except BagError as e:
        raise BagError(f"{path} {e}") from None


def _pose_of(msg: Any, msgtype: str) -> tuple[Any, str | None]:
    if msgtype == "geometry_msgs/msg/PoseStamped":
        return msg.pose, None
    if msgtype == "nav_msgs/msg/Odometry":
        return msg.pose.pose, str(msg.child_frame_id).lstrip("/") or None
    return msg.pose.pose, None


class _Clock:
    """Watches header stamp minus record time per stream: a change larger than the limit is
    a clock jump."""

    def __init__(self, limit_ns: int):
        self.limit, self.last = int(limit_ns), {}

    def check(self, key: str, stamp: int, record: int, path: Path) -> None:
        off = stamp - record
        prev = self.last.get(key)
        if prev is not None and abs(off - prev) > self.limit:
            raise BagError(f"{path}: {key}: the clock jumps by {(off - prev) / 1e9:+.3f} s at {stamp_s(stamp)} "
                           f"(header stamp against record time; bag_options.max_clock_jump_s={self.limit / 1e9:g})")
        self.last[key] = off


def read_bag(path: str | Path, opt: BagOptions = BagOptions(), need_views: bool = True,
             progress: bool = False) -> BagViews:
    """Pass 1 over the bag (see the module doc): map, transforms, the views' poses and labels.

    Raises:
        BagError: one line naming the file, topic or stamp (missing topic, no transform at a
            view's stamp, an unreadable file, an unknown type, a map that changes size, a
            clock that jumps)."""
    path = Path(path).expanduser()
    with open_bag(path, opt.max_message_bytes) as bag:
        topics = choose_topics(bag, opt, need_views)
        topics_all = bag.topics
        map_t: Topic = topics["map"]
        names = [map_t.name]
        if need_views:
            names += [topics["views"].name, *topics["tf"]]
            names += [t.name for t in (topics["poses"], topics["camera_info"]) if t is not None]
        tf = TfBuffer(int(opt.tf_tolerance_s * 1e9), int(opt.tf_max_gap_s * 1e9))
        clock = _Clock(int(opt.max_clock_jump_s * 1e9))
        chosen: MapMessage | None = None
        first_geom: tuple | None = None
        first_text = ""
        n_maps = 0
        want_ns = map_stamp_ns(opt.map_stamp)
        map_stamps: list[int] = []
        vt = topics.get("views")
        stamps, records, vframe, labels_all = [], [], None, []
        hfov = None
        pose_child = _pose_child(bag, topics["poses"]) if need_views and topics.get("poses") is not None else None
        total = sum(bag.topics[n].count for n in names)
        bar = None
        if progress:
            from tqdm import tqdm  # noqa: PLC0415

            bar = tqdm(total=total, desc=f"reading {path.name}", unit="msg", mininterval=1.0)
        for topic, msgtype, t, msg in bag.messages(names):
            if bar is not None:
                bar.update(1)
            if topic == map_t.name:
                st = header_ns(msg, t)
                map_stamps.append(st)
                if want_ns is not None and st > want_ns:  # never a later map in its place
                    continue
                _check_map_size(msg, opt.max_map_pixels, f"{path} {topic} at {stamp_s(st)}")
                m = map_message(msg, f"{path} {topic}", st)
                n_maps += 1
                if first_geom is None:
                    first_geom, first_text = m.geometry, m.shape_text()
                elif m.geometry != first_geom and want_ns is None:
                    raise BagError(f"{path} {topic}: the map changes at {stamp_s(st)} from {first_text} to "
                                   f"{m.shape_text()}; a moving or growing map is not supported (pass "
                                   f"bag_options.map_stamp=<seconds> to use one map message)")
                chosen = m
            elif msgtype in TF_TYPES:
                static = "static" in topic
                for ts in msg.transforms:
                    st = header_ns(ts, t)
                    child = str(ts.child_frame_id).lstrip("/")
                    if pose_child is not None and child == pose_child:
                        continue
                    if not static:
                        clock.check(f"{topic} {ts.header.frame_id} -> {child}", st, t, path)
                    tr, q = ts.transform.translation, ts.transform.rotation
                    _tf_add(tf, path, str(ts.header.frame_id), child, st, (tr.x, tr.y, tr.z), (q.x, q.y, q.z, q.w),
                            static, topic)
            elif topics.get("poses") is not None and topic == topics["poses"].name:
                st = header_ns(msg, t)
                clock.check(topic, st, t, path)
                pose, _ = _pose_of(msg, msgtype)
                p, q = pose.position, pose.orientation
                _tf_add(tf, path, str(msg.header.frame_id), pose_child, st, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w),
                        False, topic)
            elif topics.get("camera_info") is not None and topic == topics["camera_info"].name:
                if hfov is None:
                    hfov = horizontal_fov_deg(msg, f"{path} {topic} at {stamp_s(t)}")
            elif vt is not None and topic == vt.name:
                st = header_ns(msg, t)
                clock.check(topic, st, t, path)
                if vframe is None and getattr(msg, "header", None) is not None and str(msg.header.frame_id).strip():
                    vframe = str(msg.header.frame_id).strip().lstrip("/")
                stamps.append(st)
                records.append(t)
                if msgtype in LABEL_TYPES:
                    where = f"{path} {topic} at {stamp_s(st)}"
                    labels_all.append(check_label(view_label(msg, msgtype, where, opt.classes), opt.classes, where))
        if bar is not None:
            bar.close()
    if chosen is None:  # no map, or none at or before bag_options.map_stamp: one line listing the map stamps
        map_before(map_stamps, want_ns, f"{path} {map_t.name}")
        raise BagError(f"{path} {map_t.name}: no OccupancyGrid message")
    grid = grid_from_map(chosen, opt.unknown_as, opt.free_max)
    map_frame = map_frame_of(chosen, opt.map_frame, f"{path} {map_t.name}")
    if not need_views:
        return BagViews(path, chosen, grid, topics, "none", "", map_frame, "", np.zeros(0, np.int64),
                        np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64), n_map_messages=n_maps)
    if not stamps:
        raise BagError(f"{path} {vt.name}: no view messages")
    cam = _camera_frame(opt, vframe, pose_child, tf, path, vt.name)
    fwd = forward_axis(cam, opt.camera_axis)
    poses = np.zeros((len(stamps), 3))
    for i, st in enumerate(stamps):
        where = f"{path} {vt.name} view {i} at {stamp_s(st)}"
        try:
            m = tf.lookup(map_frame, cam, st)
        except BagError as e:
            hint = ""
            unused = sorted(t.name for t in topics_all.values() if t.msgtype in POSE_TYPES)
            if "not connected" in str(e) and unused and topics.get("poses") is None:
                hint = f"; pose topics in the bag: {unused}; bag_options.pose_topic=<topic> uses one"
            raise BagError(f"{where}: {e}{hint}") from None
        poses[i] = planar_pose(m, fwd, where)
    kept = subsample(poses, opt.min_distance_m, opt.min_turn_deg)
    kind = "labels" if vt.msgtype in LABEL_TYPES else "images"
    labels = [labels_all[i] for i in kept] if kind == "labels" else []
    return BagViews(path, chosen, grid, topics, kind, vt.msgtype, map_frame, cam, np.asarray(stamps, np.int64),
                    np.asarray(records, np.int64), poses, kept, labels, hfov, n_maps)


def _pose_child(bag: Bag, topic: Topic) -> str:
    """The frame a pose topic places: an Odometry's ``child_frame_id`` (its tf edge, if the bag
    also has one, is then left out: the pose topic wins), else the topic's name."""
    for _, msgtype, _, msg in bag.messages([topic.name]):
        child = _pose_of(msg, msgtype)[1]
        return child or topic.name.strip("/")
    return topic.name.strip("/")


def _camera_frame(opt: BagOptions, vframe: str | None, pose_child: str | None, tf: TfBuffer, path: Path,
                  topic: str) -> str:
    """The frame whose pose is each view's pose: ``bag_options.camera_frame``, else the views'
    header frame (when tf knows it), else the pose topic's frame, else ``base_link`` (label
    messages without a header)."""
    if opt.camera_frame:
        return opt.camera_frame.lstrip("/")
    if vframe and (vframe in tf.frames or pose_child is None):
        return vframe
    if pose_child is not None:
        return pose_child
    if "base_link" in tf.frames:
        return "base_link"
    raise BagError(f"{path} {topic}: the views carry no frame and the bag has no base_link; pass "
                   f"bag_options.camera_frame=<frame> (frames are {sorted(tf.frames)})")


def iter_images(views: BagViews, chunk: int = 64, progress: bool = False) -> Iterator[list[tuple[int, np.ndarray]]]:
    """Pass 2: the kept views' images, decoded only for those kept, in lists of up to ``chunk``
    ``(view index into kept, (H, W, 3) uint8 RGB)``."""
    keep = set(int(i) for i in views.kept)
    out: list[tuple[int, np.ndarray]] = []
    topic = views.topics["views"].name
    bar = None
    if progress:
        from tqdm import tqdm  # noqa: PLC0415

        bar = tqdm(total=len(views.kept), desc="decoding kept images", unit="img", mininterval=1.0)
    pos = {int(v): k for k, v in enumerate(views.kept)}
    with open_bag(views.path) as bag:
        i = -1
        for _, msgtype, _t, msg in bag.messages([topic]):
            i += 1
            if i not in keep:
                continue
            out.append((pos[i], decode_image(msg, msgtype, f"{views.path} {topic} view {i} at "
                                                           f"{stamp_s(int(views.stamps[i]))}")))
            if bar is not None:
                bar.update(1)
            if len(out) >= chunk:
                yield out
                out = []
    if out:
        yield out
    if bar is not None:
        bar.close()
