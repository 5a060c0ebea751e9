"""Ground-truth formats: instance colours, label maps, IPA-style white rooms between black lines."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from PIL import Image

from benchmark.metrics import MetricParams, score_instances
from envs.maps.gridmap import GridMap
from envs.maps.ground_truth import carry_onto_grid, read_ground_truth, self_iou
from envs.maps.label_png import write_label_png

RES = 0.05


def ipa_pair():
    """An IPA-style ground truth and its occupancy map, 60 x 80 px at 0.05 m/px.

    GT: black border 2 px; a 1-px black line at col 40 (rows 2..57) and a 2-px black line
    at rows 30..31 (cols 41..77): rooms left (rows 2..57, cols 2..39: 56 x 38 = 2128 px),
    top right (rows 2..29, cols 41..77: 28 x 37 = 1036 px), bottom right (rows 32..57,
    cols 41..77: 26 x 37 = 962 px). Map: the same border; the wall at col 40 has a door
    (rows 20..27 walkable); the GT's horizontal line is open floor in the map.
    """
    gt = np.full((60, 80), 255, np.uint8)
    gt[:2], gt[-2:], gt[:, :2], gt[:, -2:] = 0, 0, 0, 0
    gt[:, 40] = 0
    gt[30:32, 41:] = 0
    walk = np.ones((60, 80), bool)
    walk[:2], walk[-2:], walk[:, :2], walk[:, -2:] = False, False, False, False
    walk[:, 40] = False
    walk[20:28, 40] = True
    return gt, GridMap(walk, RES, (0.0, 3.0))


def test_ipa_style_ground_truth_scores_100_against_itself(tmp_path):
    gt_img, grid = ipa_pair()
    Image.fromarray(gt_img).save(tmp_path / "ipa_gt.png")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a correct read warns about nothing
        g = read_ground_truth(tmp_path / "ipa_gt.png", "rooms_white", grid)
    inst = g.instances
    assert len(g.instance_classes) == 3 and (g.instance_classes == -1).all() and g.classes is None
    left, top, bottom = inst[10, 10], inst[10, 60], inst[50, 60]
    assert len({left, top, bottom}) == 3 and min(left, top, bottom) >= 0
    # the 2-px line: row 30 is 1 px from the top room (row 29), row 31 1 px from the bottom one (row 32)
    assert inst[30, 60] == top and inst[31, 60] == bottom
    # the door pixels in col 40 are walkable in the map: they join a neighbouring room
    assert set(inst[20:28, 40].tolist()) <= {left, top}
    # the wall pixels of col 40 outside the door and the border are not walkable: -1
    assert inst[5, 40] == -1 and inst[0, 0] == -1 and (inst[~grid.walkable] == -1).all()
    # every walkable pixel got a room: 2128 + 1036 + 962 + 37 * 2 (line) + 8 (door)
    assert (inst >= 0).sum() == grid.walkable.sum() == 2128 + 1036 + 962 + 74 + 8
    assert np.count_nonzero(inst == bottom) == 962 + 37
    params = MetricParams(instances="connected")
    assert score_instances(inst, inst, params, resolution=RES)["iou"] == 1.0
    assert g.self_iou == 1.0


def test_ipa_style_ground_truth_misread_as_instances_warns(tmp_path):
    gt_img, grid = ipa_pair()
    Image.fromarray(gt_img).save(tmp_path / "ipa_gt.png")
    # read as one colour per room, the white is a single "room" in three separate regions:
    # each region's IoU with it is its share of the white, so the mean is exactly 1/3
    # white is not a room colour by default: no room at all, with a hint at the right format
    with pytest.raises(ValueError, match=r"ipa_gt.png: no room found reading it as format 'instance' \(rooms drawn "
                                         r"white between black lines are format 'rooms_white'"):
        read_ground_truth(tmp_path / "ipa_gt.png", "instance", resolution=RES)
    with pytest.warns(UserWarning, match=r"ipa_gt.png: the ground truth scored against itself gives IoU 33.3 %"):
        g = read_ground_truth(tmp_path / "ipa_gt.png", "instance", resolution=RES, not_room_colours=["#000000"])
    assert len(g.instance_classes) == 1 and g.self_iou == pytest.approx(1 / 3)
    params = MetricParams(instances="connected")
    assert score_instances(g.instances, g.instances, params, resolution=RES)["iou"] == pytest.approx(1 / 3)


def test_self_iou_by_hand():
    inst = np.array([[0, 0, -1, 0],
                     [1, 1, -1, 0]])
    # room 0 has regions of 2 and 2 px (of 4): 0.5 each; room 1 one region of 2 px: 1.0 -> mean 2/3
    assert self_iou(inst) == pytest.approx(2 / 3)
    assert self_iou(inst, min_px=3) != self_iou(inst)  # no region reaches 3 px -> NaN
    assert np.isnan(self_iou(np.full((2, 2), -1)))


def test_instance_format_carried_onto_the_map(tmp_path):
    rgb = np.zeros((20, 30, 3), np.uint8)
    rgb[2:18, 2:14] = (200, 30, 30)  # room A: 16 x 12 = 192 px
    rgb[2:18, 16:28] = (30, 30, 200)  # room B: 192 px; cols 14, 15 black between them
    Image.fromarray(rgb).save(tmp_path / "inst.png")
    walk = np.zeros((20, 30), bool)
    walk[2:18, 2:28] = True  # the map has no wall between the rooms
    walk[10, 5] = False  # a table in room A
    grid = GridMap(walk, 0.1, (0.0, 0.0))
    g = read_ground_truth(tmp_path / "inst.png", "instance", grid, min_room_m2=1.0)
    a, b = g.instances[5, 5], g.instances[5, 20]
    assert {a, b} == {0, 1} and g.n_colours == 3
    # col 14 is 1 px from room A (col 13), col 15 1 px from room B (col 16): within 0.5 m
    assert (g.instances[2:18, 14] == a).all() and (g.instances[2:18, 15] == b).all()
    assert g.instances[10, 5] == -1 and (g.instances[~walk] == -1).all()
    # with fill_distance 0.05 m (half a pixel) the black gap stays unassigned
    g0 = read_ground_truth(tmp_path / "inst.png", "instance", grid, min_room_m2=1.0, fill_distance=0.05)
    assert (g0.instances[:, 14:16] == -1).all()
    # a wrong-sized map is one line naming the file and both sizes
    with pytest.raises(ValueError, match=r"inst.png: ground truth is 20 x 30 pixels but the map is 20 x 31"):
        read_ground_truth(tmp_path / "inst.png", "instance", GridMap(np.ones((20, 31), bool), 0.1, (0, 0)))


def test_carry_onto_grid_limits_by_distance():
    inst = np.array([[0, -1, -1, -1, 1]])
    grid = GridMap(np.ones((1, 5), bool), 1.0, (0.0, 0.0))
    # pixel 1 is 1 m from room 0, pixel 3 1 m from room 1; pixel 2 is 2 m from both
    assert carry_onto_grid(inst, grid, fill_distance=1.0).tolist() == [[0, 0, -1, 1, 1]]
    assert carry_onto_grid(inst, grid, fill_distance=None)[0, [0, 1, 3, 4]].tolist() == [0, 0, 1, 1]


def test_many_colours_warn(tmp_path):
    rng = np.random.default_rng(0)
    rgb = rng.integers(1, 255, (40, 40, 3), dtype=np.uint8)  # noise: ~1600 colours
    rgb[:20] = (10, 200, 10)
    Image.fromarray(rgb).save(tmp_path / "noise.png")
    with pytest.warns(UserWarning, match=r"noise.png: \d{3,} distinct colours, 1 became rooms"):
        read_ground_truth(tmp_path / "noise.png", "instance", resolution=0.05)


def test_label_formats(tmp_path):
    classes = ("bathroom", "bedroom", "kitchen")
    labels = np.full((10, 12), -1)
    labels[1:9, 1:5] = 1  # bedroom 32 px
    labels[1:9, 7:11] = 1  # a second bedroom, separate: 32 px
    labels[1:4, 5:7] = 2  # kitchen between them, touching both: 6 px
    # the sidecar's classes are (bedroom, kitchen): indices one lower than in ``classes``
    write_label_png(tmp_path / "lab.png", np.where(labels >= 0, labels - 1, -1), classes[1:], legend=False)
    g = read_ground_truth(tmp_path / "lab.png", "label", classes=classes, resolution=0.1)
    assert g.classes == classes and sorted(g.instance_classes.tolist()) == [1, 1, 2]
    sizes = sorted(np.bincount(g.instances[g.instances >= 0]).tolist())
    assert sizes == [6, 32, 32]
    assert g.instance_classes[g.instances[2, 6]] == 2 and g.instance_classes[g.instances[5, 2]] == 1
    with pytest.raises(ValueError, match=r"lab.png: classes \['kitchen'\] of its sidecar lab.json are not in"):
        read_ground_truth(tmp_path / "lab.png", "label", classes=("bedroom",))
    # an index PNG without sidecar: value = class index, 255 = no room
    idx = np.where(labels < 0, 255, labels).astype(np.uint8)
    Image.fromarray(idx).save(tmp_path / "idx.png")
    gi = read_ground_truth(tmp_path / "idx.png", "label", classes=classes)
    assert np.array_equal(gi.instances >= 0, labels >= 0) and sorted(gi.instance_classes.tolist()) == [1, 1, 2]
    idx[0, 0] = 7
    Image.fromarray(idx).save(tmp_path / "idx7.png")
    with pytest.raises(ValueError, match=r"idx7.png: pixel values \[7\] are neither a class index \(0..2\)"):
        read_ground_truth(tmp_path / "idx7.png", "label", classes=classes)
    with pytest.raises(ValueError, match="needs the class list"):
        read_ground_truth(tmp_path / "idx.png", "label")


def test_bad_format_and_missing_file(tmp_path):
    with pytest.raises(ValueError, match=r"ground-truth format 'colours'.*expected one of \['instance', 'label', "
                                         r"'rooms_white'\]"):
        read_ground_truth(tmp_path / "x.png", "colours")
    with pytest.raises(FileNotFoundError, match="ground-truth map not found: .*x.png"):
        read_ground_truth(tmp_path / "x.png", "instance")
    Image.fromarray(np.zeros((5, 5), np.uint8)).save(tmp_path / "black.png")
    with pytest.raises(ValueError, match="black.png: no room found reading it as format 'rooms_white'"):
        read_ground_truth(tmp_path / "black.png", "rooms_white", resolution=0.05)
