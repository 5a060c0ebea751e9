import json

import numpy as np
import pytest
from maps import l_grid, rect_grid, two_rooms_grid
from scipy import ndimage

from benchmark.viewpoints import Autotrace, FromFile, load_poses
from envs.maps.scene import Scene


@pytest.mark.parametrize("make", [rect_grid, l_grid, two_rooms_grid])
def test_autotrace_keeps_offset_and_is_deterministic(make):
    grid = make()
    at = Autotrace(offset=0.2, spacing=0.3, n_headings=3)
    p = at.generate(grid)
    assert len(p) > 0 and p.shape[1] == 3
    r, c = grid.world_to_cell(p[:, 0], p[:, 1])
    assert grid.is_walkable(r, c).all()
    dist = ndimage.distance_transform_edt(np.pad(grid.walkable, 1))[1:-1, 1:-1]
    assert (dist[r, c] > 0.2 / grid.resolution).all()
    assert np.array_equal(p, at.generate(grid))
    assert len(p) % 3 == 0


def test_autotrace_covers_both_rooms_and_points_inward():
    grid = two_rooms_grid()
    p = Autotrace(offset=0.2, spacing=0.3, n_headings=1).generate(grid)
    _, c = grid.world_to_cell(p[:, 0], p[:, 1])
    assert (c < 38).any() and (c > 39).any()
    # a point near the left wall of the rectangle looks right (yaw ~90) when inward
    g = rect_grid()
    q = Autotrace(offset=0.2, spacing=0.2, n_headings=1).generate(g)
    r, c = g.world_to_cell(q[:, 0], q[:, 1])
    left = (c == c.min()) & (r > 12) & (r < 28)
    assert left.any() and np.allclose(q[left, 2], 90, atol=20)


def test_autotrace_spacing():
    g = rect_grid(h=40, w=200)
    n1 = len(Autotrace(offset=0.2, spacing=0.5).generate(g))
    n2 = len(Autotrace(offset=0.2, spacing=1.0).generate(g))
    assert 1.6 < n1 / n2 < 2.4


def test_poses_from_file(tmp_path):
    grid = rect_grid()
    scene = Scene("h1", grid, np.zeros(grid.shape, np.int32), np.zeros(grid.shape, np.int32), np.array([0]), ["r"])
    x, z = grid.pixel_to_world(20, 30)
    (tmp_path / "h1.csv").write_text(f"x,z,yaw\n{x},{z},90\n{x},{z},180\n")
    assert FromFile(str(tmp_path / "{house_id}.csv")).generate(scene).tolist() == [[x, z, 90], [x, z, 180]]
    (tmp_path / "p.json").write_text(json.dumps({"poses": [{"x": x, "z": z, "yaw": 0}, {"x": 99, "z": 99, "yaw": 0}]}))
    with pytest.raises(ValueError, match="1 of 2 poses are off the walkable map.*index 1"):
        FromFile(str(tmp_path / "p.json")).generate(scene)
    assert len(FromFile(str(tmp_path / "p.json"), off_map="drop").generate(scene)) == 1
    (tmp_path / "bad.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match="lacks column"):
        load_poses(tmp_path / "bad.csv")


def test_autotrace_covers_both_arms_of_the_l():
    g = l_grid()
    p = Autotrace(offset=0.2, spacing=0.3, n_headings=1).generate(g)
    r, c = g.world_to_cell(p[:, 0], p[:, 1])
    assert ((r < 30) & (c < 22)).any()  # the vertical arm, above the corner
    assert ((c > 30) & (r >= 38)).any()  # the horizontal arm, right of the corner


def test_autotrace_headings_spread_around_the_inward_normal():
    g = rect_grid()
    one = Autotrace(offset=0.2, spacing=0.3, n_headings=1).generate(g)
    three = Autotrace(offset=0.2, spacing=0.3, n_headings=3, heading_spread=180).generate(g)
    assert np.array_equal(three[::3, :2], one[:, :2]) and np.array_equal(three[1::3], one)
    rel = np.mod(three[:, 2].reshape(-1, 3) - one[:, 2:3] + 180, 360) - 180
    assert np.allclose(rel, [-90, 0, 90])
    four = Autotrace(offset=0.2, spacing=0.3, n_headings=4, heading_spread=360).generate(g)
    rel4 = np.mod(four[:, 2].reshape(-1, 4) - one[:, 2:3] + 180, 360) - 180
    assert np.allclose(rel4, [-180, -90, 0, 90])  # a full circle does not repeat its first heading
    with pytest.raises(ValueError, match="spacing"):
        Autotrace(spacing=0)


def test_autotrace_covers_every_room_of_shared_houses(procthor_file):
    from envs.datasets.house_files import load_houses
    from envs.maps.scene import rasterise_house

    at = Autotrace(offset=0.5, spacing=1.0, n_headings=1)
    checked = 0
    for house in load_houses(procthor_file, 0, 12):
        scene = rasterise_house(house, resolution=0.05)
        p = at.generate(scene)
        r, c = scene.grid.world_to_cell(p[:, 0], p[:, 1])
        assert scene.grid.is_walkable(r, c).all()
        dist = ndimage.distance_transform_edt(np.pad(scene.grid.walkable, 1))[1:-1, 1:-1] * 0.05
        assert (dist[r, c] > 0.5).all()
        visited = set(scene.instances[r, c].tolist())
        for k in range(len(scene.instance_classes)):
            room = scene.instances == k
            if room.any() and dist[room].max() > 0.6:  # a room wide enough for the path
                assert k in visited, f"{house.id}: room {k} has no viewpoint"
                checked += 1
    assert checked >= 40


def test_pose_file_formats_and_errors(tmp_path):
    (tmp_path / "list.json").write_text(json.dumps([{"x": 1.0, "z": 2.0, "yaw": 90}, {"x": 3, "z": 4, "yaw": -45}]))
    assert load_poses(tmp_path / "list.json").tolist() == [[1, 2, 90], [3, 4, -45]]
    (tmp_path / "upper.csv").write_text(" X , Z , Yaw \n1.5,2.5,180\n")
    assert load_poses(tmp_path / "upper.csv").tolist() == [[1.5, 2.5, 180]]
    with pytest.raises(FileNotFoundError, match="pose file not found"):
        load_poses(tmp_path / "missing.csv")
    (tmp_path / "nan.csv").write_text("x,z,yaw\n1,nan,0\n")
    with pytest.raises(ValueError, match="non-finite"):
        load_poses(tmp_path / "nan.csv")
    with pytest.raises(ValueError, match="off_map"):
        FromFile("p.csv", off_map="ignore")
