"""A robot user's first hour with ``roomseg-segment bag=...`` (issue 62): bags that cannot be
misread. The aggregator follows what the views are (place labels: graph KNN; images: the
vision cone) and says so; the class list never comes from the labels seen (an index ground
truth is read against the seven classes, or the bag's own LabelInfo list); a map stamp before
every map and a map frame the map is not in are one line; bag-info lists the map stamps and
refuses an image bag the default classifier would refuse; the RViz grid's classes differ in
colour; the hints name what works."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from bag_run import CLASSES_ARG, ORIGIN, PAPER_CLASSES, RES, house  # noqa: E402

from benchmark.commands import bag_info, segment  # noqa: E402
from benchmark.commands.segment_example import write_example  # noqa: E402
from envs.bags.read import BagOptions, read_bag  # noqa: E402
from envs.bags.source import BagError, open_bag  # noqa: E402
from envs.bags.synthetic import RobotRun, write_robot_bag  # noqa: E402
from envs.bags.write import RVIZ_VALUES, costmap_rgb  # noqa: E402
from envs.maps.segmentation_io import read_index_png  # noqa: E402

QUIET = ["bag_options.progress=false"]
COLOUR_CLASSIFIER = ["classifier._target_=bag_run.ColourClassifier", "classifier.path=none"]


@pytest.fixture(scope="module")
def h():
    return house()


@pytest.fixture(scope="module")
def gt(tmp_path_factory):
    """The example building's ground truth as a bare class-index PNG (no gt.json naming its
    classes): its values index the run's class list."""
    from PIL import Image

    d = tmp_path_factory.mktemp("gt")
    ex = write_example(d)
    index = np.where(ex.rooms >= 0, np.asarray(ex.room_classes)[np.maximum(ex.rooms, 0)], 255).astype(np.uint8)
    Image.fromarray(index, mode="L").save(d / "gt_index.png")
    return d / "gt_index.png"


def _summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def _one_line_error(capsys, rc: int) -> str:
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1, err
    return err


# ---------------------------------------------------------------- 1. the aggregator follows the views


def test_place_labels_pick_graph_knn_and_say_so(tmp_path, h, gt, capsys):
    """A place label (the room the robot stands in) spread by the vision cone leaks through
    open doors; graph KNN keeps it to the paths: the default for label views, said on stdout
    and in the summary; an aggregator= given wins."""
    bag = write_robot_bag(tmp_path / "run.bag", "ros1", h.run())
    auto, cone = tmp_path / "auto", tmp_path / "cone"
    assert segment.main([f"bag={bag}", f"gt={gt}", "gt_format=label", *QUIET, f"out={auto}"]) == 0
    said = capsys.readouterr().out
    assert "aggregator graph_knn: the views are place labels" in said
    assert segment.main([f"bag={bag}", f"gt={gt}", "gt_format=label", *QUIET, "aggregator=vision_cone",
                         f"out={cone}"]) == 0
    assert "aggregator vision_cone (aggregator= given)" in capsys.readouterr().out
    a, c = _summary(auto), _summary(cone)
    assert a["aggregator"].endswith("GraphKNN") and a["aggregator_choice"].startswith("graph_knn: the views are place")
    assert c["aggregator"].endswith("VisionCone")
    # the example building: 6 rooms; the cone spreads labels through the doors
    assert a["n_segments"] < c["n_segments"]
    assert a["scores"]["iou"] > c["scores"]["iou"] + 0.1 and a["scores"]["accuracy"] > c["scores"]["accuracy"]


@pytest.mark.slow
def test_images_keep_the_vision_cone(tmp_path, h):
    run = h.run(labels=None, image=h.view_image, image_format="raw")
    bag = write_robot_bag(tmp_path / "run.bag", "ros1", run)
    out = tmp_path / "out"
    assert segment.main([f"bag={bag}", *QUIET, *COLOUR_CLASSIFIER, f"out={out}"]) == 0
    s = _summary(out)
    assert s["aggregator"].endswith("VisionCone") and s["aggregator_choice"].startswith("vision_cone: the views are camera")


# ---------------------------------------------------------------- 2. the class list does not follow the data


def test_index_gt_is_not_misread_when_a_class_never_occurs(tmp_path, h, gt):
    """The robot never says "bathroom" (its room is labelled corridor): the class list is
    still the seven, so every other class keeps its index in the ground truth PNG."""
    labels = ["corridor" if v == "bathroom" else v for v in h.labels]
    assert "bathroom" not in labels and "bedroom" in labels
    bag = write_robot_bag(tmp_path / "run.bag", "ros1", h.run(labels=labels))
    out, named = tmp_path / "out", tmp_path / "named"
    assert segment.main([f"bag={bag}", f"gt={gt}", "gt_format=label", *QUIET, f"out={out}"]) == 0
    assert segment.main([f"bag={bag}", f"gt={gt}", "gt_format=label", *QUIET, CLASSES_ARG, f"out={named}"]) == 0
    s = _summary(out)
    assert s["classes"] == list(PAPER_CLASSES) and s["classes_from"] == "the paper's seven, the default"
    assert np.array_equal(read_index_png(out / "labels.png"), read_index_png(named / "labels.png"))
    # only the bathroom's pixels are wrong (read against five classes: 0.13)
    assert s["scores"]["accuracy"] == _summary(named)["scores"]["accuracy"] > 0.7


def test_a_class_outside_the_list_is_one_line(tmp_path, h, capsys):
    labels = ["office" if v == "kitchen" else v for v in h.labels]
    bag = write_robot_bag(tmp_path / "run.bag", "ros1", h.run(labels=labels))
    out = tmp_path / "out"
    err = _one_line_error(capsys, segment.main([f"bag={bag}", *QUIET, f"out={out}"]))
    assert "run.bag /room_label: class(es) ['office']" in err and "not in the class list ['balcony'," in err
    assert "(the paper's seven, the default)" in err and "pass classes=[...]" in err and not out.exists()
    assert bag_info.main([str(bag)]) == 2
    assert "class(es) ['office']" in capsys.readouterr().err


def test_the_bags_label_info_is_the_class_list(tmp_path, h, capsys):
    """A ROS 2 bag with its own class list (vision_msgs/LabelInfo, ids in its order)."""
    own = tuple(reversed(PAPER_CLASSES))
    bag = write_robot_bag(tmp_path / "run", "mcap", h.run(label_type="classification", classes=own, label_info=True))
    out = tmp_path / "out"
    assert segment.main([f"bag={bag}", *QUIET, f"out={out}"]) == 0
    s = _summary(out)
    assert s["classes"] == list(own) and s["classes_from"] == "the bag's LabelInfo on /label_info"
    labels = read_index_png(out / "labels.png")
    plain = tmp_path / "plain"
    assert segment.main([f"bag={bag}", *QUIET, CLASSES_ARG, f"out={plain}"]) == 0
    seven = read_index_png(plain / "labels.png")
    # the same rooms, each class at its reversed index (ties between classes may break the other way)
    k = len(own) - 1
    same = np.where(labels >= 0, k - labels, -1) == seven
    assert same.mean() > 0.99 and np.array_equal(labels >= 0, seven >= 0)
    capsys.readouterr()
    assert bag_info.main([str(bag)]) == 0
    assert f"classes {list(own)} (the bag's LabelInfo on /label_info)" in capsys.readouterr().out


# ---------------------------------------------------------------- 3. map stamps


def test_map_stamp_before_every_map_is_refused(tmp_path, h, capsys):
    run = h.run()
    t0 = int(h.stamps[0])
    run.map_stamps_ns = [t0 + 5_000_000_000, t0 + 10_000_000_000]
    bag = write_robot_bag(tmp_path / "run.bag", "ros1", run)
    with pytest.raises(BagError, match=r"run.bag /map: bag_options.map_stamp=1700000001.000000000 is before every "
                                       r"map; the map stamps are \[1700000005.000000000 s, 1700000010.000000000 s\]"):
        read_bag(bag, BagOptions(map_stamp=1700000001.0))
    assert read_bag(bag, BagOptions(map_stamp=1700000007.0)).map.stamp_ns == t0 + 5_000_000_000
    assert read_bag(bag, BagOptions(map_stamp=1700000010.0)).map.stamp_ns == t0 + 10_000_000_000
    assert read_bag(bag).map.stamp_ns == t0 + 10_000_000_000
    # bag-info lists them and says which one it takes
    assert bag_info.main([str(bag)]) == 0
    out = capsys.readouterr().out
    assert "map stamps /map: [1700000005.000000000 s, 1700000010.000000000 s]" in out
    assert "stamp 1700000010.000000000 s: the last map)" in out
    assert bag_info.main([str(bag), "map_stamp=1700000007"]) == 0
    assert "stamp 1700000005.000000000 s: the last map at or before bag_options.map_stamp=1700000007)" in \
        capsys.readouterr().out
    assert bag_info.main([str(bag), "map_stamp=1700000001"]) == 2
    assert "is before every map" in capsys.readouterr().err
    err = _one_line_error(capsys, segment.main([f"bag={bag}", *QUIET, "bag_options.map_stamp=1700000001",
                                                f"out={tmp_path / 'out'}"]))
    assert "is before every map" in err


@pytest.mark.parametrize("value", ["nan", "inf", "'soon'"])
def test_map_stamp_that_is_not_a_number_is_one_line(tmp_path, h, capsys, value):
    bag = write_robot_bag(tmp_path / "run.bag", "ros1", h.run())
    err = _one_line_error(capsys, segment.main([f"bag={bag}", *QUIET, f"bag_options.map_stamp={value}",
                                                f"out={tmp_path / 'out'}"]))
    assert "bag_options.map_stamp=" in err and "expected seconds since the epoch" in err
    assert "cannot convert" not in err


# ---------------------------------------------------------------- 4. the map's frame


def test_map_frame_odom_without_map_to_odom_is_refused(tmp_path, h, capsys):
    """No localiser recorded (no map -> odom): views taken in odom would sit off the map by
    odom's offset, and the output relabelled odom; refused in one line."""
    bag = write_robot_bag(tmp_path / "run.bag", "ros1", h.run(publish_map_to_odom=False))
    with pytest.raises(BagError, match=r"run.bag /map: bag_options.map_frame=odom but the map is in frame 'map'; "
                                       r"views placed in 'odom' would be off the map"):
        read_bag(bag, BagOptions(map_frame="odom"))
    with pytest.raises(BagError, match=r"tf: no frame 'map' in the bag"):
        read_bag(bag)
    err = _one_line_error(capsys, segment.main([f"bag={bag}", *QUIET, "bag_options.map_frame=odom",
                                                f"out={tmp_path / 'out'}"]))
    assert "bag_options.map_frame=odom but the map is in frame 'map'" in err
    # naming the map's own frame is fine
    ok = write_robot_bag(tmp_path / "ok.bag", "ros1", h.run())
    assert read_bag(ok, BagOptions(map_frame="map")).map_frame == "map"


# ---------------------------------------------------------------- 5. smaller things


def test_rviz_grid_shows_the_classes_apart(tmp_path, h):
    """/segmentation keeps class indices (0-6, all near white in RViz's map scheme);
    /segmentation_rviz holds values RViz's costmap scheme colours apart, the room outlines in
    the same colours."""
    bag = write_robot_bag(tmp_path / "run.bag", "ros1", h.run())
    out = tmp_path / "out"
    assert segment.main([f"bag={bag}", *QUIET, CLASSES_ARG, f"out={out}"]) == 0
    assert _summary(out)["bag_topics"] == ["/map", "/segmentation", "/segmentation_rviz", "/rooms"]
    got = {}
    with open_bag(out / "segmentation.bag") as b:
        for topic, _, _, msg in b.messages(["/segmentation", "/segmentation_rviz", "/rooms"]):
            got[topic] = msg
    labels = read_index_png(out / "labels.png").astype(np.int64)
    shape = labels.shape
    seg = np.asarray(got["/segmentation"].data, np.int64).reshape(shape)[::-1]
    viz = np.asarray(got["/segmentation_rviz"].data, np.int64).reshape(shape)[::-1]
    cls = labels  # -1: no class
    assert np.array_equal(seg, cls)
    assert np.array_equal(viz, np.where(cls >= 0, np.asarray(RVIZ_VALUES)[np.maximum(cls, 0)], 0))
    # the seven classes' colours: at least 120 apart (RGB distance) in the costmap scheme
    cols = np.array([costmap_rgb(v) for v in RVIZ_VALUES[:7]], float)
    d = np.sqrt(((cols[:, None] - cols[None]) ** 2).sum(-1))[np.triu_indices(7, 1)]
    assert d.min() > 120
    grey = np.array([255 - 255 * k // 100 for k in range(7)], float)  # the map scheme's colours of 0-6
    assert np.ptp(grey) * math.sqrt(3) < 30
    # each room outline in its class's colour there
    names = list(PAPER_CLASSES)
    for m in got["/rooms"].markers:
        if m.ns == "rooms":
            rgb = tuple(round(c * 255) for c in (m.color.r, m.color.g, m.color.b))
            assert rgb in {costmap_rgb(RVIZ_VALUES[k]) for k in range(len(names))}


def test_bag_info_refuses_an_image_bag_without_an_image_classifier(tmp_path, h, capsys):
    bag = write_robot_bag(tmp_path / "run.bag", "ros1", h.run(labels=None, image=h.view_image))
    assert bag_info.main([str(bag)]) == 2
    err = capsys.readouterr().err
    assert "the views are images (sensor_msgs/msg/Image); roomseg-segment needs an image classifier" in err
    assert bag_info.main([str(bag), "classifier=cnn"]) == 0
    assert "aggregator vision_cone: the views are camera images" in capsys.readouterr().out
    labels_bag = write_robot_bag(tmp_path / "labels.bag", "ros1", h.run())
    assert bag_info.main([str(labels_bag), "classifier=cnn"]) == 2
    assert "the views are labels" in capsys.readouterr().err
    assert bag_info.main([str(labels_bag), "aggregator=vision_cone"]) == 0
    assert "aggregator vision_cone (aggregator= given)" in capsys.readouterr().out


def test_a_damaged_lone_mcap_is_told_to_run_mcap_recover(tmp_path, h):
    folder = write_robot_bag(tmp_path / "run", "mcap", h.run())
    lone = tmp_path / "run.mcap"
    data = next(folder.glob("*.mcap")).read_bytes()
    lone.write_bytes(data[: len(data) // 2])
    with pytest.raises(BagError, match=r"run.mcap: .*mcap recover"):
        read_bag(lone)


def test_an_off_map_view_is_named_in_ros_x_y(tmp_path, h, capsys):
    route = h.route.copy()
    route[3, :2] = (-40.0, -30.0)
    bag = write_robot_bag(tmp_path / "run.bag", "ros1",
                          RobotRun(h.occupancy, RES, ORIGIN, route, h.stamps, labels=h.labels, classes=PAPER_CLASSES))
    err = _one_line_error(capsys, segment.main([f"bag={bag}", *QUIET, "bag_options.min_distance_m=0",
                                                "bag_options.min_turn_deg=0", f"out={tmp_path / 'out'}"]))
    # (the label has no header: its pose is base_link's, 0.2 m behind the camera)
    assert re.search(r"1 of 219 poses .* first view 3 at x=-40\.\d{3}, y=-30\.\d{3} m in the map frame \(ROS x, y", err)


def test_the_install_lines_name_what_works():
    """rosbags comes with make setup (the extra's name is not on PyPI); the torch line names
    make setup-test, which installs torch (make setup does not)."""
    from benchmark.classifiers.torch_common import INSTALL_HINT as TORCH
    from envs.bags.source import INSTALL_HINT as BAGS

    root = Path(__file__).resolve().parents[1]
    make = (root / "Makefile").read_text()
    recipe = make.split("$(VENV)/.installed: pyproject.toml\n", 1)[1].split("\n\n", 1)[0]
    assert '$(PIP) install -q -e ".[bags]"' in recipe and "torch" not in recipe
    assert 'bags = ["rosbags' in (root / "pyproject.toml").read_text()
    assert "make setup installs it" in BAGS and "roomseg-bench[bags]" not in BAGS
    assert "make setup-test" in TORCH and "(or make setup)" not in TORCH
