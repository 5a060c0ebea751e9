"""Maps and poses in: ROS map_server maps, plain PNGs, arrays, frame conversion, pose files.

Every expected value is worked out by hand in the comments beside it.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from PIL import Image

from envs.maps.frames import (
    grid_origin_to_ros_origin,
    ros_origin_to_grid_origin,
    ros_to_world,
    world_to_ros,
)
from envs.maps.gridmap import GridMap, yaw_to_pixel_direction
from envs.maps.pose_files import read_poses
from envs.maps.ros import (
    grid_from_array,
    grid_to_ros_image,
    image_to_occupancy,
    occupancy_png,
    read_ros_map,
    unknown_pixel,
    write_grid_ros,
    write_ros_map,
)

# --------------------------------------------------------------------------- frames


def test_ros_to_world_hand_cases():
    # theta 0 faces +x: project yaw 90; pi/2 faces +y = +z: yaw 0; pi faces -x: 270;
    # -pi/2 faces -z: 180; pi/4 (between +x and +y): 45; 3pi/4 (between -x and +y): 315
    thetas = [0, math.pi / 2, math.pi, -math.pi / 2, math.pi / 4, 3 * math.pi / 4]
    x, z, yaw = ros_to_world([1.0] * 6, [-2.5] * 6, thetas)
    assert np.allclose(yaw, [90, 0, 270, 180, 45, 315])
    assert np.all(x == 1.0) and np.all(z == -2.5)  # ROS y is the project's z, no mirroring
    assert float(ros_to_world(0, 0, 2 * math.pi)[2]) == pytest.approx(90)
    assert 0 <= float(ros_to_world(0, 0, math.pi / 2 + 1e-17)[2]) < 360


def test_world_to_ros_hand_cases_and_round_trip():
    x, y, th = world_to_ros(3.0, 4.0, [90, 0, 270, 180, 45, 315, -90])
    assert np.allclose(th, [0, math.pi / 2, math.pi, -math.pi / 2, math.pi / 4, 3 * math.pi / 4, math.pi])
    assert float(x) == 3.0 and float(y) == 4.0
    rng = np.random.default_rng(0)
    p = rng.uniform(-50, 50, (100, 3))
    p[:, 2] = rng.uniform(0, 360, 100)
    back = ros_to_world(*world_to_ros(p[:, 0], p[:, 1], p[:, 2]))
    assert np.allclose(np.column_stack(back)[:, :2], p[:, :2])
    assert np.allclose(np.mod(back[2] - p[:, 2] + 180, 360) - 180, 0, atol=1e-9)


def test_ros_heading_matches_map_direction():
    # a ROS heading of +y (theta = pi/2) must point up on the map (row decreasing)
    _, _, yaw = ros_to_world(0, 0, math.pi / 2)
    dr, dc = yaw_to_pixel_direction(yaw)
    assert dr == pytest.approx(-1) and dc == pytest.approx(0, abs=1e-12)
    _, _, yaw = ros_to_world(0, 0, 0.0)  # +x: right on the map
    dr, dc = yaw_to_pixel_direction(yaw)
    assert dr == pytest.approx(0, abs=1e-12) and dc == pytest.approx(1)


def test_origin_conversion():
    # bottom-left corner at (-3, 1.5), 4 rows of 0.5 m: top edge at z = 1.5 + 2 = 3.5
    assert ros_origin_to_grid_origin((-3.0, 1.5), 4, 0.5) == (-3.0, 3.5)
    assert grid_origin_to_ros_origin((-3.0, 3.5), 4, 0.5) == (-3.0, 1.5)
    assert ros_origin_to_grid_origin((1.0, 2.0, 0.0), 10, 0.05) == pytest.approx((1.0, 2.5))


# --------------------------------------------------------------------------- reading ROS maps


def _write(tmp_path, img: np.ndarray, name="m", image="m.pgm", **meta):
    fields = {"image": image, "resolution": 0.5, "origin": [-1.0, 2.0, 0.0], "negate": 0,
              "occupied_thresh": 0.65, "free_thresh": 0.25}
    fields.update(meta)
    Image.fromarray(img).save(tmp_path / image)
    y = tmp_path / f"{name}.yaml"
    y.write_text("".join(f"{k}: {json.dumps(v)}\n" for k, v in fields.items() if v is not None))
    return y


#: a 4 x 5 map: 254 free, 0 occupied, 205 unknown for thresholds (0.196, 0.65) only
IMG = np.array([[254, 254, 0, 254, 205],
                [254, 0, 0, 254, 254],
                [254, 254, 254, 254, 0],
                [0, 254, 254, 254, 254]], dtype=np.uint8)


def test_hand_made_ros_map_with_offset_origin_and_poses(tmp_path):
    y = _write(tmp_path, IMG, free_thresh=0.196)
    m = read_ros_map(y)
    # 205 -> p = 50/255 = 0.19608 > 0.196 (not free), < 0.65 (not occupied): unknown
    assert m.occupancy.dtype == np.int8
    assert m.occupancy.tolist() == [[0, 0, 100, 0, -1], [0, 100, 100, 0, 0], [0, 0, 0, 0, 100], [100, 0, 0, 0, 0]]
    assert m.grid.walkable.tolist() == (IMG == 254).tolist()
    # origin [-1, 2] is the bottom-left corner; 4 rows of 0.5 m -> the top-left corner is (-1, 4)
    assert m.grid.origin == (-1.0, 4.0) and m.grid.resolution == 0.5 and m.origin == (-1.0, 2.0, 0.0)
    assert m.mode == "trinary" and m.negate is False and m.image_path == tmp_path / "m.pgm"
    # poses in the ROS frame; their cells by hand (ROS cell i = floor((x - ox)/res),
    # j = floor((y - oy)/res) counted from the bottom; image row = H - 1 - j):
    #   (-0.75, 3.75): i = floor(0.5) = 0, j = floor(3.5) = 3 -> image (0, 0), free
    #   ( 0.90, 2.10): i = floor(3.8) = 3, j = floor(0.2) = 0 -> image (3, 3), free
    #   ( 0.10, 3.40): i = floor(2.2) = 2, j = floor(2.8) = 2 -> image (1, 2), occupied
    #   ( 1.30, 3.99): i = floor(4.6) = 4, j = floor(3.98) = 3 -> image (0, 4), unknown
    (tmp_path / "poses.csv").write_text("x,y,theta\n-0.75,3.75,0\n0.9,2.1,1.5707963267948966\n0.1,3.4,3.14159\n"
                                        "1.3,3.99,-1.5707963267948966\n")
    p = read_poses(tmp_path / "poses.csv", frame="ros")
    r, c = m.grid.world_to_cell(p[:, 0], p[:, 1])
    assert list(zip(r.tolist(), c.tolist())) == [(0, 0), (3, 3), (1, 2), (0, 4)]
    assert m.grid.is_walkable(r, c).tolist() == [True, True, False, False]
    assert np.allclose(p[:, 2], [90, 0, 270, 180], atol=1e-3)
    # unknown as free makes the unknown cell walkable, occupied cells stay blocked
    free = read_ros_map(y, unknown_as="free").grid
    assert free.is_walkable(r, c).tolist() == [True, True, False, True]


def test_negate_both_ways(tmp_path):
    img = np.array([[0, 254, 128, 255]], dtype=np.uint8)
    # negate 0: p = (255 - v)/255 = 1, 0.0039, 0.498, 0 -> occupied, free, unknown, free
    assert read_ros_map(_write(tmp_path, img, negate=0)).occupancy.tolist() == [[100, 0, -1, 0]]
    # negate 1: p = v/255 = 0, 0.996, 0.502, 1 -> free, occupied, unknown, occupied
    m = read_ros_map(_write(tmp_path, img, name="n", negate=1))
    assert m.occupancy.tolist() == [[0, 100, -1, 100]] and m.negate is True
    assert m.grid.walkable.tolist() == [[True, False, False, False]]
    assert read_ros_map(_write(tmp_path, img, name="t", negate=True)).negate is True


VALUES = np.array([[0, 50, 100, 128, 200, 230, 254, 255]], dtype=np.uint8)


def test_modes_trinary_scale_raw(tmp_path):
    y = _write(tmp_path, VALUES)
    # p = 1, .804, .608, .498, .216, .098, .004, 0 against occupied .65 / free .25
    assert read_ros_map(y).occupancy.tolist() == [[100, 100, -1, -1, 0, 0, 0, 0]]
    # scale: v=100 -> ratio (155/255 - .25)/.4 = .8946 -> 1 + floor(87.67) = 88;
    #        v=128 -> ratio (127/255 - .25)/.4 = .6201 -> 1 + floor(60.77) = 61
    assert read_ros_map(y, mode="scale").occupancy.tolist() == [[100, 100, 88, 61, 0, 0, 0, 0]]
    # raw: the value itself, 0..100 kept, above 100 unknown
    assert read_ros_map(y, mode="raw").occupancy.tolist() == [[0, 50, 100, -1, -1, -1, -1, -1]]
    assert read_ros_map(y, mode="raw").grid.walkable.tolist() == [[True] + [False] * 7]
    # raw with negate: 255 - v = 255, 205, 155, 127, 55, 25, 1, 0
    yn = _write(tmp_path, VALUES, name="rn", negate=1, mode="raw")
    m = read_ros_map(yn)
    assert m.mode == "raw" and m.occupancy.tolist() == [[-1, -1, -1, -1, 55, 25, 1, 0]]
    # the YAML's mode field is used when no override is given
    assert read_ros_map(_write(tmp_path, VALUES, name="s", mode="scale")).occupancy[0, 2] == 88


def test_scale_transparency_and_colour_images(tmp_path):
    rgba = np.zeros((1, 3, 4), np.uint8)
    rgba[0, 0] = (254, 254, 254, 255)  # opaque white: free
    rgba[0, 1] = (254, 254, 254, 0)  # transparent: unknown in scale mode
    rgba[0, 2] = (10, 20, 31, 255)  # mean (10+20+31)//3 = 20 -> p = .92 -> occupied
    Image.fromarray(rgba, "RGBA").save(tmp_path / "c.png")
    y = _write(tmp_path, VALUES, name="c", image="v.png")
    y.write_text(y.read_text().replace("v.png", "c.png"))
    assert read_ros_map(y, mode="scale").occupancy.tolist() == [[0, -1, 100]]
    assert read_ros_map(y).occupancy.tolist() == [[0, 0, 100]]  # trinary ignores alpha


def test_image_to_occupancy_thresholds_are_strict():
    # v = 89: p = 166/255 = 0.65098 > .65 -> occupied; with occupied_thresh = 166/255 exactly: not
    assert image_to_occupancy(np.array([[89]]), None, False, 0.65, 0.25, "trinary").tolist() == [[100]]
    assert image_to_occupancy(np.array([[89]]), None, False, 166 / 255, 0.25, "trinary").tolist() == [[-1]]
    # scale near the free end: v = 190 -> p = 65/255 = .2549, ratio = .01225: ROS 1's 1 + floor(98 * ratio)
    # = 2 (the wiki's 99 * ratio would give 1); v = 191 -> p = .25098, ratio = .00245 -> 1
    assert image_to_occupancy(np.array([[190, 191]]), None, False, 0.65, 0.25, "scale").tolist() == [[2, 1]]


# --------------------------------------------------------------------------- writing and round trips


def test_written_ros_map_reads_back_identical(tmp_path):
    rng = np.random.default_rng(1)
    walk = rng.random((37, 53)) > 0.3
    grid = GridMap(walk, 0.05, (-12.35, 7.9))
    y = write_grid_ros(tmp_path / "out" / "seg.yaml", grid)
    assert (tmp_path / "out" / "seg.pgm").read_bytes()[:2] == b"P5"  # binary PGM
    m = read_ros_map(y)
    assert np.array_equal(m.grid.walkable, walk) and m.grid.resolution == 0.05
    assert m.grid.origin == pytest.approx((-12.35, 7.9), abs=1e-12)
    assert np.array_equal(np.asarray(Image.open(m.image_path)), grid_to_ros_image(grid))
    # a read map written again with its own fields reads back identical (occupancy and fields)
    src = _write(tmp_path, IMG, free_thresh=0.196, negate=0)
    a = read_ros_map(src)
    y2 = write_ros_map(tmp_path / "copy.yaml", IMG, a.resolution, a.origin, a.negate, a.occupied_thresh,
                       a.free_thresh, a.mode, image_name="copy.png")
    b = read_ros_map(y2)
    assert np.array_equal(a.occupancy, b.occupancy) and np.array_equal(a.grid.walkable, b.grid.walkable)
    assert (b.resolution, b.origin, b.negate, b.occupied_thresh, b.free_thresh, b.mode, b.grid.origin) == \
        (a.resolution, a.origin, a.negate, a.occupied_thresh, a.free_thresh, a.mode, a.grid.origin)
    assert not list(tmp_path.glob(".*.tmp"))  # atomic writes leave no temporary files


def test_unknown_pixel_reads_as_unknown():
    for free, occ, neg in [(0.25, 0.65, False), (0.196, 0.65, False), (0.25, 0.65, True), (0.1, 0.9, False)]:
        v = unknown_pixel(free, occ, neg)
        assert image_to_occupancy(np.array([[v]]), None, neg, occ, free, "trinary")[0, 0] == -1
    assert unknown_pixel(0.196, 0.65) == 205  # map_saver's value where it qualifies


# --------------------------------------------------------------------------- plain PNGs and arrays


def test_occupancy_png_and_array(tmp_path):
    img = np.array([[255, 240, 120, 10]] * 2, dtype=np.uint8)
    Image.fromarray(img).save(tmp_path / "plain.png")
    # p = 0, .059, .53, .96 with free .25 / occupied .65: free, free, unknown, occupied
    g = occupancy_png(tmp_path / "plain.png", resolution=0.1)
    assert g.walkable.tolist() == [[True, True, False, False]] * 2
    assert g.origin == pytest.approx((0.0, 0.2))  # bottom-left corner at (0, 0): top edge at 2 * 0.1
    g = occupancy_png(tmp_path / "plain.png", resolution=0.1, origin=(5.0, 6.0), free_thresh=0.6,
                      unknown_as="free")
    assert g.walkable.tolist() == [[True, True, True, False]] * 2 and g.origin == (5.0, 6.0)
    a = grid_from_array(np.array([[True, False]]), 0.5, (1.0, 2.0))
    assert a.walkable.tolist() == [[True, False]] and a.origin == (1.0, 2.0)
    occ = np.array([[0, 100, -1, 0]], np.int8)
    assert grid_from_array(occ, 0.5, free_value=0).walkable.tolist() == [[True, False, False, True]]
    with pytest.raises(ValueError, match="dtype int8; expected bool"):
        grid_from_array(occ, 0.5)


# --------------------------------------------------------------------------- pose files


def test_pose_files_ros_sim_pixel_agree(tmp_path):
    grid = GridMap(np.ones((10, 10), bool), 0.5, (-1.0, 4.0))
    # the same two poses in three frames: (x=0.25, z=1.75) facing +x, (x=-0.75, z=3.75) facing +z
    # pixel of (0.25, 1.75): col = (0.25 + 1)/0.5 = 2.5 -> centre of col 2; row = (4 - 1.75)/0.5 = 4.5 -> row 4
    (tmp_path / "r.csv").write_text("x,y,theta\n0.25,1.75,0\n-0.75,3.75,1.5707963267948966\n")
    (tmp_path / "s.json").write_text(json.dumps({"poses": [{"x": 0.25, "z": 1.75, "yaw": 90},
                                                           {"x": -0.75, "z": 3.75, "yaw": 0}]}))
    (tmp_path / "p.csv").write_text("row,col,yaw\n4,2,90\n0,0,0\n")
    r = read_poses(tmp_path / "r.csv", frame="ros")
    s = read_poses(tmp_path / "s.json", frame="sim")
    p = read_poses(tmp_path / "p.csv", frame="pixel", grid=grid)
    assert np.allclose(r, [[0.25, 1.75, 90], [-0.75, 3.75, 0]]) and np.allclose(s, r) and np.allclose(p, r)


def test_bad_inputs_give_one_line_naming_file_and_field(tmp_path):
    def one_line(exc_info, *parts):
        msg = str(exc_info.value)
        assert "\n" not in msg, msg
        for part in parts:
            assert part in msg, (part, msg)

    y = _write(tmp_path, IMG, resolution=None)  # resolution left out
    with pytest.raises(ValueError) as e:
        read_ros_map(y)
    one_line(e, str(y), "'resolution'")
    y = _write(tmp_path, IMG, name="noimg", image="m.pgm")
    y.write_text(y.read_text().replace("m.pgm", "nowhere.pgm"))
    with pytest.raises(FileNotFoundError) as e:
        read_ros_map(y)
    one_line(e, str(y), "'image'", "nowhere.pgm")
    for field, value, expect in [("negate", 2, "'negate'"), ("resolution", -0.05, "'resolution'"),
                                 ("origin", [0, 0], "'origin'"), ("origin", [0, 0, 0.3], "yaw"),
                                 ("mode", "ternary", "'mode'"), ("free_thresh", 1.5, "'free_thresh'"),
                                 ("occupied_thresh", "high", "'occupied_thresh'")]:
        y = _write(tmp_path, IMG, name="bad", **{field: value})
        with pytest.raises(ValueError) as e:
            read_ros_map(y)
        one_line(e, str(y), expect, "0.3" if expect == "yaw" else str(value).replace("'", ""))
    with pytest.raises(FileNotFoundError) as e:
        read_ros_map(tmp_path / "absent.yaml")
    one_line(e, "absent.yaml")
    # pose files: wrong columns for the frame named, with what was expected and found
    (tmp_path / "sim.csv").write_text("x,z,yaw\n1,2,3\n")
    with pytest.raises(ValueError) as e:
        read_poses(tmp_path / "sim.csv", frame="ros")
    one_line(e, str(tmp_path / "sim.csv"), "['y', 'theta']", "'ros'", "found columns ['x', 'z', 'yaw']")
    (tmp_path / "txt.csv").write_text("x,z,yaw\n1,abc,3\n")
    with pytest.raises(ValueError) as e:
        read_poses(tmp_path / "txt.csv", frame="sim")
    one_line(e, "txt.csv", "'abc'", "'z'", "index 0")
    with pytest.raises(ValueError, match="frame"):
        read_poses(tmp_path / "sim.csv", frame="auto")
    with pytest.raises(ValueError, match="needs the map"):
        read_poses(tmp_path / "sim.csv", frame="pixel")


def test_from_file_viewpoints_read_ros_poses(tmp_path):
    from benchmark.viewpoints import FromFile
    from envs.maps.scene import Scene

    grid = GridMap(np.ones((10, 10), bool), 0.5, (-1.0, 4.0))
    scene = Scene("m1", grid, np.zeros(grid.shape, np.int32), np.zeros(grid.shape, np.int32), np.array([0]), ["r"])
    # ROS (0.25, 1.75, pi) -> world (0.25, 1.75), yaw 270; (9.0, 1.0) lies right of the map (x <= 4)
    (tmp_path / "m1.csv").write_text(f"x,y,theta\n0.25,1.75,{math.pi}\n9.0,1.0,0\n")
    vp = FromFile(str(tmp_path / "{house_id}.csv"), off_map="drop", frame="ros")
    assert np.allclose(vp.generate(scene), [[0.25, 1.75, 270]])
    with pytest.raises(ValueError, match=r"lacks column\(s\) \['z', 'yaw'\] for frame 'sim'"):
        FromFile(str(tmp_path / "{house_id}.csv")).generate(scene)  # the default frame is sim
    with pytest.raises(ValueError, match="viewpoints frame must be one of"):
        FromFile("p.csv", frame="map")


@pytest.mark.parametrize("mode", ["trinary", "scale", "raw"])
@pytest.mark.parametrize("negate", [False, True])
def test_uint8_table_equals_formula(mode, negate):
    """A uint8 image is read through a table of the formula on the values 0..255: the same
    occupancy as the formula on int64 values, transparency included."""
    grey = np.arange(256).reshape(16, 16)
    alpha = np.where(np.arange(256).reshape(16, 16) % 5 == 0, 128, 255)
    for a in (None, alpha):
        want = image_to_occupancy(grey.astype(np.int64), a, negate, 0.65, 0.25, mode)
        got = image_to_occupancy(grey.astype(np.uint8), None if a is None else a.astype(np.uint8), negate, 0.65,
                                 0.25, mode)
        assert got.dtype == np.int8 and np.array_equal(got, want)


def test_grey_of_colour_images_is_the_integer_mean(tmp_path):
    """RGB / RGBA / LA: uint8 grey = integer mean of the colour channels (sums above 255
    included), alpha as stored; a grey image has no alpha (None: opaque)."""
    from envs.maps.ros import _grey_and_alpha

    rng = np.random.default_rng(0)
    rgba = rng.integers(0, 256, (9, 11, 4)).astype(np.uint8)
    rgba[0, 0] = (255, 255, 255, 7)
    for mode, a in (("RGBA", rgba), ("RGB", rgba[..., :3]), ("LA", rgba[..., [0, 3]]), ("L", rgba[..., 0])):
        grey, alpha = _grey_and_alpha(Image.fromarray(np.ascontiguousarray(a), mode), tmp_path / "x.png")
        colour = a if mode in ("RGB", "L") else a[..., :-1]
        want = colour.astype(np.int64) if mode == "L" else colour.astype(np.int64).sum(-1) // colour.shape[-1]
        assert grey.dtype == np.uint8 and np.array_equal(grey, want)
        if mode in ("RGBA", "LA"):
            assert np.array_equal(alpha, a[..., -1])
        else:
            assert alpha is None
