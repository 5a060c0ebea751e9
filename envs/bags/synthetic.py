"""Write a robot's recording as a bag, for tests and measurements: a map, a tf tree along a
route, and per view a label or an image, with ``rosbags``' writers (ROS 1, ROS 2 sqlite3,
MCAP).

The tf tree is the usual one (REP 105): ``map -> odom`` (a fixed offset, published on ``/tf``
at every view, as a localiser does), ``odom -> base_link`` (the route, on ``/tf`` at every
view's stamp), ``base_link -> camera_link`` (a fixed mount ``camera_offset_m`` ahead, on
``/tf_static``) and ``camera_link -> camera_optical_frame`` (the optical rotation: z forward,
x right, y down). The views' headers name ``camera_optical_frame``, so their poses in the map
are the route's poses exactly (to rounding). What it leaves out: sensor noise, message delays
(each view's transform is stamped at the view), odometry drift.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from envs.bags.source import require_rosbags

FORMATS = ("ros1", "sqlite3", "mcap")
#: Type definitions of the vision_msgs messages the tests publish (not in rosbags' stores).
VISION_MSGS_ROS2 = {
    "vision_msgs/msg/ObjectHypothesis": "string class_id\nfloat64 score\n",
    "vision_msgs/msg/Classification": "std_msgs/Header header\nvision_msgs/ObjectHypothesis[] results\n",
    "vision_msgs/msg/VisionClass": "uint16 class_id\nstring class_name\n",
    "vision_msgs/msg/LabelInfo": "std_msgs/Header header\nvision_msgs/VisionClass[] class_map\nfloat32 threshold\n",
}
VISION_MSGS_ROS1 = {
    "tf2_msgs/msg/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
    "vision_msgs/msg/ObjectHypothesis": "int64 id\nfloat64 score\n",
    "vision_msgs/msg/Classification2D": ("std_msgs/Header header\nvision_msgs/ObjectHypothesis[] results\n"
                                         "sensor_msgs/Image source_img\n"),
}


@dataclass
class RobotRun:
    """What to write (see the module doc).

    Attributes:
        occupancy: (H, W) int8 cell values (-1 unknown, 0 free, 100 occupied), row 0 on top.
        resolution: metres per cell; ros_origin: ROS origin (x, y) of the bottom-left corner.
        route: (N, 3) the camera's ROS ``x, y, theta`` in the map per view.
        stamps_ns: (N,) the views' stamps (header and record time), increasing.
        labels: N class names (label views), or None.
        image: i -> (H, W, 3) uint8 RGB of view i (image views), or None.
        map_to_odom: (x, y, theta) of odom in map.
        camera_offset_m: the camera's mount ahead of base_link along its x.
        label_type: ``string`` | ``classification`` (vision_msgs; ROS 1 ``Classification2D``
            with ids into ``classes``).
        image_format: ``raw`` (rgb8 Image) | ``jpeg`` | ``png`` (CompressedImage).
        hfov_deg: the CameraInfo's horizontal field of view (image views).
        map_stamps_ns: when the map is published (default: once, at the first stamp).
        map_sizes: per map message an (H, W) to publish instead (a map that changes size).
        tf_stamps_shift_ns: shift of the ``/tf`` stamps against the views' (a clock that jumps).
        pose_topic: also publish the poses on a topic: ``pose`` (``/camera_pose``, a
            PoseStamped of the camera in ``map``, and no tf at all) or ``odometry``
            (``/odom``, Odometry ``odom -> base_link``; ``/tf`` then holds ``map -> odom`` only).
        publish_map_to_odom: False leaves ``map -> odom`` out of ``/tf`` (no localiser recorded;
            odom still sits at ``map_to_odom`` in the map).
        label_info: also publish ``classes`` as a ``vision_msgs/LabelInfo`` on ``/label_info``
            (ROS 2 bags; ``class_id`` = the index in ``classes``).
    """

    occupancy: np.ndarray
    resolution: float
    ros_origin: tuple[float, float]
    route: np.ndarray
    stamps_ns: np.ndarray
    labels: Sequence[str] | None = None
    image: Callable[[int], np.ndarray] | None = None
    classes: Sequence[str] | None = None
    map_to_odom: tuple[float, float, float] = (0.7, -0.4, 0.3)
    camera_offset_m: float = 0.2
    label_type: str = "string"
    image_format: str = "raw"
    hfov_deg: float = 90.0
    map_stamps_ns: Sequence[int] | None = None
    map_sizes: Sequence[tuple[int, int]] | None = None
    tf_stamps_shift_ns: int = 0
    pose_topic: str | None = None
    publish_map_to_odom: bool = True
    label_info: bool = False


def _quat_z(theta: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(theta / 2), math.cos(theta / 2))


def _compose(a, b):
    """SE(2) a * b, each (x, y, theta)."""
    ax, ay, at = a
    bx, by, bt = b
    return (ax + math.cos(at) * bx - math.sin(at) * by, ay + math.sin(at) * bx + math.cos(at) * by, at + bt)


def _inverse(a):
    x, y, t = a
    return (-(math.cos(t) * x + math.sin(t) * y), math.sin(t) * x - math.cos(t) * y, -t)


def write_robot_bag(path: str | Path, fmt: str, run: RobotRun) -> Path:
    """Write ``run`` as a bag at ``path`` (a ``.bag`` file for ``ros1``, a bag folder for
    ``sqlite3`` and ``mcap``). Returns the path."""
    if fmt not in FORMATS:
        raise ValueError(f"fmt={fmt!r}; expected one of {list(FORMATS)}")
    require_rosbags()
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore  # noqa: PLC0415

    ros1 = fmt == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    vision = VISION_MSGS_ROS1 if ros1 else VISION_MSGS_ROS2
    add = {}
    for name, text in vision.items():
        add.update(get_types_from_msg(text, name))
    store.register(add)
    T = store.types
    ser = store.serialize_ros1 if ros1 else store.serialize_cdr
    path = Path(path)

    def header(ns: int, frame: str):
        st = T["builtin_interfaces/msg/Time"](sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))
        return T["std_msgs/msg/Header"](seq=0, stamp=st, frame_id=frame) if ros1 else \
            T["std_msgs/msg/Header"](stamp=st, frame_id=frame)

    def tfs(ns: int, parent: str, child: str, x: float, y: float, z: float, q):
        V, Q = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
        tr = T["geometry_msgs/msg/Transform"](translation=V(x=x, y=y, z=z), rotation=Q(x=q[0], y=q[1], z=q[2], w=q[3]))
        return T["geometry_msgs/msg/TransformStamped"](header=header(ns, parent), child_frame_id=child, transform=tr)

    def grid_msg(ns: int, values: np.ndarray):
        h, w = values.shape
        P, Q = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
        pose = T["geometry_msgs/msg/Pose"](position=P(x=float(run.ros_origin[0]), y=float(run.ros_origin[1]), z=0.0),
                                            orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0))
        st = T["builtin_interfaces/msg/Time"](sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))
        info = T["nav_msgs/msg/MapMetaData"](map_load_time=st, resolution=float(run.resolution), width=w, height=h,
                                              origin=pose)
        return T["nav_msgs/msg/OccupancyGrid"](header=header(ns, "map"), info=info,
                                               data=np.ascontiguousarray(values[::-1]).astype(np.int8).ravel())

    stamps = np.asarray(run.stamps_ns, np.int64)
    msgs: list[tuple[int, str, str, object]] = []  # (record ns, topic, type, message)
    map_stamps = list(run.map_stamps_ns) if run.map_stamps_ns is not None else [int(stamps[0])]
    for k, ns in enumerate(map_stamps):
        vals = run.occupancy
        if run.map_sizes is not None:
            h, w = run.map_sizes[k]
            vals = np.full((h, w), -1, np.int8)
            hh, ww = min(h, run.occupancy.shape[0]), min(w, run.occupancy.shape[1])
            vals[:hh, :ww] = run.occupancy[:hh, :ww]
        msgs.append((int(ns), "/map", "nav_msgs/msg/OccupancyGrid", grid_msg(int(ns), vals)))
    TF = T["tf2_msgs/msg/TFMessage"]
    # camera_link -> optical: z forward (= camera_link x), x right (= -y), y down (= -z): rpy (-pi/2, 0, -pi/2)
    q_opt = (-0.5, 0.5, -0.5, 0.5)
    static = TF(transforms=[tfs(int(stamps[0]), "base_link", "camera_link", run.camera_offset_m, 0.0, 0.5, (0, 0, 0, 1)),
                            tfs(int(stamps[0]), "camera_link", "camera_optical_frame", 0.0, 0.0, 0.0, q_opt)])
    if run.pose_topic != "pose":
        msgs.append((int(stamps[0]), "/tf_static", "tf2_msgs/msg/TFMessage", static))
    m2o = run.map_to_odom
    cam_in_base = (run.camera_offset_m, 0.0, 0.0)
    o2m = _inverse(m2o)
    for i, (pose, ns) in enumerate(zip(run.route, stamps)):
        base = _compose(tuple(float(v) for v in pose), _inverse(cam_in_base))
        ob = _compose(o2m, base)
        tns = int(ns) + int(run.tf_stamps_shift_ns)
        edges = [tfs(tns, "map", "odom", m2o[0], m2o[1], 0.0, _quat_z(m2o[2]))] if run.publish_map_to_odom else []
        if run.pose_topic is None:
            edges.append(tfs(tns, "odom", "base_link", ob[0], ob[1], 0.0, _quat_z(ob[2])))
        if run.pose_topic != "pose":
            msgs.append((int(ns), "/tf", "tf2_msgs/msg/TFMessage", TF(transforms=edges)))
        if run.pose_topic is not None:
            P, Q = T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
            x, y, t = (float(v) for v in pose) if run.pose_topic == "pose" else ob
            qz = _quat_z(t)
            ps = T["geometry_msgs/msg/Pose"](position=P(x=x, y=y, z=0.0),
                                             orientation=Q(x=qz[0], y=qz[1], z=qz[2], w=qz[3]))
            if run.pose_topic == "pose":
                msgs.append((int(ns), "/camera_pose", "geometry_msgs/msg/PoseStamped",
                             T["geometry_msgs/msg/PoseStamped"](header=header(int(ns), "map"), pose=ps)))
            else:
                V = T["geometry_msgs/msg/Vector3"]
                tw = T["geometry_msgs/msg/Twist"](linear=V(x=0.0, y=0.0, z=0.0), angular=V(x=0.0, y=0.0, z=0.0))
                msgs.append((int(ns), "/odom", "nav_msgs/msg/Odometry", T["nav_msgs/msg/Odometry"](
                    header=header(int(ns), "odom"), child_frame_id="base_link",
                    pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=ps, covariance=np.zeros(36)),
                    twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=tw, covariance=np.zeros(36)))))
        h = header(int(ns), "camera_optical_frame")
        if run.labels is not None:
            if run.label_type == "string":
                msgs.append((int(ns), "/room_label", "std_msgs/msg/String", T["std_msgs/msg/String"](data=run.labels[i])))
            elif ros1:
                hyp = T["vision_msgs/msg/ObjectHypothesis"](id=list(run.classes).index(run.labels[i]), score=1.0)
                img = T["sensor_msgs/msg/Image"](header=h, height=0, width=0, encoding="", is_bigendian=0, step=0,
                                                 data=np.zeros(0, np.uint8))
                msgs.append((int(ns), "/room_class", "vision_msgs/msg/Classification2D",
                             T["vision_msgs/msg/Classification2D"](header=h, results=[hyp], source_img=img)))
            else:
                hyp = T["vision_msgs/msg/ObjectHypothesis"](class_id=run.labels[i], score=1.0)
                msgs.append((int(ns), "/room_class", "vision_msgs/msg/Classification",
                             T["vision_msgs/msg/Classification"](header=h, results=[hyp])))
        if run.image is not None:
            rgb = np.ascontiguousarray(run.image(i), dtype=np.uint8)
            if run.image_format == "raw":
                im = T["sensor_msgs/msg/Image"](header=h, height=rgb.shape[0], width=rgb.shape[1], encoding="rgb8",
                                                is_bigendian=0, step=rgb.shape[1] * 3, data=rgb.ravel())
                msgs.append((int(ns), "/camera/image_raw", "sensor_msgs/msg/Image", im))
            else:
                import io  # noqa: PLC0415

                from PIL import Image  # noqa: PLC0415

                buf = io.BytesIO()
                Image.fromarray(rgb).save(buf, format="JPEG" if run.image_format == "jpeg" else "PNG", quality=90)
                im = T["sensor_msgs/msg/CompressedImage"](header=h, format=run.image_format,
                                                          data=np.frombuffer(buf.getvalue(), np.uint8))
                msgs.append((int(ns), "/camera/image_raw/compressed", "sensor_msgs/msg/CompressedImage", im))
            if i == 0:
                w_px, h_px = rgb.shape[1], rgb.shape[0]
                fx = w_px / (2 * math.tan(math.radians(run.hfov_deg) / 2))
                k = np.array([fx, 0, w_px / 2, 0, fx, h_px / 2, 0, 0, 1], float)
                kw = dict(header=h, height=h_px, width=w_px, distortion_model="plumb_bob",
                          binning_x=0, binning_y=0,
                          roi=T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0,
                                                                    do_rectify=False))
                if ros1:
                    kw.update(D=np.zeros(5), K=k, R=np.eye(3).ravel(), P=np.zeros(12))
                else:
                    kw.update(d=np.zeros(5), k=k, r=np.eye(3).ravel(), p=np.zeros(12))
                msgs.append((int(ns), "/camera/camera_info", "sensor_msgs/msg/CameraInfo",
                             T["sensor_msgs/msg/CameraInfo"](**kw)))
    if run.label_info:
        VC = T["vision_msgs/msg/VisionClass"]
        msgs.append((int(stamps[0]), "/label_info", "vision_msgs/msg/LabelInfo", T["vision_msgs/msg/LabelInfo"](
            header=header(int(stamps[0]), ""), class_map=[VC(class_id=k, class_name=str(c))
                                                       for k, c in enumerate(run.classes)], threshold=0.5)))
    msgs.sort(key=lambda m: m[0])
    _write(path, fmt, store, ser, msgs)
    return path


def _write(path: Path, fmt: str, store, ser, msgs) -> None:
    conns: dict[str, object] = {}
    if fmt == "ros1":
        from rosbags.rosbag1 import Writer  # noqa: PLC0415

        w = Writer(path)
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer  # noqa: PLC0415

        w = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP if fmt == "mcap" else StoragePlugin.SQLITE3)
    with w:
        for ns, topic, typ, msg in msgs:
            if topic not in conns:
                kw = {"latching": 1} if fmt == "ros1" and topic in ("/tf_static", "/map") else {}
                conns[topic] = w.add_connection(topic, typ, typestore=store, **kw)
            w.write(conns[topic], ns, ser(msg, typ))
