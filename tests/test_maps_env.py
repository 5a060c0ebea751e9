"""The map-folder environment (env=maps): pairing, scenes from the input map, the runner on it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hydra import compose, initialize_config_dir
from PIL import Image

from benchmark.harness.runner import CONF_DIR, run
from envs.datasets.maps import MapHouse, MapsEnv
from envs.maps.ros import write_ros_map

ROOT = Path(__file__).resolve().parents[1]
RES = 0.05
#: room colours of the instance ground truth
COLOURS = [(220, 40, 40), (40, 160, 40), (40, 40, 220)]


def three_rooms(n_rooms: int = 3):
    """A row of square rooms, 3 m (60 px) inside, 2-px walls, 0.8 m (16 px) doors.

    Returns (map image (H, W) uint8 254 free / 0 occupied, ground-truth RGB, per-room interior
    slices). Image 64 x (2 + 62 * n) px. Room k's interior is rows 2..61, cols 2 + 62k .. 61 + 62k.
    The ground truth colours each room's interior *and the walls around it* (a GT drawn on
    the floor plan, not on the free space), black outside, so its non-black area is larger
    than the map's free space.
    """
    h, w = 64, 2 + 62 * n_rooms
    img = np.zeros((h, w), np.uint8)
    gt = np.zeros((h, w, 3), np.uint8)
    rooms = []
    for k in range(n_rooms):
        c0 = 2 + 62 * k
        img[2:62, c0:c0 + 60] = 254
        gt[0:64, c0 - 2:c0 + 62] = COLOURS[k]
        rooms.append((slice(2, 62), slice(c0, c0 + 60)))
        if k:
            img[24:40, c0 - 2:c0] = 254  # the door in the wall to the previous room
    return img, gt, rooms


def make_folder(folder: Path, ids=("office_a", "office_b")) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for i, mid in enumerate(ids):
        img, gt, _ = three_rooms()
        write_ros_map(folder / f"{mid}.yaml", img, RES, origin=(-2.0 + i, 1.5, 0.0), free_thresh=0.196)
        Image.fromarray(gt).save(folder / f"{mid}_gt.png")
    return folder


def test_pairing_ids_and_scene_from_the_input_map(tmp_path):
    ids = [f"office_{c}" for c in "abcdefghi"]
    folder = make_folder(tmp_path / "maps", ids)
    env = MapsEnv(str(folder))
    assert env.house_ids() == ids  # nine office_* maps stay nine (full stems, sorted)
    img, gt, rooms = three_rooms()
    scene = env.scene("office_b")
    # the grid is the map's: free cells of the image; origin from the ROS origin (-1, 1.5):
    # top-left corner z0 = 1.5 + 64 * 0.05 = 4.7
    assert np.array_equal(scene.grid.walkable, img == 254)
    assert scene.grid.origin == pytest.approx((-1.0, 4.7)) and scene.grid.resolution == RES
    # the ground truth is carried onto it: its rooms on walls are dropped (walls are not
    # walkable), the door cells (GT colour of the room on either side) keep that room
    assert (scene.instances[~scene.grid.walkable] == -1).all()
    assert (scene.instances[scene.grid.walkable] >= 0).all()
    assert len(scene.instance_classes) == 3 and (scene.instance_classes == -1).all()
    for k, (rs, cs) in enumerate(rooms):
        ids_k = np.unique(scene.instances[rs, cs])
        assert len(ids_k) == 1
        # door between room k-1 and k: cols c0-2, c0-1; col c0-2 is in room k-1's GT colour band
        if k:
            c0 = cs.start
            assert (scene.instances[24:40, c0 - 1] == ids_k[0]).all()
    assert isinstance(env.house("office_b"), MapHouse)
    with pytest.raises(ValueError, match="'office_b' .*occupancy map, not a house.*renderer=floorplan"):
        _ = env.house("office_b").rooms
    files = {p.name for p in env.input_files("office_b")}
    assert files == {"office_b.yaml", "office_b.pgm", "office_b_gt.png"}


def test_png_maps_manifest_and_bad_inputs(tmp_path):
    folder = tmp_path / "png"
    folder.mkdir()
    img, gt, _ = three_rooms(2)
    Image.fromarray(img).save(folder / "lab.png")
    Image.fromarray(gt).save(folder / "lab_gt.png")
    # the GT file matches the map pattern {id}.png too, but is a GT: never a map
    with pytest.raises(ValueError, match=r"lab.png: a .png map has no resolution; set env.image_resolution"):
        MapsEnv(str(folder), maps="{id}.png").scene("lab")
    env = MapsEnv(str(folder), maps="{id}.png", image_resolution=0.05)
    assert env.house_ids() == ["lab"]
    s = env.scene("lab")
    assert np.array_equal(s.grid.walkable, img == 254) and s.grid.origin == pytest.approx((0.0, 3.2))
    # a manifest with a missing ground truth and a map without one
    (folder / "list.csv").write_text("id,map,ground_truth\nfirst,lab.png,lab_gt.png\nsecond,lab.png,\n"
                                     "third,lab.png,nowhere.png\n")
    env = MapsEnv(str(folder), manifest="list.csv", image_resolution=0.05)
    assert env.house_ids() == ["first", "second", "third"]
    assert np.array_equal(env.scene("first").instances, s.instances)
    with pytest.raises(ValueError, match="map 'second': no ground truth"):
        env.scene("second")
    with pytest.raises(FileNotFoundError, match=r"map 'third': ground_truth file not found: .*nowhere.png"):
        env.scene("third")
    (folder / "bad.csv").write_text("name,file\nx,lab.png\n")
    with pytest.raises(ValueError, match=r"bad.csv: manifest needs columns 'id' and 'map'.*found \['name', 'file'\]"):
        MapsEnv(str(folder), manifest="bad.csv")
    with pytest.raises(FileNotFoundError, match="no map file matches env.maps"):
        MapsEnv(str(folder))  # no .yaml here
    with pytest.raises(ValueError, match="env.gt_format is 'colours'"):
        MapsEnv(str(folder), maps="{id}.png", gt_format="colours")
    with pytest.raises(ValueError, match="env.dir is not set"):
        MapsEnv("???")
    # a ROS YAML missing a field fails that map alone with the file and field
    ros = make_folder(tmp_path / "ros", ["good", "broken"])
    (ros / "broken.yaml").write_text((ros / "broken.yaml").read_text().replace("resolution: 0.05\n", ""))
    env = MapsEnv(str(ros))
    env.scene("good")
    with pytest.raises(ValueError, match=r"broken.yaml: missing field\(s\) \['resolution'\]"):
        env.scene("broken")


def _compose(tmp_path: Path, folder: Path, *overrides: str):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=["env=maps", f"env.dir={folder}", f"run.results_dir={tmp_path / 'res'}",
                                           "run.progress=false", *overrides], return_hydra_config=True)
    choices = {k: str(v) for k, v in cfg.hydra.runtime.choices.items() if not k.startswith("hydra")}
    return cfg, choices


def test_runner_scores_distance_segmenter_on_a_map_folder(tmp_path):
    folder = make_folder(tmp_path / "maps", ["office_a", "office_b", "office_c"])
    (folder / "office_c_gt.png").unlink()  # a map without ground truth fails alone
    cfg, ch = _compose(tmp_path, folder, "segmenter=distance", "run.allow_failures=true")
    df = run(cfg, tmp_path / "out", ch)
    assert sorted(df["house_id"]) == ["office_a", "office_b", "office_c"]
    bad = df[df["house_id"] == "office_c"].iloc[0]
    assert bad["status"] == "failed" and "office_c_gt.png" in bad["error"], bad["error"]
    df = df[df["house_id"] != "office_c"]
    assert (df["status"] == "ok").all(), df[["house_id", "status", "error"]]
    # three 3 x 3 m rooms joined by 0.8 m doors: the distance transform finds them
    assert (df["iou"] > 0.9).all() and (df["n_gt_segments"] == 3).all() and (df["n_pred_segments"] == 3).all()


@pytest.mark.slow
def test_multirun_sweeps_three_segmenters_over_the_folder(tmp_path):
    folder = make_folder(tmp_path / "maps")
    res = tmp_path / "res"
    cmd = [sys.executable, "-m", "benchmark.commands.bench", "-m", "env=maps", f"env.dir={folder}",
           "segmenter=distance,voronoi,morphological", f"run.results_dir={res}", "run.name=maps",
           "run.progress=false", "hydra/launcher=basic"]
    out = subprocess.run(cmd, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    csvs = sorted((res / "runs" / "maps").rglob("metrics.csv"))
    assert len(csvs) == 3
    df = pd.concat(pd.read_csv(c) for c in csvs)
    assert len(df) == 6 and (df["status"] == "ok").all()
    assert df["iou"].between(0, 1).all() and (df["n_gt_segments"] == 3).all()
    assert (df[df["segmenter"] == "distance"]["iou"] > 0.9).all()


def test_method_on_ground_truth_without_classes_fails_that_house_with_one_line(tmp_path):
    """Instance ground truth carries no room classes: the method's class scores would be
    meaningless, so the house fails with a line saying so (segmenters still score it)."""
    from benchmark.harness.pipeline import MethodPipeline
    from envs.maps.gridmap import GridMap
    from envs.maps.scene import Scene

    grid = GridMap(np.ones((4, 4), bool), 0.1, (0.0, 0.4))
    inst = np.zeros((4, 4), np.int32)
    scene = Scene(house_id="m", grid=grid, rooms=inst.copy(), instances=inst, instance_classes=np.array([-1]),
                  room_ids=["r0"], classes=("a", "b"))

    class Env:
        name = "maps"

        def house_ids(self):
            return ["m"]

        def house(self, hid):
            raise AssertionError("not needed")

        def scene(self, hid):
            return scene

    pipe = MethodPipeline(env=Env(), cache_dir=tmp_path, keys={}, names={}, metric_params=None)
    with pytest.raises(ValueError, match="1 of 1 ground-truth rooms have no class"):
        pipe._compute("m", {})
