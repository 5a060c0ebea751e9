import shutil

import numpy as np
import pytest

from envs.render.cache import (
    is_complete,
    poses_table,
    read_observations,
    read_poses,
    write_observations,
)
from envs.render.observation import Observation


def _obs(rng):
    return [
        Observation(pose=(1.0 / 3, -2.5, 359.99), objects=[("Bed", 0.125), ("Pillow", 1 / 7)],
                    visible_classes=rng.random(7), meta={"n_visible_cells": 12}),
        Observation(pose=(0.1, 0.2, 0.3), image=rng.integers(0, 256, (8, 6, 3), dtype=np.uint8),
                    objects=[("Sofa", 0.5)]),
        Observation(pose=(4.0, 5.0, 90.0), meta={"refused": True, "error": "teleport failed"}),
    ]


def _same(a, b):
    assert a.pose == b.pose and a.objects == b.objects and a.meta == b.meta
    assert (a.visible_classes is None) == (b.visible_classes is None)
    if a.visible_classes is not None:
        assert np.array_equal(a.visible_classes, b.visible_classes)
    assert (a.image is None and b.image is None) or np.array_equal(a.image, b.image)


def test_round_trip_with_images_objects_and_refused_views(tmp_path):
    obs = _obs(np.random.default_rng(0))
    folder = tmp_path / "house-1"
    assert not is_complete(folder)
    write_observations(folder, obs)
    assert is_complete(folder)
    back = read_observations(folder)
    assert len(back) == 3
    for a, b in zip(obs, back):
        _same(a, b)
    assert sorted(p.name for p in (folder / "images").iterdir()) == ["000001.png"]
    lines = (folder / "poses.csv").read_text().splitlines()
    assert lines[0] == "index,x,z,yaw,refused,image"
    assert lines[2] == "1,0.1,0.2,0.3,0,images/000001.png" and lines[3] == "2,4.0,5.0,90.0,1,"
    poses, refused = read_poses(folder)
    assert np.array_equal(poses, [[1.0 / 3, -2.5, 359.99], [0.1, 0.2, 0.3], [4.0, 5.0, 90.0]])
    assert refused.tolist() == [False, False, True]
    assert read_observations(folder, images=False)[1].image is None


def test_the_files_written_byte_for_byte(tmp_path):
    """The format as written: poses.csv and observations.jsonl as text, written out here by
    hand, and COMPLETE's count and the sha256 of each file as it lies on disk, in name order."""
    import hashlib

    obs = [Observation(pose=(0.5, -1.25, 90.0), objects=[("Bed", 0.25)], visible_classes=np.array([1, 0], np.float32),
                       meta={"n_visible_cells": np.int64(3)}),
           Observation(pose=(2.0, 3.0, -45.5), image=np.zeros((2, 2, 3), np.uint8)),
           Observation(pose=(1.0, 1.0, 0.0), meta={"refused": True, "error": "é"})]
    folder = tmp_path / "h"
    write_observations(folder, obs)
    assert (folder / "poses.csv").read_bytes() == (
        b"index,x,z,yaw,refused,image\n0,0.5,-1.25,90.0,0,\n1,2.0,3.0,-45.5,0,images/000001.png\n2,1.0,1.0,0.0,1,\n")
    assert (folder / "observations.jsonl").read_bytes() == (
        b'{"objects": [["Bed", 0.25]], "visible_classes": [1.0, 0.0], "meta": {"n_visible_cells": 3}}\n'
        b'{"objects": [], "visible_classes": null, "meta": {}}\n'
        b'{"objects": [], "visible_classes": null, "meta": {"refused": true, "error": "\\u00e9"}}\n')
    names = ["images/000001.png", "observations.jsonl", "poses.csv"]
    assert (folder / "COMPLETE").read_text() == "3\n" + "".join(
        f"{hashlib.sha256((folder / n).read_bytes()).hexdigest()} {n}\n" for n in names)


def test_a_copied_cache_reads_the_same(tmp_path):
    obs = _obs(np.random.default_rng(1))
    write_observations(tmp_path / "gpu-box" / "h", obs)
    shutil.copytree(tmp_path / "gpu-box" / "h", tmp_path / "laptop" / "cache" / "h")
    shutil.rmtree(tmp_path / "gpu-box")
    for a, b in zip(obs, read_observations(tmp_path / "laptop" / "cache" / "h")):
        _same(a, b)


def test_rewrite_replaces_and_a_failed_rewrite_keeps_the_old_render(tmp_path):
    obs = _obs(np.random.default_rng(2))
    folder = tmp_path / "h"
    write_observations(folder, obs)
    write_observations(folder, obs[:1])
    assert len(read_observations(folder)) == 1 and not (folder / "images").exists()
    bad = obs + [Observation(pose=(0, 0, 0), image=np.zeros((2, 2), np.uint8))]
    with pytest.raises(ValueError, match=r"observation 3: image must be \(H, W, 3\) uint8"):
        write_observations(folder, bad)
    assert len(read_observations(folder)) == 1  # the old render is untouched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h"]  # no temporary folders left


def test_incomplete_and_damaged(tmp_path):
    (tmp_path / "x").mkdir()
    with pytest.raises(FileNotFoundError, match="no complete render"):
        read_observations(tmp_path / "x")
    with pytest.raises(FileNotFoundError, match="no complete render"):
        read_poses(tmp_path / "x")
    write_observations(tmp_path / "y", _obs(np.random.default_rng(3)))
    (tmp_path / "y" / "COMPLETE").write_text("5\n")
    with pytest.raises(ValueError, match="damaged"):
        read_observations(tmp_path / "y")
    with pytest.raises(TypeError, match="not JSON serialisable"):
        write_observations(tmp_path / "z", [Observation(pose=(0, 0, 0), meta={"x": object()})])
    assert not (tmp_path / "z").exists()


def test_the_poses_table_of_views_is_the_one_their_render_holds(tmp_path):
    """poses_table of the views written (and of the views read back) equals read_poses of the
    folder bit for bit: on random floats of every magnitude, numpy floats, -0.0, refused views
    and none."""
    rng = np.random.default_rng(8)
    obs = []
    for i in range(300):
        x, z, yaw = rng.uniform(-1, 1, 3) * 10.0 ** rng.integers(-9, 9, 3)
        pose = (np.float64(x), float(z), float(yaw)) if i % 2 else (-0.0, float(z), float(np.float32(yaw)))
        obs.append(Observation(pose=pose, visible_classes=rng.random(3), meta={"refused": True} if i % 7 == 0 else {}))
    for views in (obs, [obs[1]]):
        folder = tmp_path / f"house-{len(views)}"
        write_observations(folder, views)
        want = read_poses(folder)
        for got in (poses_table(views), poses_table(read_observations(folder))):
            assert got[0].tobytes() == want[0].tobytes() and got[0].shape == want[0].shape
            assert got[1].dtype == bool and got[1].tolist() == want[1].tolist()
    assert want[1].tolist() == [False] and read_poses(tmp_path / "house-300")[1].sum() == 43
    empty = poses_table([])
    assert empty[0].shape == (0, 3) and empty[1].shape == (0,)
