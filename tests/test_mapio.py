import numpy as np
import pytest
from PIL import Image

from envs.maps.label_png import read_instance_png, read_label_png, write_label_png

CLASSES = ["balcony", "bathroom", "bedroom"]


def test_label_png_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    labels = rng.integers(-1, 3, (20, 30)).astype(np.int32)
    walkable = rng.random((20, 30)) < 0.8
    labels[~walkable] = -1
    p = write_label_png(tmp_path / "m.png", labels, CLASSES, walkable=walkable, resolution=0.05)
    back, classes = read_label_png(p)
    assert classes == CLASSES and np.array_equal(back, labels)
    assert (tmp_path / "m_legend.png").exists()
    rgb = np.asarray(Image.open(p))
    assert tuple(rgb[~walkable][0]) == (0, 0, 0)


def test_label_png_bad_values(tmp_path):
    with pytest.raises(ValueError, match="outside"):
        write_label_png(tmp_path / "m.png", np.full((3, 3), 7), CLASSES)
    with pytest.raises(ValueError, match="non-empty"):
        write_label_png(tmp_path / "m.png", np.zeros((0, 3), int), CLASSES)
    Image.fromarray(np.zeros((3, 3, 3), np.uint8)).save(tmp_path / "x.png")
    with pytest.raises(FileNotFoundError, match="sidecar"):
        read_label_png(tmp_path / "x.png")


def test_instance_png_with_blended_edge(tmp_path):
    img = np.zeros((10, 20, 3), np.uint8)
    img[:, :9] = (255, 0, 0)
    img[:, 11:] = (0, 0, 255)
    img[:, 9:11] = (128, 0, 128)  # 20 px of blend between the rooms
    img[0, 0] = (0, 0, 0)
    Image.fromarray(img).save(tmp_path / "i.png")
    inst, colors = read_instance_png(tmp_path / "i.png", min_pixels=50, return_colors=True)
    assert inst.max() == 1 and inst[0, 0] == -1
    assert (inst[:, 9] == inst[0, 1]).all() and (inst[:, 10] == inst[0, 19]).all()  # nearest room
    assert {tuple(c) for c in colors} == {(255, 0, 0), (0, 0, 255)}
    dropped = read_instance_png(tmp_path / "i.png", min_pixels=50, assign="drop")
    assert (dropped[:, 9:11] == -1).all()
    with pytest.raises(FileNotFoundError):
        read_instance_png(tmp_path / "none.png")


def test_draw_house_shows_every_room_class(procthor_file, tmp_path):
    from benchmark.commands.draw_house import main
    from envs.datasets.house_files import load_houses
    from envs.maps.scene import rasterise_house
    from envs.world.classes import class_colors

    out = tmp_path / "house.png"
    assert main(["--houses", str(procthor_file), "--index", "3", "--out", str(out), "--resolution", "0.1"]) == 0
    rgb = np.asarray(Image.open(out).convert("RGB"))
    scene = rasterise_house(load_houses(procthor_file, 3, 4)[0], resolution=0.1)
    count = {name: int((rgb == np.array(c)).all(-1).sum()) for name, c in zip(scene.classes, class_colors(scene.classes))}
    shown = {scene.classes[int(c)] for c in scene.instance_classes}
    swatch = max(n for name, n in count.items() if name not in shown)  # legend only
    assert swatch > 0  # every class is in the legend
    for name in shown:  # a room class also covers its rooms on the map
        assert count[name] > 10 * swatch, (name, count)
