import json

import numpy as np
import pytest
from maps import l_grid, rect_grid, two_rooms_grid
from scipy import ndimage

from benchmark.viewpoints import Autotrace, FromFile, load_poses
from envs.scene import Scene


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
