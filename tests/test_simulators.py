"""Simulator adapters: everything that does not need the simulator process."""

import inspect
import json

import numpy as np
import pytest

from envs.poses import (
    habitat_forward,
    habitat_quat_to_thor_yaw,
    habitat_to_thor_position,
    pose_to_thor_teleport,
    thor_forward,
    thor_to_habitat_position,
    thor_yaw_to_habitat_quat,
)


@pytest.mark.parametrize("yaw,thor_fwd,hab_fwd", [
    (0, (0, 0, 1), (0, 0, -1)),     # THOR +z is Habitat -z
    (90, (1, 0, 0), (1, 0, 0)),     # THOR +x stays +x
    (180, (0, 0, -1), (0, 0, 1)),
    (270, (-1, 0, 0), (-1, 0, 0)),
])
def test_heading_conversion_by_hand(yaw, thor_fwd, hab_fwd):
    assert np.allclose(thor_forward(yaw), thor_fwd, atol=1e-12)
    q = thor_yaw_to_habitat_quat(yaw)
    assert np.isclose(np.linalg.norm(q), 1.0)
    assert np.allclose(habitat_forward(q), hab_fwd, atol=1e-12)
    # the Habitat forward is the mirrored THOR forward
    assert np.allclose(habitat_forward(q), thor_to_habitat_position(*thor_forward(yaw)), atol=1e-12)


def test_round_trips():
    rng = np.random.default_rng(0)
    for _ in range(50):
        x, y, z, yaw = rng.uniform(-10, 10), rng.uniform(0, 2), rng.uniform(-10, 10), rng.uniform(0, 360)
        assert np.allclose(habitat_to_thor_position(thor_to_habitat_position(x, y, z)), (x, y, z))
        assert np.isclose(habitat_quat_to_thor_yaw(thor_yaw_to_habitat_quat(yaw)), yaw % 360)
    assert thor_to_habitat_position(1.0, 0.9, 2.0).tolist() == [1.0, 0.9, -2.0]
    with pytest.raises(ValueError, match="vertical axis"):
        habitat_quat_to_thor_yaw([0.7, 0.7, 0.0, 0.0])


def test_teleport_arguments_match_the_real_api():
    ai2thor = pytest.importorskip("ai2thor.controller")
    args = pose_to_thor_teleport((1.5, -2.0, 90.0), 0.95, 30.0)
    assert args == {"action": "TeleportFull", "position": {"x": 1.5, "y": 0.95, "z": -2.0},
                    "rotation": {"x": 0.0, "y": 90.0, "z": 0.0}, "horizon": 30.0, "standing": True}
    from envs.ai2thor_renderer import controller_kwargs

    kw = controller_kwargs({"rooms": []}, width=64, height=48, fov=90, platform="CloudRendering")
    params = inspect.signature(ai2thor.Controller.__init__).parameters
    named = {k for k in kw if k in params}
    assert {"scene", "platform", "width", "height"} <= named
    # the rest are Unity initialisation parameters, accepted through **unity_initialization_parameters
    assert any(p.kind == p.VAR_KEYWORD for p in params.values())
    import ai2thor.platform

    assert kw["platform"] is ai2thor.platform.CloudRendering and kw["renderInstanceSegmentation"] is True
    with pytest.raises(ValueError, match="unknown AI2-THOR platform"):
        controller_kwargs("FloorPlan1", platform="Windows95")


def _event(objects, masks, success=True, error=""):
    from ai2thor.server import Event

    ev = Event({"objects": objects, "lastActionSuccess": success, "errorMessage": error, "screenWidth": 4,
                "screenHeight": 4, "colors": [], "colorBounds": []})
    ev.instance_masks = masks
    ev.frame = np.full((4, 4, 3), 7, np.uint8)
    return ev


def test_visible_objects_from_real_events():
    pytest.importorskip("ai2thor.server")
    from envs.ai2thor_renderer import visible_objects

    m1 = np.zeros((4, 4), bool)
    m1[:2, :2] = True  # 4 of 16 pixels
    m2 = np.zeros((4, 4), bool)
    m2[3, 3] = True
    m3 = np.zeros((4, 4), bool)
    m3[0, 3] = True
    ev = _event([{"objectId": "Bed|1|2", "objectType": "Bed"}, {"objectId": "Chair|3", "objectType": "Chair"},
                 {"objectId": "Chair|4", "objectType": "Chair"}], {"Bed|1|2": m1, "Chair|3": m2, "Chair|4": m3,
                                                                   "Pillow|9": m2})
    assert visible_objects(ev) == [("Bed", 0.25), ("Chair", 0.125), ("Pillow", 0.0625)]


def test_refused_teleport_is_recorded_and_skipped():
    pytest.importorskip("ai2thor.server")
    from envs.ai2thor_renderer import AI2THORRenderer

    class StandIn:  # plays the controller: refuses the second pose
        def __init__(self):
            self.calls = []

        def step(self, **kw):
            self.calls.append(kw)
            ok = len(self.calls) != 2
            return _event([{"objectId": "Sofa|1", "objectType": "Sofa"}], {"Sofa|1": np.ones((4, 4), bool)},
                          success=ok, error="" if ok else "position not reachable")

    c = StandIn()
    obs = AI2THORRenderer(horizon=10).render_with(c, np.array([[0, 0, 0], [1, 1, 90], [2, 2, 180]]), 0.9)
    assert [o.meta.get("refused", False) for o in obs] == [False, True, False]
    assert obs[1].meta["error"] == "position not reachable" and obs[1].image is None
    assert obs[0].objects == [("Sofa", 1.0)] and obs[2].image.shape == (4, 4, 3)
    assert c.calls[1]["rotation"]["y"] == 90.0 and c.calls[1]["horizon"] == 10


def test_reachable_positions_to_map():
    from envs.ai2thor_renderer import reachable_grid

    pts = [{"x": 0.0, "y": 0.9, "z": 0.0}, {"x": 0.25, "y": 0.9, "z": 0.0}, {"x": 0.25, "y": 0.9, "z": 0.25}]
    g = reachable_grid(pts, 0.25, resolution=0.05, margin=0.0)
    assert g.walkable.sum() == 3 * 25  # three 5 x 5 px squares
    r, c = g.world_to_cell(0.25, 0.25)
    assert g.walkable[r, c]
    with pytest.raises(ValueError, match="no reachable"):
        reachable_grid([], 0.25)


def test_missing_simulator_gives_one_line(monkeypatch):
    import builtins

    real = builtins.__import__

    def fake(name, *a, **k):
        if name.startswith("habitat_sim"):
            raise ImportError("no habitat")
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", fake)
    from envs.habitat_renderer import require_habitat

    with pytest.raises(ImportError, match="conda install habitat-sim") as e:
        require_habitat()
    assert "\n" not in str(e.value)


def test_annotation_import_and_architecthor_env(tmp_path):
    from PIL import Image

    from envs.annotations import import_instance_map
    from envs.architecthor import ArchitecTHOREnv

    img = np.zeros((20, 30, 3), np.uint8)
    img[2:18, 2:14] = (255, 0, 0)
    img[2:18, 16:28] = (0, 0, 255)
    img[8:12, 14:16] = (0, 0, 255)  # a doorway, part of the right room
    Image.fromarray(img).save(tmp_path / "inst.png")
    (tmp_path / "cls.json").write_text(json.dumps({"#ff0000": "kitchen", "#0000ff": "living_room"}))
    import_instance_map(tmp_path / "inst.png", json.loads((tmp_path / "cls.json").read_text()), 0.05, (1.0, 2.0),
                        tmp_path / "ann" / "ArchitecTHOR-Val-00")
    env = ArchitecTHOREnv(str(tmp_path / "ann"))
    assert len(env.house_ids()) == 10 and env.house("ArchitecTHOR-Val-00").data == {"scene": "ArchitecTHOR-Val-00"}
    s = env.scene("ArchitecTHOR-Val-00")
    assert s.grid.resolution == 0.05 and s.grid.origin == (1.0, 2.0)
    assert sorted(s.classes[k] for k in s.instance_classes) == ["kitchen", "living_room"]
    assert s.grid.walkable.sum() == 16 * 12 * 2 + 8
    with pytest.raises(FileNotFoundError, match="no annotation"):
        env.scene("ArchitecTHOR-Test-04")
    (tmp_path / "bad.json").write_text(json.dumps({"#ff0000": "kitchen"}))
    with pytest.raises(ValueError, match="has no class"):
        import_instance_map(tmp_path / "inst.png", {"#ff0000": "kitchen"}, 0.05, (0, 0), tmp_path / "x")


def test_doctor_runs_and_names_what_is_missing(capsys):
    from benchmark.doctor import checks, main

    rows = checks(hab_dataset="/nonexistent/x.json")
    hab = [r for r in rows if r[0] == "ai2thor-hab scenes"][0]
    assert hab[1] == "optional-MISSING" and "/nonexistent/x.json" in hab[2]
    assert all(r[1] == "OK" for r in rows if r[0].startswith("core:"))
    assert main(["--hab-dataset", "/nonexistent/x.json"]) == 0
    assert "core OK" in capsys.readouterr().out


def test_navmesh_topdown_orientation():
    from envs.habitat_renderer import topdown_to_gridmap
    from envs.poses import habitat_to_thor_position

    top = np.zeros((4, 6), bool)
    top[0, 5] = True  # Habitat: x = x_min + 5.5 * res, z_hab = z_min + 0.5 * res
    g = topdown_to_gridmap(top, lower_bound=(2.0, 0.0, -3.0), resolution=0.5)
    x_hab, z_hab = 2.0 + 5.5 * 0.5, -3.0 + 0.5 * 0.5
    x, _, z = habitat_to_thor_position((x_hab, 0.0, z_hab))
    r, c = g.world_to_cell(x, z)
    assert (int(r), int(c)) == (0, 5) and g.walkable[r, c]
    assert g.origin == (2.0, 3.0)


def test_ground_truth_carried_onto_a_reachable_positions_map(shared_houses):
    from envs.ai2thor_renderer import reachable_grid
    from envs.scene import rasterise_house, scene_on_grid

    scene = rasterise_house(shared_houses[0])
    # reachable positions on a 0.25 m grid where the raster is walkable (as AI2-THOR would report)
    rr, cc = np.nonzero(scene.grid.walkable)
    x, z = scene.grid.pixel_to_world(rr, cc)
    pts = {(round(a * 4) / 4, round(b * 4) / 4) for a, b in zip(x, z)}
    grid = reachable_grid([{"x": a, "y": 0.9, "z": b} for a, b in sorted(pts)], 0.25, resolution=0.05)
    moved = scene_on_grid(scene, grid)
    assert moved.grid is grid and moved.instances.shape == grid.shape
    # every room is still there, and each moved cell's room matches the raster at that point
    assert set(np.unique(moved.instances)) - {-1} == set(range(len(scene.room_ids)))
    r, c = np.nonzero(moved.instances >= 0)
    wx, wz = grid.pixel_to_world(r, c)
    sr, sc = scene.grid.world_to_cell(wx, wz)
    assert np.array_equal(scene.rooms[sr, sc], moved.instances[r, c])
    from envs.procthor import ProcTHOREnv

    with pytest.raises(ValueError, match="occupancy"):
        ProcTHOREnv(path=None, occupancy="lidar")
