"""Simulator adapters without the simulator process.

AI2-THOR: the real ``ai2thor.controller.Controller`` runs (its __init__, reset, step) with
only the Unity side replaced: ``find_build`` returns a build that needs no download and
``start`` connects a stand-in server that answers actions with real ``ai2thor.server.Event``
objects (frames and instance-segmentation buffers decoded by ai2thor's own code).
Habitat-Sim (not installable here): the pure parts by hand, and the adapter against a
stand-in module with the documented API surface.
"""

import builtins
import inspect
import json
import sys
import types

import numpy as np
import pytest

from envs.maps.poses import pose_to_habitat, vertical_fov
from envs.world.house import House

# ---------------------------------------------------------------------------- AI2-THOR

W, H = 8, 6
COLOURS = {"Bed|1": [10, 20, 30], "Sofa|2": [40, 50, 60], "Chair|3": [70, 80, 90], "Chair|4": [91, 92, 93],
           "wall|1|0|0": [1, 2, 3]}
OBJECTS = [{"objectId": "Bed|1", "objectType": "Bed", "visible": True},
           {"objectId": "Sofa|2", "objectType": "Sofa", "visible": True},
           {"objectId": "Chair|3", "objectType": "Chair", "visible": True},
           {"objectId": "Chair|4", "objectType": "Chair", "visible": True}]
REACHABLE = [{"x": 0.0, "y": 0.9, "z": 0.0}, {"x": 0.25, "y": 0.9, "z": 0.0}, {"x": 0.5, "y": 0.9, "z": 0.0}]


def segmentation(yaw):
    """(H, W) object id per pixel of the view at ``yaw`` (None = no object)."""
    seg = np.full((H, W), None, dtype=object)
    if yaw == 0:  # bed on the top half, wall below
        seg[: H // 2] = "Bed|1"
        seg[H // 2:] = "wall|1|0|0"
    elif yaw == 90:  # a sofa on all but one pixel
        seg[:] = "Sofa|2"
        seg[0, 0] = None
    else:  # two chairs: 12 + 6 pixels
        seg[:, :2] = "Chair|3"
        seg[:, 7] = "Chair|4"
    return seg


def frame(yaw):
    return np.full((H, W, 3), int(yaw) % 256, np.uint8)


def event(metadata, yaw=None):
    """A real ai2thor Event, with frame and segmentation decoded by ai2thor from Unity-style buffers."""
    from ai2thor.server import Event

    md = {"screenWidth": W, "screenHeight": H, "lastActionSuccess": True, "errorMessage": "", "errorCode": "",
          "objects": [dict(o) for o in OBJECTS], "sceneName": "Procedural", "actionReturn": None,
          "colors": [{"name": k, "color": v} for k, v in COLOURS.items()], **metadata}
    ev = Event(md)
    if yaw is not None:
        seg = segmentation(yaw)
        rgba = np.zeros((H, W, 4), np.uint8)
        rgba[..., 3] = 255
        for k, c in COLOURS.items():
            rgba[seg == k, :3] = c
        ev.add_image(np.flip(frame(yaw), axis=0).tobytes())  # Unity sends rows bottom-up
        ev.add_image_ids(np.flip(rgba, axis=0).tobytes())
    return ev


class StandInUnity:
    """Answers the actions ai2thor's Controller sends, as Unity would for a tiny house."""

    unity_proc = None
    started = True

    def __init__(self, fail=None):
        self.sent = []
        self.stopped = False
        # action -> (errorCode, errorMessage): answer it as failed; "reach_anywhere": True accepts every teleport
        self.fail = {} if fail is None else fail

    def send(self, action):
        self.sent.append(action)

    def receive(self, timeout=None):
        a = self.sent[-1] if self.sent else {"action": "Start"}
        name = a.get("action")
        if name in self.fail and name != "reach_anywhere":
            code, message = self.fail[name]
            return event({"lastAction": name, "lastActionSuccess": False, "errorCode": code, "errorMessage": message})
        if name == "TeleportFull":
            p, yaw = a["position"], a["rotation"]["y"]
            if p["z"] > 50:
                return event({"lastActionSuccess": False, "errorCode": "InvalidArgument",
                              "errorMessage": "position out of the scene bounds"})
            if not self.fail.get("reach_anywhere") and \
                    not any(abs(q["x"] - p["x"]) < 1e-6 and abs(q["z"] - p["z"]) < 1e-6 for q in REACHABLE):
                return event({"lastActionSuccess": False, "errorMessage": f"{p} is not a valid position"})
            return event({"lastAction": name}, yaw=yaw)
        if name == "GetScenesInBuild":
            return event({"lastAction": name, "actionReturn": ["ArchitecTHOR-Val-00", "FloorPlan1_physics"]})
        if name == "GetReachablePositions":
            return event({"lastAction": name, "actionReturn": [dict(q) for q in REACHABLE]})
        return event({"lastAction": name})

    def set_init_params(self, params):
        pass

    def stop(self):
        self.stopped = True


class StandInBuild:
    server_types = ["FIFO", "WSGI"]
    url = None

    def __init__(self, platform):
        self.platform = platform
        self.unlocked = False

    def download(self):
        pass

    def unlock(self):
        self.unlocked = True


@pytest.fixture
def thor(monkeypatch):
    """The real Controller with the Unity side stood in; yields the record of what it was asked."""
    pytest.importorskip("ai2thor.controller")
    from ai2thor.controller import Controller

    seen = {"fail": {}}  # action -> (errorCode, errorMessage) the stand-in answers as failed

    def find_build(self, local_build, commit_id, branch, platform):
        seen["commit_id"], seen["platform"] = commit_id, platform
        seen["build"] = StandInBuild(platform)
        return seen["build"]

    def start(self, port=0, start_unity=True, width=300, height=300, x_display=None, host="127.0.0.1", **kw):
        seen["size"] = (width, height)
        self.server = seen["server"] = StandInUnity(seen["fail"])
        self.last_event = self.server.receive()
        return self.last_event

    monkeypatch.setattr(Controller, "find_build", find_build)
    monkeypatch.setattr(Controller, "start", start)
    return seen


def _house():
    return House("house-1", {"rooms": [{"id": "room|1", "roomType": "Bedroom", "floorPolygon": []}],
                             "metadata": {"agent": {"position": {"x": 0, "y": 0.9, "z": 0}}}})


def test_renderer_through_the_real_controller(thor):
    import ai2thor.platform

    from envs.render.thor import AI2THORRenderer

    r = AI2THORRenderer(width=W, height=H, fov=90, horizon=10, platform="CloudRendering", commit_id="a" * 40)
    poses = np.array([[0.0, 0.0, 0.0], [0.25, 0.0, 90.0], [1.0, 1.0, 0.0], [0.5, 0.0, 180.0], [0.5, 99.0, 0.0]])
    obs = r.render(_house(), None, poses)
    assert thor["commit_id"] == "a" * 40 and thor["platform"] is ai2thor.platform.CloudRendering
    assert thor["size"] == (W, H)
    sent = thor["server"].sent
    init = next(a for a in sent if a["action"] == "Initialize")
    assert init["fieldOfView"] == pytest.approx(vertical_fov(90, W, H)) and init["renderInstanceSegmentation"]
    assert init["gridSize"] == 0.25 and init["snapToGrid"] is False
    assert next(a for a in sent if a["action"] == "CreateHouse")["house"] == _house().data
    tele = [a for a in sent if a["action"] == "TeleportFull"]
    assert len(tele) == 5 and all(a["position"]["y"] == 0.9 and a["horizon"] == 10.0 for a in tele)
    assert [a["rotation"]["y"] for a in tele] == [0.0, 90.0, 0.0, 180.0, 0.0]
    # what came back
    assert [o.meta.get("refused", False) for o in obs] == [False, False, True, False, True]
    assert "not a valid position" in obs[2].meta["error"] and obs[2].image is None
    assert "out of the scene bounds" in obs[4].meta["error"]  # ai2thor raised ValueError: recorded too
    assert obs[0].objects == [("Bed", 0.5)]  # the wall is structure, not an object
    assert obs[1].objects == [("Sofa", pytest.approx(47 / 48))]
    assert obs[3].objects == [("Chair", pytest.approx(18 / 48))]  # two chairs add up
    assert np.array_equal(obs[1].image, frame(90)) and obs[1].image.flags.c_contiguous
    assert obs[0].pose == (0.0, 0.0, 0.0) and obs[4].pose == (0.5, 99.0, 0.0)
    # reachable positions through the same controller, then shut down
    assert r.reachable_positions(_house()) == REACHABLE
    r.close()
    assert thor["server"].stopped and thor["build"].unlocked and r._controller is None


def test_a_scene_name_is_loaded_by_name(thor):
    from envs.render.thor import AI2THORRenderer

    r = AI2THORRenderer(width=W, height=H, agent_y=0.95)
    obs = r.render(House("ArchitecTHOR-Val-00", {"scene": "ArchitecTHOR-Val-00"}), None, np.array([[0.0, 0.0, 90.0]]))
    resets = [a for a in thor["server"].sent if a["action"] == "Reset"]
    assert resets[-1]["sceneName"] == "ArchitecTHOR-Val-00"
    assert not any(a["action"] == "CreateHouse" for a in thor["server"].sent)
    assert obs[0].objects == [("Sofa", pytest.approx(47 / 48))]
    assert [a for a in thor["server"].sent if a["action"] == "TeleportFull"][0]["position"]["y"] == 0.95


def test_a_controller_that_cannot_start_says_so_in_one_line(monkeypatch):
    pytest.importorskip("ai2thor.controller")
    from ai2thor.controller import Controller

    from envs.render.thor import AI2THORRenderer

    def no_build(self, *a, **k):
        raise ValueError("Invalid commit_id: abc - no build exists for arch=Linux platforms=CloudRendering\nmore")

    monkeypatch.setattr(Controller, "find_build", no_build)
    with pytest.raises(RuntimeError, match="AI2-THOR could not start .*Invalid commit_id.*benchmark.commands.doctor") as e:
        AI2THORRenderer(commit_id="abc").render(_house(), None, np.zeros((1, 3)))
    assert "\n" not in str(e.value)


BAD_HOUSE = "Invalid house: object type 'Bed_23' is not in this build"


@pytest.mark.parametrize("code", ["", "InvalidArgument"])  # reported only / raised by ai2thor's step()
def test_a_house_that_does_not_load_fails_with_the_simulators_message(thor, code):
    """ai2thor's reset sends CreateHouse without checking it: the adapter does, at the first
    start (the Controller's own __init__) and at a reset to the next house."""
    from envs.render.thor import AI2THORRenderer, HouseLoadError

    thor["fail"]["CreateHouse"] = (code, BAD_HOUSE)
    r = AI2THORRenderer(width=W, height=H)
    with pytest.raises(HouseLoadError) as e:
        r.render(_house(), None, np.zeros((2, 3)))
    assert str(e.value) == f"house 'house-1': AI2-THOR could not load it (CreateHouse failed): {BAD_HOUSE}"
    assert not any(a["action"] == "TeleportFull" for a in thor["server"].sent)  # nothing rendered
    if code:  # raised inside Controller(): the Unity process it started is stopped, not leaked
        assert thor["server"].stopped and r._controller is None
    else:  # the controller started: it stays for the next house
        assert r._controller is not None and not thor["server"].stopped
    thor["fail"].clear()
    obs = r.render(_house(), None, np.array([[0.0, 0.0, 0.0]]))
    assert obs[0].objects == [("Bed", 0.5)]
    thor["fail"]["CreateHouse"] = (code, BAD_HOUSE)  # the next house fails on reset()
    with pytest.raises(HouseLoadError, match="CreateHouse failed.*Bed_23"):
        r.reachable_positions(House("house-2", _house().data))
    r.close()


def test_a_scene_name_that_does_not_load_fails_too(thor):
    from envs.render.thor import AI2THORRenderer

    r = AI2THORRenderer(width=W, height=H)
    r.render(House("ArchitecTHOR-Val-00", {"scene": "ArchitecTHOR-Val-00"}), None, np.zeros((1, 3)))
    thor["fail"]["Initialize"] = ("", "agentMode 'drone' is not supported")
    with pytest.raises(RuntimeError, match="'ArchitecTHOR-Val-00': AI2-THOR could not load it .*drone") as e:
        r.render(House("ArchitecTHOR-Val-00", {"scene": "ArchitecTHOR-Val-00"}), None, np.zeros((1, 3)))
    assert "\n" not in str(e.value)
    r.close()


def _sweep_config(tmp_path):
    from hydra import compose, initialize_config_dir

    from benchmark.harness.runner import CONF_DIR

    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose("config", overrides=[
            "env=synthetic", "env.n_houses=2", "env.resolution=0.1", "renderer=ai2thor", f"renderer.width={W}",
            f"renderer.height={H}", "classifier=oracle", "aggregator=graph_knn", "postprocess=none",
            f"run.results_dir={tmp_path / 'results'}", "run.progress=false"], return_hydra_config=True)


@pytest.mark.slow
@pytest.mark.parametrize("fail", ["CreateHouse", "TeleportFull"])
def test_a_failed_load_is_a_failed_house_and_no_complete_render(thor, tmp_path, fail):
    """Through the sweep: the house fails with the simulator's message (CreateHouse refused)
    or as all views refused (every teleport refused), and its render folder is never marked
    complete, so the next run renders it again."""
    from benchmark.harness.runner import run

    cfg = _sweep_config(tmp_path)
    choices = {k: str(v) for k, v in cfg.hydra.runtime.choices.items() if not k.startswith("hydra")}
    thor["fail"][fail] = ("", BAD_HOUSE if fail == "CreateHouse" else "not a valid position")
    df = run(cfg, tmp_path / "out", choices)
    assert (df["status"] == "failed").all()
    want = f"AI2-THOR could not load it (CreateHouse failed): {BAD_HOUSE}" if fail == "CreateHouse" else "refused"
    assert all(want in e for e in df["error"]), list(df["error"])
    renders = list((tmp_path / "results" / "cache" / "render").rglob("COMPLETE"))
    assert renders == []


def test_controller_kwargs_match_the_real_signature():
    pytest.importorskip("ai2thor.controller")
    import ai2thor.controller
    import ai2thor.platform

    from envs.render.thor import controller_kwargs

    kw = controller_kwargs({"rooms": []}, width=64, height=48, fov=90, platform="CloudRendering", commit_id="c" * 40,
                           quality="Ultra", gpu_device=0, local_executable_path="/opt/thor/thor.x86_64")
    params = inspect.signature(ai2thor.controller.Controller.__init__).parameters
    named = {k for k in kw if k in params}
    assert named == {"scene", "platform", "width", "height", "commit_id", "quality", "gpu_device",
                     "local_executable_path"}
    assert any(p.kind == p.VAR_KEYWORD for p in params.values())  # the rest go to Unity's Initialize
    assert set(kw) - named == {"fieldOfView", "renderInstanceSegmentation", "gridSize", "snapToGrid",
                               "visibilityDistance"}
    assert kw["platform"] is ai2thor.platform.CloudRendering
    assert kw["fieldOfView"] == pytest.approx(2 * np.rad2deg(np.arctan(48 / 64)))
    assert controller_kwargs("FloorPlan1", width=32, height=32, fov=90)["fieldOfView"] == pytest.approx(90)
    with pytest.raises(ValueError, match="unknown AI2-THOR platform"):
        controller_kwargs("FloorPlan1", platform="Windows95")
    with pytest.raises(ValueError, match="house dict or a scene name"):
        controller_kwargs(3)


def test_platforms_and_build_folder():
    pytest.importorskip("ai2thor.build")
    import ai2thor.build

    from envs.render.thor import resolve_platform, thor_build_dir

    assert resolve_platform("auto", display=":0") == "Linux64"
    assert resolve_platform("auto", display="") == "CloudRendering"
    assert resolve_platform("Linux64", display="") == "Linux64"
    d = thor_build_dir("CloudRendering", "f" * 40)
    assert d.parts[-3:] == (".ai2thor", "releases", "thor-CloudRendering-" + "f" * 40)
    assert thor_build_dir("CloudRendering").name.endswith(ai2thor.build.COMMIT_ID)


def test_renderer_arguments_are_checked():
    from envs.render.thor import AI2THORRenderer

    for bad, match in [({"fov": 180}, "fov"), ({"width": 0}, "image size"), ({"horizon": 120}, "horizon"),
                       ({"platform": "Win"}, "platform"), ({"grid_size": 0}, "grid_size"), ({"min_share": 1}, "min_share")]:
        with pytest.raises(ValueError, match=match):
            AI2THORRenderer(**bad)


def test_visible_objects_options():
    pytest.importorskip("ai2thor.server")
    from envs.render.thor import visible_objects

    ev = event({}, yaw=0)
    assert visible_objects(ev) == [("Bed", 0.5)]
    assert visible_objects(ev, include_structure=True) == [("Bed", 0.5), ("wall", 0.5)]
    assert visible_objects(event({}, yaw=180), min_share=0.2) == [("Chair", 0.25)]  # the 6-pixel chair is dropped
    assert visible_objects(event({})) == []  # no segmentation rendered


def test_reachable_positions_to_map():
    from envs.render.thor import reachable_grid

    pts = [{"x": 0.0, "y": 0.9, "z": 0.0}, {"x": 0.25, "y": 0.9, "z": 0.0}, {"x": 0.25, "y": 0.9, "z": 0.25}]
    g = reachable_grid(pts, 0.25, resolution=0.05, margin=0.0)
    assert g.walkable.sum() == 3 * 25  # three 5 x 5 px squares
    assert g.shape == (10, 10) and g.origin == (-0.125, 0.375)
    assert g.walkable[g.world_to_cell(0.25, 0.25)] and not g.walkable[g.world_to_cell(0.0, 0.25)]
    with pytest.raises(ValueError, match="no reachable"):
        reachable_grid([], 0.25)


def _block_import(monkeypatch, prefix):
    real = builtins.__import__

    def fake(name, *a, **k):
        if name == prefix or name.startswith(prefix + "."):
            raise ImportError(f"no {name}")
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", fake)


@pytest.mark.parametrize("module,func,install", [
    ("habitat_sim", "envs.render.habitat:require_habitat", "conda install habitat-sim"),
    ("ai2thor", "envs.render.thor:require_ai2thor", "pip install 'roomseg-bench[thor]'"),
])
def test_a_missing_simulator_gives_one_line(monkeypatch, module, func, install):
    import importlib

    mod, name = func.split(":")
    f = getattr(importlib.import_module(mod), name)
    _block_import(monkeypatch, module)
    with pytest.raises(ImportError, match="needs") as e:
        f()
    assert install in str(e.value) and "\n" not in str(e.value)


# ---------------------------------------------------------------------------- Habitat-Sim

def test_habitat_sensor_settings_by_hand():
    from envs.render.habitat import sensor_settings

    s = sensor_settings(320, 240, 90.0, 1.5, horizon=30.0, semantic=True)
    assert [x["uuid"] for x in s] == ["color", "semantic"] and [x["type"] for x in s] == ["COLOR", "SEMANTIC"]
    assert s[0]["resolution"] == [240, 320] and s[0]["position"] == [0.0, 1.5, 0.0] and s[0]["hfov"] == 90.0
    assert s[0]["orientation"] == pytest.approx([-np.pi / 6, 0.0, 0.0])  # 30 degrees down
    assert len(sensor_settings(8, 8, 60, 1.0, semantic=False)) == 1
    with pytest.raises(ValueError, match="fov"):
        sensor_settings(8, 8, 0, 1.0)


@pytest.mark.parametrize("mirror", ["z", "x"])
def test_navmesh_topdown_orientation(mirror):
    """A navmesh pixel lands on the map pixel of the same world point, for both mirrors."""
    from envs.maps.poses import habitat_to_thor_position
    from envs.render.habitat import topdown_to_gridmap

    top = np.zeros((4, 6), bool)
    top[0, 5] = True  # Habitat x = x_min + 5.5 res, z = z_min + 0.5 res
    lb, res = (2.0, 0.0, -3.0), 0.5
    g = topdown_to_gridmap(top, lower_bound=lb, resolution=res, mirror=mirror)
    x, _, z = habitat_to_thor_position((lb[0] + 5.5 * res, 0.0, lb[2] + 0.5 * res), mirror)
    r, c = g.world_to_cell(x, z)
    assert g.walkable[r, c] and g.walkable.sum() == 1
    if mirror == "z":  # by hand: rows follow Habitat z = -our z, no flip
        assert (int(r), int(c)) == (0, 5) and g.origin == (2.0, 3.0)
    else:  # Habitat x = -our x, Habitat z = our z: both flipped
        assert (int(r), int(c)) == (3, 0) and g.origin == (-5.0, -1.0)


def test_semantic_objects_and_names(tmp_path):
    from envs.render.habitat import load_semantic_names, semantic_objects

    sem = np.zeros((4, 5), np.int32)
    sem[:2, :] = 12  # 10 px bed
    sem[3, :2] = 7  # 2 px chair
    sem[3, 4] = 99  # unknown id
    names = {12: "Bed", 7: "Chair", 8: "Chair"}
    assert semantic_objects(sem, names) == [("Bed", 0.5), ("Chair", 0.1)]
    assert semantic_objects(sem[..., None], names, min_share=0.2) == [("Bed", 0.5)]
    cfg = tmp_path / "ai2thor-hab" / "ai2thor-hab.scene_dataset_config.json"
    (cfg.parent / "configs").mkdir(parents=True)
    cfg.write_text("{}")
    assert load_semantic_names(cfg) == {}
    (cfg.parent / "configs" / "object_semantic_id_mapping.json").write_text(json.dumps({"Bed": 12, "Chair": 7}))
    assert load_semantic_names(cfg) == {12: "Bed", 7: "Chair"}


def test_missing_dataset_gives_one_line(tmp_path):
    from envs.render.habitat import check_dataset

    with pytest.raises(FileNotFoundError, match="hssd/ai2thor-hab.*ROOMSEG_HAB_DATASET") as e:
        check_dataset(tmp_path / "nope.json")
    assert "\n" not in str(e.value)


def _stand_in_habitat(navigable, recorded):
    """A module with habitat_sim's documented names: configuration objects record what is set."""
    hs = types.ModuleType("habitat_sim")

    class Obj:
        def __init__(self, *a):
            self.args = a

    class SensorType:
        COLOR, SEMANTIC = "COLOR", "SEMANTIC"

    class PathFinder:
        is_loaded = False

        def get_bounds(self):
            return np.array([0.0, 0.0, -2.0]), np.array([2.0, 1.0, 0.0])

        def get_topdown_view(self, res, height):
            recorded["topdown"] = (res, height)
            return np.ones((4, 4), bool)

        def is_navigable(self, p):
            return navigable(p)

    class Agent:
        def set_state(self, state):
            recorded.setdefault("states", []).append((np.array(state.position), state.rotation))

    class Simulator:
        def __init__(self, cfg):
            recorded["config"] = cfg
            self.pathfinder = PathFinder()

        def recompute_navmesh(self, pathfinder, settings):
            recorded["navmesh"] = settings
            pathfinder.is_loaded = True

        def initialize_agent(self, i):
            return Agent()

        def get_sensor_observations(self):
            sem = np.zeros((4, 4, 1), np.int32)
            sem[:2] = 12
            return {"color": np.full((4, 4, 4), 200, np.uint8), "semantic": sem}

        def close(self):
            recorded["closed"] = True

    class NavMeshSettings(Obj):
        def set_defaults(self):
            self.defaults = True

    for name, cls in [("SimulatorConfiguration", Obj), ("CameraSensorSpec", Obj), ("AgentState", Obj),
                      ("NavMeshSettings", NavMeshSettings), ("Simulator", Simulator)]:
        setattr(hs, name, cls)
    hs.SensorType = SensorType
    hs.Configuration = lambda sim_cfg, agents: Obj(sim_cfg, agents)
    hs.agent = types.SimpleNamespace(AgentConfiguration=Obj)
    common = types.ModuleType("habitat_sim.utils.common")
    common.quat_from_coeffs = lambda c: ("quat_xyzw", tuple(float(v) for v in c))
    utils = types.ModuleType("habitat_sim.utils")
    utils.common = common
    hs.utils = utils
    return {"habitat_sim": hs, "habitat_sim.utils": utils, "habitat_sim.utils.common": common}


def test_habitat_renderer_against_a_stand_in(monkeypatch, tmp_path):
    from envs.render.habitat import HabitatRenderer

    cfg = tmp_path / "ai2thor-hab" / "ai2thor-hab.scene_dataset_config.json"
    (cfg.parent / "configs").mkdir(parents=True)
    cfg.write_text("{}")
    (cfg.parent / "configs" / "object_semantic_id_mapping.json").write_text(json.dumps({"Bed": 12}))
    rec = {}
    mods = _stand_in_habitat(lambda p: p[0] < 5.0, rec)
    for k, v in mods.items():
        monkeypatch.setitem(sys.modules, k, v)
    r = HabitatRenderer(str(cfg), width=4, height=4, fov=80, camera_y=1.4, horizon=20, mirror="z")
    poses = np.array([[1.0, 2.0, 90.0], [9.0, 0.0, 0.0]])
    obs = r.render(House("ArchitecTHOR-Val-01", {"scene": "ArchitecTHOR-Val-01"}), None, poses)
    sim_cfg, agents = rec["config"].args
    assert sim_cfg.scene_id == "ArchitecTHOR-Val-01" and sim_cfg.scene_dataset_config_file == str(cfg)
    specs = agents[0].sensor_specifications
    assert [s.uuid for s in specs] == ["color", "semantic"] and specs[1].sensor_type == "SEMANTIC"
    assert specs[0].hfov == 80 and specs[0].resolution == [4, 4] and specs[0].position == [0.0, 1.4, 0.0]
    assert specs[0].orientation == pytest.approx([-np.deg2rad(20), 0, 0])
    assert rec["navmesh"].defaults and rec["navmesh"].agent_radius == 0.2  # the dataset had no navmesh
    # pose 0 set as Habitat state; pose 1 is off the navmesh and refused
    (pos, rot), = rec["states"]
    want_pos, want_q = pose_to_habitat(poses[0], 0.0, "z")
    assert np.allclose(pos, want_pos) and pos.tolist() == [1.0, 0.0, -2.0]
    assert rot[0] == "quat_xyzw" and np.allclose(rot[1], [want_q[1], want_q[2], want_q[3], want_q[0]])
    assert obs[1].meta == {"refused": True, "error": "pose is not on the navmesh"} and obs[1].image is None
    assert obs[0].image.shape == (4, 4, 3) and obs[0].objects == [("Bed", 0.5)]
    g = r.navmesh_grid("ArchitecTHOR-Val-01", resolution=0.5)
    assert rec["topdown"] == (0.5, 0.0) and g.origin == (0.0, 2.0) and g.walkable.all()
    r.close()
    assert rec["closed"]


def test_habitat_arguments_are_checked():
    from envs.render.habitat import HabitatRenderer

    for bad, match in [({"fov": 0}, "fov"), ({"mirror": "y"}, "mirror"), ({"horizon": -100}, "horizon"),
                       ({"agent_radius": 0}, "agent_radius")]:
        with pytest.raises(ValueError, match=match):
            HabitatRenderer("x.json", **bad)


# ---------------------------------------------------------------------------- doctor

def test_doctor_names_what_is_missing(capsys, tmp_path):
    from benchmark.commands.doctor import checks, main

    rows = {r[0]: r for r in checks(hab_dataset=str(tmp_path / "x.json"), annotations=str(tmp_path),
                                    shared=str(tmp_path))}
    assert rows["ai2thor-hab scenes"][1] == "optional" and str(tmp_path / "x.json") in rows["ai2thor-hab scenes"][2]
    assert rows["ArchitecTHOR annotations"][2].startswith(f"0/10 houses under {tmp_path}")
    assert rows["shared ProcTHOR/SeLRoS data"][1] == "optional"
    assert all(r[1] == "OK" for k, r in rows.items() if k.startswith("core:"))
    for k, r in rows.items():
        if r[1] != "OK":
            assert r[2] and "\n" not in r[2], k  # one line of what to do
    (tmp_path / "ArchitecTHOR-Val-00").mkdir()
    (tmp_path / "ArchitecTHOR-Val-00" / "labels.png").write_bytes(b"")
    (tmp_path / "x.json").write_text("{}")
    rows = {r[0]: r for r in checks(hab_dataset=str(tmp_path / "x.json"), annotations=str(tmp_path))}
    assert rows["ai2thor-hab scenes"][1] == "OK" and rows["ArchitecTHOR annotations"][2].startswith("1/10")
    assert main(["--hab-dataset", str(tmp_path / "x.json")]) == 0
    out = capsys.readouterr().out
    assert "core OK" in out and "ai2thor-hab scenes" in out


def test_doctor_fails_when_a_core_package_is_missing(monkeypatch, capsys):
    import benchmark.commands.doctor as doctor

    monkeypatch.setattr(doctor, "CORE", doctor.CORE + ("no_such_package_xyz",))
    assert doctor.main([]) == 1
    assert "1 core piece(s) missing: core: no_such_package_xyz" in capsys.readouterr().out


def test_ground_truth_carried_onto_a_reachable_positions_map(shared_houses):
    from envs.datasets.procthor import ProcTHOREnv
    from envs.maps.scene import rasterise_house, scene_on_grid
    from envs.render.thor import reachable_grid

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
    with pytest.raises(ValueError, match="occupancy"):
        ProcTHOREnv(path=None, occupancy="lidar")


def test_procthor_occupancy_from_the_renderer(thor, procthor_file):
    """env.occupancy=ai2thor asks the (stood-in) simulator for reachable positions."""
    from envs.datasets.procthor import ProcTHOREnv

    env = ProcTHOREnv(path=str(procthor_file), stop=1, occupancy="ai2thor", thor={"width": W, "height": H})
    s = env.scene(env.house_ids()[0])
    assert s.grid.walkable.sum() == 3 * 25 and s.grid.resolution == 0.05
    assert any(a["action"] == "GetReachablePositions" for a in thor["server"].sent)


def test_mirror_agreement_finds_the_convention():
    """An L-shaped navmesh built with mirror=z: AI2-THOR points agree with z, not with x."""
    from envs.render.habitat import mirror_agreement

    res, lb = 0.1, (0.0, 0.0, -4.0)  # Habitat x in [0, 3], z in [-4, 0]
    top = np.zeros((40, 30), bool)
    top[:, :10] = True  # a strip along Habitat x in [0, 1]
    top[30:, :] = True  # and along Habitat z in [-1, 0]
    rows, cols = np.nonzero(top)
    hab_x, hab_z = lb[0] + (cols + 0.5) * res, lb[2] + (rows + 0.5) * res
    pts = [{"x": float(a), "y": 0.9, "z": float(-b)} for a, b in zip(hab_x[::7], hab_z[::7])]  # z mirrored
    share = mirror_agreement(top, lb, res, pts)
    assert share["z"] == 1.0 and share["x"] < 0.5
    with pytest.raises(ValueError, match="no reachable"):
        mirror_agreement(top, lb, res, [])


def test_reachable_command_through_the_real_controller(thor, tmp_path, capsys):
    from benchmark.commands.thor import main

    assert main(["reachable", "--scene", "ArchitecTHOR-Val-00", "--out", str(tmp_path / "p.json")]) == 0
    assert json.loads((tmp_path / "p.json").read_text()) == REACHABLE
    assert thor["server"].stopped and "3 reachable positions of ArchitecTHOR-Val-00" in capsys.readouterr().out


# ---------------------------------------------------------------------------- gpu-check

@pytest.mark.slow
def test_gpu_check_without_a_gpu_prints_every_line_skipped(monkeypatch, capsys):
    """This machine's situation, made certain: no CUDA, no Vulkan, no X display, no
    habitat-sim. Every check is a 'skipped: why' line with a time, the table is printed,
    nothing raises, and the exit status says the required checks did not pass."""
    torch = pytest.importorskip("torch")
    import ctypes.util

    from benchmark.commands import gpu_check

    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    monkeypatch.delenv("DISPLAY", raising=False)
    _block_import(monkeypatch, "habitat_sim")
    assert gpu_check.main([]) == 1
    out = capsys.readouterr().out
    rows = {line.split("  ")[0].strip(): line for line in out.splitlines()[2:10]}
    assert " pass: core packages import" in rows.pop("roomseg-bench installed")
    assert list(rows) == ["torch + CUDA", "ai2thor render", "habitat-sim scene (optional)", "classifier cnn",
                          "classifier dinov2", "classifier vlm", "end to end (1 house, 2 aggregators)"]
    assert all(" skipped: " in line for line in rows.values()), out
    assert "no CUDA GPU visible to torch" in rows["torch + CUDA"]
    assert "no Vulkan library for CloudRendering" in rows["ai2thor render"]
    assert "conda install habitat-sim" in rows["habitat-sim scene (optional)"]
    assert "needs the CUDA check to pass" in rows["classifier vlm"]
    assert "needs the ai2thor check to pass" in rows["end to end (1 house, 2 aggregators)"]
    assert "Traceback" not in out and "1 passed, 0 failed, 7 skipped; required and not passed: torch + CUDA" in out


def test_gpu_check_runs_on_a_bare_python(tmp_path):
    """The first step on a bare workstation: the module needs only the standard library, so
    a Python without the project's packages still prints the table and says what to install."""
    import subprocess

    from benchmark.commands import gpu_check

    code = ("import builtins, sys\n"
            "real = builtins.__import__\n"
            "def no(name, *a, **k):\n"
            "    if name.split('.')[0] in {'numpy', 'scipy', 'cv2', 'PIL', 'shapely', 'pandas', 'hydra', 'omegaconf',"
            " 'procthor', 'torch', 'ai2thor', 'habitat_sim'}: raise ImportError('No module named ' + repr(name))\n"
            "    return real(name, *a, **k)\n"
            "builtins.__import__ = no\n"
            "from benchmark.commands.maintainer.gpu_check import main\n"
            "sys.exit(main([]))\n")
    root = inspect.getfile(gpu_check).rsplit("/benchmark/", 1)[0]
    p = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, timeout=120)
    assert p.returncode == 1 and "Traceback" not in p.stdout + p.stderr, p.stderr
    assert "roomseg-bench installed" in p.stdout and "skipped: not installed: numpy, scipy" in p.stdout
    assert "ai2thor render                           0.0  skipped: needs the roomseg-bench installed check" in p.stdout


def test_gpu_check_failures_are_one_line_and_the_exit_status_follows_required_checks(monkeypatch, capsys):
    from benchmark.commands import gpu_check

    def boom(ctx):
        raise RuntimeError("CUDA error: out of memory\nCUDA kernel errors might be asynchronously reported")

    def skip(ctx):
        raise gpu_check.Skip("habitat-sim is not installed")

    items = [("first", True, lambda ctx: "fine"), ("second", True, boom), ("third", False, skip),
             ("fourth", True, lambda ctx: "still runs")]
    monkeypatch.setattr(gpu_check, "checks", lambda: items)
    assert gpu_check.main([]) == 1
    out = capsys.readouterr().out
    assert "FAIL: RuntimeError: CUDA error: out of memory" in out and "asynchronously" not in out
    assert "third (optional)" in out and "skipped: habitat-sim is not installed" in out
    assert "pass: still runs" in out and "2 passed, 1 failed, 1 skipped; required and not passed: second" in out
    monkeypatch.setattr(gpu_check, "checks", lambda: [items[0], items[2]])
    assert gpu_check.main([]) == 0  # an optional check may be skipped
    assert "every required check passed" in capsys.readouterr().out


def test_gpu_check_renders_one_view_through_the_real_controller(thor, monkeypatch):
    """The ai2thor check with the Unity side stood in: one house, one view at the agent start,
    RGB + visible objects handed on to the classifier checks (skipped here: no CUDA)."""
    from benchmark.commands import gpu_check

    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.setattr(gpu_check, "_house_source", lambda ctx: (_house(), "a test house"))
    ctx = gpu_check.Context(platform="Linux64", commit_id="b" * 40, installed=True)
    rows = gpu_check.run_checks(ctx, [("ai2thor render", True, gpu_check.check_ai2thor),
                                      ("classifier vlm", True, gpu_check.classifier_check("vlm"))])
    assert rows[0].status == "pass", rows[0].detail
    assert rows[0].detail == f"build {'b' * 12} (Linux64), house house-1 from a test house: RGB {W}x{H}, " \
                             "1 visible object types"
    assert thor["commit_id"] == "b" * 40 and thor["server"].stopped
    assert ctx.view.shape == (H, W, 3) and rows[1].status == "skipped"
    thor["fail"]["CreateHouse"] = ("", BAD_HOUSE)  # a build that does not match the house: one FAIL line
    row, = gpu_check.run_checks(gpu_check.Context(platform="Linux64", installed=True),
                                [("ai2thor render", True, gpu_check.check_ai2thor)])
    assert row.status == "FAIL" and row.detail == f"HouseLoadError: house 'house-1': AI2-THOR could not load it " \
                                                  f"(CreateHouse failed): {BAD_HOUSE}"


@pytest.mark.slow
def test_gpu_check_end_to_end_through_the_stand_in(thor, monkeypatch, tmp_path, procthor_file):
    """The last check on a shared ProcTHOR house: the render check, a classifier check with a
    tiny CNN checkpoint on the CPU, then the runner with both aggregators; one line of
    scores."""
    torch = pytest.importorskip("torch")
    from benchmark.classifiers.cnn import build_resnet
    from benchmark.classifiers.torch_common import save_checkpoint
    from benchmark.commands import gpu_check

    classes = ["balcony", "bathroom", "bedroom", "corridor", "dining_room", "kitchen", "living_room"]
    torch.manual_seed(0)
    save_checkpoint(tmp_path / "cnn.pt", build_resnet("resnet18", 7, pretrained=False), classes)
    thor["fail"]["reach_anywhere"] = True
    monkeypatch.setenv("DISPLAY", ":0")
    cnn = [f"checkpoint={tmp_path / 'cnn.pt'}", "arch=resnet18", "pretrained=false", "image_size=32"]
    ctx = gpu_check.Context(house_file=str(procthor_file), platform="Linux64", out=tmp_path / "e2e", device="cpu",
                            classifier_overrides={"cnn": cnn}, installed=True)
    rows = gpu_check.run_checks(ctx, [("ai2thor render", True, gpu_check.check_ai2thor),
                                      ("classifier cnn", True, gpu_check.classifier_check("cnn")),
                                      ("end to end", True, gpu_check.check_end_to_end)])
    assert [r.status for r in rows] == ["pass", "pass", "pass"], [r.detail for r in rows]
    assert rows[1].detail.startswith("cnn: the view is ")
    assert rows[2].detail.startswith("1 house, cnn: graph_knn IoU ") and "; vision_cone IoU " in rows[2].detail
    assert list((tmp_path / "e2e").rglob("metrics.csv"))
