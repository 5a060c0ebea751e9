"""envs/bags: bags written with rosbags' writers (ROS 1, ROS 2 sqlite3, MCAP) from the example
building's autotrace run read back into the map, poses and views; tf interpolation against
SciPy; every bad-bag case is one line naming the file, topic or stamp."""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest

pytest.importorskip("rosbags")

from bag_run import PAPER_CLASSES, RES, house  # noqa: E402

from envs.bags.read import BagOptions, iter_images, read_bag  # noqa: E402
from envs.bags.source import BagError  # noqa: E402
from envs.bags.synthetic import write_robot_bag  # noqa: E402
from envs.bags.transforms import TfBuffer  # noqa: E402
from envs.bags.views import subsample  # noqa: E402
from envs.maps.ros import read_ros_map  # noqa: E402

ALL = BagOptions(min_distance_m=0, min_turn_deg=0, classes=tuple(PAPER_CLASSES))


@pytest.fixture(scope="module")
def h():
    return house()


def _path(tmp_path, fmt, name="run"):
    return tmp_path / (f"{name}.bag" if fmt == "ros1" else name)


def _angle_diff(a, b):
    return np.abs((np.asarray(a) - np.asarray(b) + np.pi) % (2 * np.pi) - np.pi)


@pytest.mark.parametrize("fmt,label_type", [("ros1", "classification"), ("sqlite3", "classification"),
                                            ("mcap", "string"), ("ros1", "string")])
def test_read_bag_gives_map_poses_and_labels(tmp_path, h, fmt, label_type):
    p = write_robot_bag(_path(tmp_path, fmt), fmt, h.run(label_type=label_type))
    opt = ALL if label_type != "string" else BagOptions(min_distance_m=0, min_turn_deg=0,
                                                        camera_frame="camera_optical_frame")
    v = read_bag(p, opt)
    # the map: the grid read_ros_map gives for the same map saved by map_server, exactly
    from bag_run import write_files

    write_files(h, tmp_path / "files")
    m = read_ros_map(tmp_path / "files" / "map.yaml")
    assert np.array_equal(v.grid.walkable, m.grid.walkable)
    assert v.grid.origin == m.grid.origin and v.grid.resolution == RES == m.grid.resolution
    assert v.map.ros_origin == (-3.25, 1.5, 0.0) and v.map_frame == "map"
    # the poses: map -> odom -> base_link -> camera_link -> camera_optical_frame at each stamp
    assert v.camera_frame == "camera_optical_frame" and len(v.kept) == len(h.route)
    assert np.abs(v.poses_ros[:, :2] - h.route[:, :2]).max() < 1e-9
    assert _angle_diff(v.poses_ros[:, 2], h.route[:, 2]).max() < 1e-9
    assert np.abs(v.poses[:, :2] - h.poses[:, :2]).max() < 1e-9
    names = [lab if isinstance(lab, str) else max(lab, key=lab.get) for lab in v.labels]
    assert names == h.labels and v.kind == "labels"


def test_header_less_labels_default_to_base_link(tmp_path, h):
    """A String label has no frame: the view is placed at base_link, 0.2 m behind the camera."""
    p = write_robot_bag(tmp_path / "run.bag", "ros1", h.run(label_type="string", camera_offset_m=0.2))
    v = read_bag(p, BagOptions(min_distance_m=0, min_turn_deg=0))
    assert v.camera_frame == "base_link"
    d = np.hypot(*(v.poses_ros[:, :2] - h.route[:, :2]).T)
    assert np.allclose(d, 0.2, atol=1e-9)


@pytest.mark.parametrize("fmt,image_format", [("ros1", "raw"), ("sqlite3", "png"), ("mcap", "jpeg")])
def test_images_decode_only_kept(tmp_path, h, fmt, image_format):
    n = 40
    run = h.run(labels=None, image=h.view_image, image_format=image_format, hfov_deg=70.0)
    run.route, run.stamps_ns = h.route[:n], h.stamps[:n]
    p = write_robot_bag(_path(tmp_path, fmt), fmt, run)
    v = read_bag(p, BagOptions(min_distance_m=1.0, min_turn_deg=90.0))
    assert v.kind == "images" and v.hfov_deg == pytest.approx(70.0, abs=1e-9)
    assert np.array_equal(v.kept, subsample(h.route[:n], 1.0, 90.0))
    got = {k: img for chunk in iter_images(v, chunk=3) for k, img in chunk}
    assert sorted(got) == list(range(len(v.kept)))
    for k, i in enumerate(v.kept):
        want = h.view_image(int(i))
        if image_format == "jpeg":  # lossy: the class colour survives
            assert np.abs(got[k][4:, :, :].astype(int) - want[4:].astype(int)).max() <= 12
        else:
            assert np.array_equal(got[k], want)


def test_subsample_known_answer():
    # along x every 0.4 m, then turning on the spot in 30 degree steps
    route = [(0.4 * i, 0.0, 0.0) for i in range(6)] + [(2.0, 0.0, math.radians(30 * k)) for k in range(1, 7)]
    kept = subsample(np.array(route), 1.0, 90.0)
    # moved 1.2 m at index 3; at 2.0 m (index 5) only 0.8 m since; turns of 90 and 180 at 8 and 11
    assert kept.tolist() == [0, 3, 8, 11]
    assert subsample(np.array(route), 0.0, 0.0).tolist() == list(range(len(route)))


def test_tf_lookup_against_scipy():
    """A chain of three edges, two dynamic, against SciPy's Rotation / Slerp (no shared code)."""
    from scipy.spatial.transform import Rotation, Slerp

    rng = np.random.default_rng(3)
    buf = TfBuffer(tolerance_ns=0, max_gap_ns=10**12)
    edges = {}
    for parent, child, static in (("map", "odom", False), ("odom", "base", False), ("base", "cam", True)):
        ts = np.array([0]) if static else np.sort(rng.choice(10**9, 6, replace=False))
        ts[0] = 0
        if not static:
            ts[-1] = 10**9
        tr = rng.normal(size=(len(ts), 3))
        rot = Rotation.random(len(ts), random_state=rng)
        for t, a, q in zip(ts, tr, rot.as_quat()):
            buf.add(parent, child, int(t), a, q, static, "/tf")
        edges[child] = (ts, tr, rot)
    for t in rng.integers(0, 10**9, 20):
        want = np.eye(4)
        for child in ("odom", "base", "cam"):
            ts, tr, rot = edges[child]
            m = np.eye(4)
            if len(ts) == 1:
                m[:3, :3], m[:3, 3] = rot[0].as_matrix(), tr[0]
            else:
                m[:3, :3] = Slerp(ts, rot)([t]).as_matrix()[0]
                m[:3, 3] = [np.interp(t, ts, tr[:, k]) for k in range(3)]
            want = want @ m
        got = buf.lookup("map", "cam", int(t))
        assert np.abs(got - want).max() < 1e-9
        assert np.abs(buf.lookup("cam", "map", int(t)) @ want - np.eye(4)).max() < 1e-9


# --------------------------------------------------------------------------- bad bags


def test_missing_topic(tmp_path, h):
    p = write_robot_bag(tmp_path / "run.bag", "ros1", h.run())
    with pytest.raises(BagError, match=r"run.bag: bag_options.view_topic=/camera/labels: no such topic; topics are .*/room_label"):
        read_bag(p, BagOptions(view_topic="/camera/labels"))
    run = h.run(labels=None)
    q = write_robot_bag(tmp_path / "nolabels.bag", "ros1", run)
    with pytest.raises(BagError, match=r"nolabels.bag: no view \(label or image\) topic"):
        read_bag(q)


def _copy_ros1(src, dst, edit=None, extra=()):
    """Copy a ROS 1 bag message by message; ``edit(topic, t, raw)`` returns the new raw bytes
    or None to drop the message; ``extra`` adds (topic, msgtype, typestore, t, raw) messages."""
    from rosbags.rosbag1 import Reader, Writer

    with Reader(src) as r, Writer(dst) as w:
        conns = {c.id: w.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest)
                 for c in r.connections}
        for c, t, raw in r.messages():
            raw = raw if edit is None else edit(c.topic, t, raw)
            if raw is not None:
                w.write(conns[c.id], t, raw)
        for topic, msgtype, store, t, raw in extra:
            w.write(w.add_connection(topic, msgtype, typestore=store), t, raw)
    return dst


def test_no_transform_at_a_view_stamp(tmp_path, h):
    """The transforms end before the last view (a recorder that dropped /tf at the end)."""
    p = write_robot_bag(tmp_path / "run.bag", "ros1", h.run(label_type="classification"))
    read_bag(p, ALL)  # the whole bag reads
    last = int(h.stamps[-1])
    q = _copy_ros1(p, tmp_path / "cut.bag", lambda topic, t, raw: None if topic == "/tf" and t >= last - 5 * 10**8
                   else raw)
    # the first view past the last transform (21.2 s) by more than bag_options.tf_tolerance_s (0.1 s)
    with pytest.raises(BagError, match=r"cut.bag /room_class view 214 at 1700000021.400000000 s: tf odom -> base_link "
                                       r"\(/tf\): no transform at 1700000021.400000000 s; it has samples from "
                                       r"1700000000.000000000 s to 1700000021.200000000 s"):
        read_bag(q, ALL)


@pytest.mark.parametrize("fmt", ["ros1", "mcap", "sqlite3"])
def test_truncated_bag(tmp_path, h, fmt):
    p = write_robot_bag(_path(tmp_path, fmt), fmt, h.run())
    f = p if fmt == "ros1" else next(p.glob("*.mcap" if fmt == "mcap" else "*.db3"))
    data = f.read_bytes()
    f.write_bytes(data[: len(data) // 2])
    with pytest.raises(BagError, match=rf"{p.name}.*(not a readable bag|cannot read|cannot decode)"):
        read_bag(p, ALL)


def test_unindexed_ros1_bag(tmp_path, h):
    """A ROS 1 bag whose recorder died before writing the index (index_pos 0)."""
    p = write_robot_bag(tmp_path / "run.bag", "ros1", h.run())
    data = bytearray(p.read_bytes())
    at = data.index(b"index_pos=") + len(b"index_pos=")
    data[at:at + 8] = (0).to_bytes(8, "little")
    p.write_bytes(bytes(data))
    with pytest.raises(BagError, match=r"run.bag: not a readable bag: .*rosbag reindex"):
        read_bag(p, ALL)


def test_unknown_message_type(tmp_path, h):
    """A view topic of a type the segmenter cannot read (a robot's own message)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    p = write_robot_bag(tmp_path / "run.bag", "ros1", h.run(labels=None))
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg("string room\nfloat32 confidence\n", "my_msgs/msg/RoomGuess"))
    raw = store.serialize_ros1(store.types["my_msgs/msg/RoomGuess"](room="kitchen", confidence=0.9),
                               "my_msgs/msg/RoomGuess")
    q = _copy_ros1(p, tmp_path / "custom.bag", extra=[("/room_guess", "my_msgs/msg/RoomGuess", store, int(h.stamps[3]),
                                                      raw)])
    with pytest.raises(BagError, match=r"custom.bag: bag_options.view_topic=/room_guess has type my_msgs/msg/RoomGuess; "
                                       r"expected std_msgs/msg/String or .*"):
        read_bag(q, BagOptions(view_topic="/room_guess"))
    with pytest.raises(BagError, match=r"custom.bag: no view \(label or image\) topic"):
        read_bag(q)


def test_map_that_changes_size(tmp_path, h):
    run = h.run()
    H, W = h.occupancy.shape
    run.map_stamps_ns = [int(h.stamps[0]), int(h.stamps[100])]
    run.map_sizes = [(H, W), (H + 20, W)]
    p = write_robot_bag(tmp_path / "run.bag", "ros1", run)
    with pytest.raises(BagError, match=rf"run.bag /map: the map changes at 1700000010.000000000 s from {W} x {H} "
                                       rf"cells, 0.05 m, origin \[-3.25, 1.5\] to {W} x {H + 20} cells"):
        read_bag(p, ALL)
    v = read_bag(p, BagOptions(min_distance_m=0, min_turn_deg=0, classes=tuple(PAPER_CLASSES), map_stamp=1700000005.0))
    assert v.map.values.shape == (H, W)


def test_clock_that_jumps(tmp_path, h):
    """The views' header clock jumps 30 s ahead of the record time halfway (an NTP step)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    p = write_robot_bag(tmp_path / "run.bag", "ros1", h.run(label_type="classification"))
    store = get_typestore(Stores.ROS1_NOETIC)
    from envs.bags.synthetic import VISION_MSGS_ROS1

    for name, text in VISION_MSGS_ROS1.items():
        store.register(get_types_from_msg(text, name))
    mid = int(h.stamps[150])

    def jump(topic, t, raw):
        if topic != "/room_class" or t < mid:
            return raw
        msg = store.deserialize_ros1(raw, "vision_msgs/msg/Classification2D")
        msg.header.stamp.sec += 30
        return store.serialize_ros1(msg, "vision_msgs/msg/Classification2D")

    q = _copy_ros1(p, tmp_path / "jump.bag", jump)
    with pytest.raises(BagError, match=r"jump.bag: /room_class: the clock jumps by \+30.000 s at 1700000045.000000000 s"):
        read_bag(q, ALL)


def test_missing_rosbags_hint(monkeypatch):
    import builtins

    real = builtins.__import__

    def fake(name, *a, **k):
        if name.startswith("rosbags"):
            raise ImportError("No module named 'rosbags'")
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", fake)
    from envs.bags.source import require_rosbags

    with pytest.raises(ImportError, match=r"needs rosbags: make setup installs it \(or pip install rosbags\)"):
        require_rosbags()


def test_bag_that_does_not_exist(tmp_path):
    with pytest.raises(BagError, match=r"bag=.*nothere.bag does not exist"):
        read_bag(tmp_path / "nothere.bag")
    shutil.rmtree(tmp_path, ignore_errors=True)


@pytest.mark.parametrize("fmt,pose_topic", [("ros1", "pose"), ("mcap", "odometry")])
def test_pose_topics_instead_of_tf(tmp_path, h, fmt, pose_topic):
    """A PoseStamped of the camera in the map (no tf), or Odometry odom -> base_link chained
    with tf's map -> odom and the static camera mount."""
    from dataclasses import replace

    p = write_robot_bag(_path(tmp_path, fmt), fmt, h.run(label_type="classification", pose_topic=pose_topic))
    if pose_topic == "odometry":  # with tf in the bag, a pose topic is used when named
        with pytest.raises(BagError, match=r"'map' and 'camera_optical_frame' are not connected .*pose topics in "
                                           r"the bag: \['/odom'\]; bag_options.pose_topic=<topic>"):
            read_bag(p, ALL)
    v = read_bag(p, replace(ALL, pose_topic="/odom") if pose_topic == "odometry" else ALL)
    assert v.topics["poses"].name == ("/camera_pose" if pose_topic == "pose" else "/odom")
    assert v.camera_frame == ("camera_pose" if pose_topic == "pose" else "camera_optical_frame")
    assert np.abs(v.poses_ros[:, :2] - h.route[:, :2]).max() < 1e-9
    assert _angle_diff(v.poses_ros[:, 2], h.route[:, 2]).max() < 1e-9


def test_raw_image_encodings_known_answers():
    """Image encodings with a padded row step, against hand-written pixels."""
    from types import SimpleNamespace

    from envs.bags.views import decode_image

    def msg(enc, w, h, step, data, big=0):
        return SimpleNamespace(encoding=enc, width=w, height=h, step=step, is_bigendian=big,
                               data=np.frombuffer(bytes(data), np.uint8))

    # 2 x 1 bgr8 with 2 padding bytes: blue then red
    got = decode_image(msg("bgr8", 2, 1, 8, [255, 0, 0, 0, 0, 255, 9, 9]), "sensor_msgs/msg/Image", "t")
    assert got.tolist() == [[[0, 0, 255], [255, 0, 0]]]
    got = decode_image(msg("rgba8", 1, 2, 4, [1, 2, 3, 4, 5, 6, 7, 8]), "sensor_msgs/msg/Image", "t")
    assert got.tolist() == [[[1, 2, 3]], [[5, 6, 7]]]
    got = decode_image(msg("mono8", 2, 1, 3, [10, 20, 0]), "sensor_msgs/msg/Image", "t")
    assert got.tolist() == [[[10, 10, 10], [20, 20, 20]]]
    # mono16: scaled so the largest value is 255 (little and big endian)
    got = decode_image(msg("mono16", 2, 1, 4, [0, 0, 0xE8, 0x03]), "sensor_msgs/msg/Image", "t")
    assert got[0, :, 0].tolist() == [0, 255]
    got = decode_image(msg("16UC1", 2, 1, 4, [0x01, 0xF4, 0x03, 0xE8], big=1), "sensor_msgs/msg/Image", "t")
    assert got[0, :, 0].tolist() == [128, 255]
    with pytest.raises(BagError, match=r"t: image encoding 'bayer_rggb8'; expected one of"):
        decode_image(msg("bayer_rggb8", 1, 1, 1, [0]), "sensor_msgs/msg/Image", "t")
    with pytest.raises(BagError, match=r"t: image of 2 x 2 px, step 6, 6 bytes; expected step >= 6 and 12 bytes"):
        decode_image(msg("rgb8", 2, 2, 6, [0] * 6), "sensor_msgs/msg/Image", "t")
    bad = SimpleNamespace(format="jpeg", data=np.frombuffer(b"not a jpeg", np.uint8))
    with pytest.raises(BagError, match=r"t: CompressedImage \(format 'jpeg'\) does not decode"):
        decode_image(bad, "sensor_msgs/msg/CompressedImage", "t")


def test_occupancy_values_and_rotated_origin():
    from types import SimpleNamespace

    from envs.bags.occupancy import grid_from_map, map_message

    q0 = SimpleNamespace(x=0.0, y=0.0, z=0.0, w=1.0)
    info = SimpleNamespace(width=3, height=2, resolution=np.float32(0.05),
                           origin=SimpleNamespace(position=SimpleNamespace(x=1.0, y=2.0, z=0.0), orientation=q0))
    # row 0 of the message is the bottom row: [0, 25, 26] bottom, [-1, 100, 0] top
    m = map_message(SimpleNamespace(info=info, data=np.array([0, 25, 26, -1, 100, 0], np.int8),
                                    header=SimpleNamespace(frame_id="/map")), "b /map", 5)
    assert m.resolution == 0.05 and m.frame == "map" and m.values.tolist() == [[-1, 100, 0], [0, 25, 26]]
    g = grid_from_map(m)
    assert g.walkable.tolist() == [[False, False, True], [True, True, False]]
    assert g.origin == (1.0, 2.0 + 2 * 0.05)
    assert grid_from_map(m, "free").walkable[0, 0]
    info.origin.orientation = SimpleNamespace(x=0.0, y=0.0, z=math.sin(0.05), w=math.cos(0.05))
    with pytest.raises(BagError, match=r"b /map at 0.000000005 s: OccupancyGrid origin is rotated by 5.730 degrees"):
        map_message(SimpleNamespace(info=info, data=np.zeros(6, np.int8), header=SimpleNamespace(frame_id="map")),
                    "b /map", 5)
