"""ArchitecTHOR: annotation import and loading, the environment, and the simulator configs."""

import json

import numpy as np
import pytest
from PIL import Image

from benchmark.commands.annotations import main
from envs.datasets.architecthor import ARCHITECTHOR_SCENES, ArchitecTHOREnv
from envs.maps.annotations import (
    components_as_rooms,
    import_room_map,
    load_annotation,
    write_walkable,
)
from envs.maps.gridmap import GridMap
from envs.world.classes import PAPER_CLASSES

RED, BLUE, GREEN = (255, 0, 0), (0, 0, 255), (0, 255, 0)


def _room_map(tmp_path):
    """20 x 30 px: a red room (left), a blue room (right) joined by a 2-px doorway of blue,
    and a green room in the bottom-right corner."""
    img = np.zeros((20, 30, 3), np.uint8)
    img[2:18, 2:14] = RED
    img[2:12, 16:28] = BLUE
    img[8:10, 14:16] = BLUE  # doorway, part of the blue room
    img[14:18, 20:28] = GREEN
    Image.fromarray(img).save(tmp_path / "map.png")
    return tmp_path / "map.png"


COLOURS = {"#ff0000": "kitchen", "#0000ff": "living_room", "#00ff00": "bathroom"}


def test_import_and_load_by_hand(tmp_path):
    out = import_room_map(_room_map(tmp_path), COLOURS, 0.05, (1.0, 2.0), tmp_path / "ann" / "ArchitecTHOR-Val-00")
    assert sorted(p.name for p in out.iterdir()) == ["SOURCE.txt", "instances.png", "labels.json", "labels.png"]
    meta = json.loads((out / "labels.json").read_text())
    assert meta["resolution"] == 0.05 and meta["origin"] == [1.0, 2.0] and meta["classes"] == list(PAPER_CLASSES)
    s = load_annotation(out)
    assert s.house_id == "ArchitecTHOR-Val-00" and s.grid.resolution == 0.05 and s.grid.origin == (1.0, 2.0)
    assert s.grid.walkable.sum() == 16 * 12 + 10 * 12 + 4 + 4 * 8
    names = sorted(PAPER_CLASSES[k] for k in s.instance_classes)
    assert names == ["bathroom", "kitchen", "living_room"]
    sem = s.semantic
    assert PAPER_CLASSES[sem[5, 5]] == "kitchen" and PAPER_CLASSES[sem[8, 14]] == "living_room"
    assert PAPER_CLASSES[sem[15, 25]] == "bathroom" and sem[0, 0] == -1
    # world position of a pixel: x = 1.0 + (c + 0.5) * 0.05, z = 2.0 - (r + 0.5) * 0.05
    assert s.grid.world_to_cell(1.0 + 5.5 * 0.05, 2.0 - 5.5 * 0.05) == (5, 5)


def test_two_rooms_of_one_class(tmp_path):
    """A class-coloured map: two bedrooms in one colour are two rooms with --rooms components,
    one room with --rooms colour."""
    img = np.zeros((10, 21, 3), np.uint8)
    img[1:9, 1:10] = RED
    img[1:9, 11:20] = RED
    Image.fromarray(img).save(tmp_path / "beds.png")
    col = import_room_map(tmp_path / "beds.png", {"#ff0000": "bedroom"}, 0.1, (0, 0), tmp_path / "a")
    comp = import_room_map(tmp_path / "beds.png", {"#ff0000": "bedroom"}, 0.1, (0, 0), tmp_path / "b",
                           rooms="components")
    assert len(load_annotation(col).instance_classes) == 1
    s = load_annotation(comp)
    assert len(s.instance_classes) == 2 and not (comp / "instances.png").exists()
    assert set(np.unique(s.instances[:, :10])) == {-1, 0} and set(np.unique(s.instances[:, 11:])) == {-1, 1}
    lab = np.array([[0, 0, -1, 0], [1, -1, -1, 0]])
    assert components_as_rooms(lab).tolist() == [[0, 0, -1, 1], [2, -1, -1, 1]]


def test_walkable_on_its_own_grid(tmp_path):
    """A navmesh walkable map on another grid: the labels are carried onto it by world position."""
    out = import_room_map(_room_map(tmp_path), COLOURS, 0.05, (1.0, 2.0), tmp_path / "h")
    walk = np.zeros((10, 15), bool)  # 0.1 m/px over the same area
    walk[1:9, 1:14] = True
    write_walkable(out, GridMap(walk, 0.1, (1.0, 2.0)))
    s = load_annotation(out)
    assert s.grid.shape == (10, 15) and s.grid.resolution == 0.1
    assert np.array_equal(s.instances >= 0, walk & (s.rooms >= 0))
    # the 0.1 m cell (2, 2) has its centre on the 0.05 m pixel (5, 5): the kitchen
    assert PAPER_CLASSES[s.semantic[2, 2]] == "kitchen"
    assert PAPER_CLASSES[s.semantic[2, 10]] == "living_room"
    # a walkable.png without walkable.json must share the label grid
    (out / "walkable.json").unlink()
    with pytest.raises(ValueError, match="differ in size"):
        load_annotation(out)
    Image.fromarray(np.full((20, 30), 255, np.uint8)).save(out / "walkable.png")
    assert load_annotation(out).grid.walkable.all()


def test_bad_annotations(tmp_path):
    with pytest.raises(FileNotFoundError, match="no annotation at .*python -m benchmark.commands.annotations import"):
        load_annotation(tmp_path / "none")
    with pytest.raises(ValueError, match="has no class in the colour JSON"):
        import_room_map(_room_map(tmp_path), {"#ff0000": "kitchen"}, 0.05, (0, 0), tmp_path / "x")
    with pytest.raises(ValueError, match="unknown room class 'garage'"):
        import_room_map(_room_map(tmp_path), {**COLOURS, "#00ff00": "garage"}, 0.05, (0, 0), tmp_path / "x")
    with pytest.raises(ValueError, match="#rrggbb"):
        import_room_map(_room_map(tmp_path), {"red": "kitchen"}, 0.05, (0, 0), tmp_path / "x")
    with pytest.raises(ValueError, match="rooms must be one of"):
        import_room_map(_room_map(tmp_path), COLOURS, 0.05, (0, 0), tmp_path / "x", rooms="blobs")
    out = import_room_map(_room_map(tmp_path), COLOURS, 0.05, (0, 0), tmp_path / "y")
    meta = json.loads((out / "labels.json").read_text())
    (out / "labels.json").write_text(json.dumps({**meta, "resolution": None}))
    with pytest.raises(ValueError, match="'resolution'"):
        load_annotation(out)


def test_import_and_check_commands(tmp_path, capsys):
    (tmp_path / "c.json").write_text(json.dumps(COLOURS))
    root = tmp_path / "ann"
    assert main(["import", "--map", str(_room_map(tmp_path)), "--colours", str(tmp_path / "c.json"),
                 "--resolution", "0.05", "--origin", "1", "2", "--out", str(root / "ArchitecTHOR-Test-00")]) == 0
    out = capsys.readouterr().out
    assert "ArchitecTHOR-Test-00: 3 rooms (bathroom 1, kitchen 1, living_room 1)" in out
    assert main(["check", str(root)]) == 0
    (root / "ArchitecTHOR-Test-01").mkdir()
    assert main(["check", str(root)]) == 1
    assert "ArchitecTHOR-Test-01: no annotation" in capsys.readouterr().out


def test_environment(tmp_path):
    import_room_map(_room_map(tmp_path), COLOURS, 0.05, (1.0, 2.0), tmp_path / "ann" / "ArchitecTHOR-Val-00")
    env = ArchitecTHOREnv(str(tmp_path / "ann"))
    assert env.house_ids() == list(ARCHITECTHOR_SCENES) and len(ARCHITECTHOR_SCENES) == 10
    assert env.house("ArchitecTHOR-Val-00").data == {"scene": "ArchitecTHOR-Val-00"}
    s = env.scene("ArchitecTHOR-Val-00")
    assert s.house_id == "ArchitecTHOR-Val-00" and len(s.instance_classes) == 3
    assert env.missing() == list(ARCHITECTHOR_SCENES[1:])
    with pytest.raises(FileNotFoundError, match="no annotation"):
        env.scene("ArchitecTHOR-Test-04")
    with pytest.raises(KeyError, match="no house"):
        env.house("FloorPlan1")
    with pytest.raises(ValueError, match="unknown ArchitecTHOR house"):
        ArchitecTHOREnv(str(tmp_path), houses=["ArchitecTHOR-Val-09"])
    # classes in another order: indices follow the env's class list
    other = ArchitecTHOREnv(str(tmp_path / "ann"), houses=["ArchitecTHOR-Val-00"],
                            classes=["kitchen", "bathroom", "living_room"])
    assert sorted(other.scene("ArchitecTHOR-Val-00").instance_classes.tolist()) == [0, 1, 2]


@pytest.mark.parametrize("overrides,target", [
    (["env=architecthor"], "env"),
    (["renderer=ai2thor"], "renderer"),
    (["renderer=habitat"], "renderer"),
])
def test_configs_compose_and_instantiate(overrides, target, tmp_path, monkeypatch):
    from hydra import compose, initialize_config_dir
    from hydra.utils import instantiate

    from benchmark.harness.runner import CONF_DIR

    monkeypatch.setenv("ROOMSEG_ARCHITECTHOR_ANNOTATIONS", str(tmp_path))
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=overrides)
    obj = instantiate(cfg[target])  # constructing starts no simulator
    if target == "env":
        assert obj.house_ids() == list(ARCHITECTHOR_SCENES) and obj.root == tmp_path
        assert obj.classes == tuple(cfg.classes)
    elif overrides[0].endswith("ai2thor"):
        assert obj.fov == 90.0 and obj.platform == "CloudRendering" and obj._controller is None
    else:
        assert obj.mirror == "z" and obj.scene_dataset.endswith("ai2thor-hab.scene_dataset_config.json")
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        bad = compose("config", overrides=overrides + [f"{target}.{'houses' if target == 'env' else 'fov'}="
                                                       + ("[Kitchen]" if target == "env" else "200")])
    with pytest.raises(Exception, match="unknown ArchitecTHOR house|fov must be in"):
        instantiate(bad[target])


def test_annotation_checked_against_the_navmesh_map(tmp_path, capsys):
    """The navmesh map is written first (its own grid, in the convention the mirror check
    chose), then the annotation is imported and checked against it by world position: the
    share of annotated pixels on walkable cells, by hand, and a WARNING when the navmesh was
    written in the other convention."""
    from envs.maps.annotations import agreement_line, walkable_agreement
    from envs.render.habitat import topdown_to_gridmap

    # Habitat's top-down view of a navmesh covering exactly the red room (rows 2:18, cols 2:14
    # of the 0.05 m room map whose top-left corner is world (x, z) = (1.0, 2.0)): with
    # mirror=z, Habitat z = -our z, so the view starts at Habitat (x, z) = (1.0, -2.0).
    top = np.zeros((20, 30), bool)
    top[2:18, 2:14] = True
    root = tmp_path / "ann"
    for mirror, house in (("z", "ArchitecTHOR-Val-00"), ("x", "ArchitecTHOR-Val-01")):
        write_walkable(root / house, topdown_to_gridmap(top, lower_bound=(1.0, 0.0, -2.0), resolution=0.05,
                                                        mirror=mirror))
    (tmp_path / "c.json").write_text(json.dumps(COLOURS))
    for house in ("ArchitecTHOR-Val-00", "ArchitecTHOR-Val-01"):
        main(["import", "--map", str(_room_map(tmp_path)), "--colours", str(tmp_path / "c.json"),
              "--resolution", "0.05", "--origin", "1", "2", "--out", str(root / house)])
    out = capsys.readouterr().out
    n_ann = 16 * 12 + 10 * 12 + 4 + 4 * 8  # red, blue, doorway, green
    a = walkable_agreement(root / "ArchitecTHOR-Val-00")
    assert a == {"annotated": n_ann, "on_walkable": pytest.approx(16 * 12 / n_ann), "walkable": 16 * 12,
                 "covered": 1.0}
    assert f"ArchitecTHOR-Val-00: 55.2% of {n_ann} annotated px on walkable cells (warn below 50%), " \
           "100.0% of 192 walkable cells in a room (warn below 90%)" in out
    bad = walkable_agreement(root / "ArchitecTHOR-Val-01")  # the other convention: off the rooms
    assert bad["on_walkable"] < 0.5 and bad["covered"] < 0.9
    line, ok = agreement_line(root / "ArchitecTHOR-Val-01")
    assert not ok and line.startswith("WARNING ArchitecTHOR-Val-01") and "navmesh mirror" in line
    assert "WARNING ArchitecTHOR-Val-01" in out and "WARNING ArchitecTHOR-Val-00" not in out
    assert main(["check", str(root)]) == 0  # warnings do not fail the check ...
    assert "1 of 2 house(s) do not sit on their navmesh map" in capsys.readouterr().out
    assert main(["check", str(root), "--strict"]) == 1  # ... unless asked to
    assert walkable_agreement(tmp_path / "nowhere") is None
    assert agreement_line(import_room_map(_room_map(tmp_path), COLOURS, 0.05, (1.0, 2.0), tmp_path / "plain"))[1]
