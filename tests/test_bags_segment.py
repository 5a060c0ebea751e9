"""``roomseg-segment bag=...``: the rooms from a bag equal those of the same run given as files
(ROS 1, ROS 2 sqlite3 and MCAP; labels and images), the written bag reads back with its map
and markers, bad bags exit 2 with one line and write nothing; ``roomseg bag-info``."""

from __future__ import annotations

import json

import numpy as np
import pytest

pytest.importorskip("rosbags")

from bag_run import CLASSES_ARG, house, write_files  # noqa: E402

from benchmark.commands import bag_info, segment  # noqa: E402
from envs.bags.source import open_bag  # noqa: E402
from envs.bags.synthetic import write_robot_bag  # noqa: E402
from envs.maps.segmentation_io import read_index_png  # noqa: E402

# the files' run uses the vision cone (roomseg-segment's default for files); a bag of labels would
# pick graph_knn (tests/test_bags_first_hour.py), so the comparison names the aggregator
ALL = ["bag_options.min_distance_m=0", "bag_options.min_turn_deg=0", "bag_options.progress=false", CLASSES_ARG,
       "aggregator=vision_cone"]


@pytest.fixture(scope="module")
def files_run(tmp_path_factory):
    """The run given as files (map.yaml, poses.csv, labels.csv) and segmented."""
    h = house()
    d = tmp_path_factory.mktemp("files")
    args = write_files(h, d / "in")
    assert segment.main([*args, f"out={d}/out"]) == 0
    return h, d / "out"


def _features(folder):
    return json.loads((folder / "rooms.geojson").read_text())["features"]


def _read_out_bag(path):
    got = {}
    with open_bag(path) as b:
        for topic, _, _, msg in b.messages(["/map", "/segmentation", "/rooms"]):
            got[topic] = msg
    return got


@pytest.mark.slow
@pytest.mark.parametrize("fmt,label_type,extra", [
    ("ros1", "classification", []),
    ("sqlite3", "classification", []),
    ("mcap", "string", ["bag_options.camera_frame=camera_optical_frame"]),
])
def test_bag_rooms_equal_files(tmp_path, files_run, fmt, label_type, extra):
    h, files_out = files_run
    bag = write_robot_bag(tmp_path / ("run.bag" if fmt == "ros1" else "run"), fmt, h.run(label_type=label_type))
    out = tmp_path / "out"
    assert segment.main([f"bag={bag}", *ALL, *extra, f"out={out}"]) == 0
    assert np.array_equal(read_index_png(out / "labels.png"), read_index_png(files_out / "labels.png"))
    assert np.array_equal(read_index_png(out / "segments.png"), read_index_png(files_out / "segments.png"))
    assert _features(out) == _features(files_out)
    s = json.loads((out / "summary.json").read_text())
    assert s["mode"] == "labels" and s["n_views"] == len(h.route) and s["map_format"] == "bag"
    assert s["camera_frame"] == "camera_optical_frame" and s["map_frame"] == "map"
    # the written bag: the input map, the segmentation and the rooms, in the map frame
    name = "segmentation.bag" if fmt == "ros1" else "segmentation.mcap"
    assert s["bag_out"] == name and name in s["files"]
    got = _read_out_bag(out / name)
    labels = read_index_png(out / "labels.png")
    seg = got["/segmentation"]
    assert (seg.info.width, seg.info.height) == (labels.shape[1], labels.shape[0])
    assert seg.header.frame_id == "map" and (seg.info.origin.position.x, seg.info.origin.position.y) == (-3.25, 1.5)
    assert np.array_equal(np.asarray(seg.data, np.int64).reshape(labels.shape)[::-1], labels)
    assert np.array_equal(np.asarray(got["/map"].data).reshape(labels.shape)[::-1], h.occupancy)
    feats = _features(out)
    rings = sum(len(f["geometry"]["coordinates"]) if f["geometry"]["type"] == "Polygon"
                else sum(len(p) for p in f["geometry"]["coordinates"]) for f in feats)
    lines = [m for m in got["/rooms"].markers if m.ns == "rooms"]
    texts = [m for m in got["/rooms"].markers if m.ns == "room_names"]
    assert len(lines) == rings and all(m.type == 4 and m.header.frame_id == "map" for m in lines)
    assert [m.text.split(" ")[0] for m in texts] == [f["properties"]["class"].split("_")[0] for f in feats]
    first = feats[0]["geometry"]["coordinates"]
    ring = first[0] if feats[0]["geometry"]["type"] == "Polygon" else first[0][0]
    assert [(p.x, p.y) for p in lines[0].points] == [tuple(c) for c in ring]


@pytest.mark.slow
@pytest.mark.parametrize("fmt,image_format", [("ros1", "raw"), ("mcap", "png")])
def test_image_bag_rooms_equal_files(tmp_path, files_run, fmt, image_format):
    """Images of each view's class colour, a colour classifier, decoded and classified in
    chunks of 5: the same rooms as the labels given as files."""
    h, files_out = files_run
    run = h.run(labels=None, image=h.view_image, image_format=image_format, hfov_deg=90.0)
    bag = write_robot_bag(tmp_path / ("run.bag" if fmt == "ros1" else "run"), fmt, run)
    out = tmp_path / "out"
    assert segment.main([f"bag={bag}", *ALL, "classifier._target_=bag_run.ColourClassifier", "classifier.path=none",
                         "bag_options.chunk=5", f"out={out}"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["mode"] == "images" and s["camera_hfov_deg"] == pytest.approx(90.0)
    assert np.array_equal(read_index_png(out / "labels.png"), read_index_png(files_out / "labels.png"))
    assert _features(out) == _features(files_out)


@pytest.mark.slow
def test_camera_info_sets_the_cone(tmp_path, files_run):
    h, _ = files_run
    run = h.run(labels=None, image=h.view_image, hfov_deg=60.0)
    bag = write_robot_bag(tmp_path / "run.bag", "ros1", run)
    out = tmp_path / "out"
    assert segment.main([f"bag={bag}", "bag_options.progress=false", "classifier._target_=bag_run.ColourClassifier",
                         "classifier.path=none", "bag_options.min_distance_m=2", "bag_options.min_turn_deg=180",
                         f"out={out}"]) == 0
    import yaml

    cfg = yaml.safe_load((out / "config.yaml").read_text())
    assert cfg["aggregator"]["fov"] == pytest.approx(60.0)
    s = json.loads((out / "summary.json").read_text())
    # autotrace's route is 1 m / 90 degrees apart: every 2 m or 180 degrees keeps fewer
    assert 0 < s["n_kept_views"] < s["n_bag_views"] == len(h.route)


@pytest.mark.slow
def test_geometry_mode_from_a_bag(tmp_path, files_run):
    h, _ = files_run
    bag = write_robot_bag(tmp_path / "run", "mcap", h.run())
    out = tmp_path / "out"
    assert segment.main([f"bag={bag}", "segmenter=distance", "bag_options.progress=false", f"out={out}"]) == 0
    got = _read_out_bag(out / "segmentation.mcap")
    texts = [m.text for m in got["/rooms"].markers if m.ns == "room_names"]
    assert len(texts) == len(_features(out)) and all(t.startswith("segment ") for t in texts)


def _bad(tmp_path, capsys, args):
    out = tmp_path / "out"
    rc = segment.main([*args, "bag_options.progress=false", f"out={out}"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]  # no leftover temporary folder
    return err


@pytest.mark.slow
def test_bad_bags_exit_2_and_write_nothing(tmp_path, capsys):
    h = house()
    bag = write_robot_bag(tmp_path / "run.bag", "ros1", h.run(label_type="string"))
    err = _bad(tmp_path, capsys, [f"bag={bag}", "bag_options.view_topic=/nope"])
    assert "run.bag: bag_options.view_topic=/nope: no such topic" in err
    err = _bad(tmp_path, capsys, [f"bag={bag}", f"map={bag}"])
    assert "the bag gives the map; drop map=" in err
    data = bag.read_bytes()
    bag.write_bytes(data[: len(data) // 3])
    err = _bad(tmp_path, capsys, [f"bag={bag}"])
    assert "run.bag" in err and "not a readable bag" in err
    err = _bad(tmp_path, capsys, [f"bag={tmp_path}/none.bag"])
    assert "none.bag does not exist" in err


def test_labels_bag_with_an_image_classifier_is_refused(tmp_path, capsys):
    h = house()
    bag = write_robot_bag(tmp_path / "run.bag", "ros1", h.run(label_type="string"))
    err = _bad(tmp_path, capsys, [f"bag={bag}", "classifier._target_=bag_run.ColourClassifier", "classifier.path=none"])
    assert "run.bag /room_label: the views are labels (std_msgs/msg/String); use classifier=labels" in err


def test_bag_info(tmp_path, capsys):
    h = house()
    bag = write_robot_bag(tmp_path / "run", "sqlite3", h.run(label_type="classification"))
    assert bag_info.main([str(bag)]) == 0
    out = capsys.readouterr().out
    assert "sqlite3, 4 topics" in out and "/room_class  vision_msgs/msg/Classification" in out
    assert "tf /tf_static: camera_link -> camera_optical_frame (1)" in out
    assert (f"views /room_class (labels, vision_msgs/msg/Classification), poses from tf /tf, /tf_static, camera "
            f"camera_optical_frame; {len(h.route)} of {len(h.route)} views kept") in out.replace("tf_static, /tf", "tf, /tf_static")
    assert bag_info.main([str(bag), "view_topic=/nope"]) == 2
    assert "no such topic" in capsys.readouterr().err
    assert bag_info.main([str(bag), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["topics"]["/map"]["count"] == 1 and info["segmenter"]["n_views"] == len(h.route)
