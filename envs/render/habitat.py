"""Habitat-Sim renderer for the ArchitecTHOR houses of the ai2thor-hab scene dataset.

Needs habitat-sim (no pip wheel for Linux: ``conda install habitat-sim headless -c
conda-forge -c aihabitat-nightly``, docs/gpu.md) and the ai2thor-hab scenes (Hugging Face ``hssd/ai2thor-hab``;
``scene_dataset`` is its ``ai2thor-hab.scene_dataset_config.json``). Written against
habitat-sim's documented Python API (``SimulatorConfiguration``, ``CameraSensorSpec``,
``agent.AgentConfiguration``, ``AgentState``, ``Agent.set_state``,
``utils.common.quat_from_coeffs``, ``pathfinder.get_topdown_view``); everything that does
not need the simulator process is a pure function tested in ``tests/test_simulators.py``.

One RGB camera, and a semantic camera when ``semantic``, both with the horizontal field of
view ``fov`` (the same number as the other renderers), ``camera_y`` metres above the agent's
base and pitched ``horizon`` degrees down. Our (x, z, yaw) poses become Habitat agent
states with :func:`envs.maps.poses.pose_to_habitat` (``mirror`` says which horizontal axis the
converted dataset mirrored, see :mod:`envs.maps.poses`). With ``refuse_off_navmesh`` a pose whose
base is not on the navmesh is recorded as refused, like a refused AI2-THOR teleport.
Visible objects come from the semantic frame: the ai2thor-hab semantic ids are object
types (``configs/object_semantic_id_mapping.json``, ``{"Bed": 12, ...}``), each listed with
the share of image pixels it covers.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Annotated

import numpy as np

from envs.maps.gridmap import GridMap
from envs.maps.poses import check_mirror, pose_to_habitat, wxyz_to_xyzw
from envs.ranges import CAMERA_FOV, Integer, Share
from envs.render.base import Renderer
from envs.render.observation import Observation, poses_array

INSTALL = ("conda install habitat-sim withbullet headless -c conda-forge -c aihabitat-nightly (a Python 3.10 build; "
           "no pip wheel for Linux)")
DEFAULT_DATASET = "data/ai2thor-hab/ai2thor-hab/ai2thor-hab.scene_dataset_config.json"


def require_habitat():
    """Import habitat_sim or raise a one-line ImportError saying what to install."""
    try:
        import habitat_sim  # noqa: PLC0415
        import habitat_sim.utils.common  # noqa: F401, PLC0415
    except ImportError:
        raise ImportError(f"the Habitat renderer needs habitat-sim: {INSTALL}") from None
    return habitat_sim


def check_dataset(path: str | Path) -> Path:
    """The scene dataset config path, or a one-line FileNotFoundError saying where to get it."""
    p = Path(path).expanduser()
    if not p.is_file():
        raise FileNotFoundError(f"ai2thor-hab scene dataset config not found at {p}: download hssd/ai2thor-hab "
                                "from Hugging Face and set ROOMSEG_HAB_DATASET (or renderer.scene_dataset)")
    return p


def sensor_settings(width: int, height: int, fov: float, camera_y: float, horizon: float = 0.0,
                    semantic: bool = True) -> list[dict]:
    """The camera sensors as plain settings: uuid, type (habitat_sim.SensorType name),
    resolution [H, W] pixels, position [x, y, z] metres relative to the agent base,
    orientation [pitch, yaw, roll] radians (negative pitch looks down), hfov degrees."""
    if int(width) <= 0 or int(height) <= 0 or not 0.0 < float(fov) < 180.0:
        raise ValueError(f"Habitat camera: image size must be positive pixels and fov must be in (0, 180) degrees, "
                         f"got {width} x {height}, {fov}")
    color = {"uuid": "color", "type": "COLOR", "resolution": [int(height), int(width)],
             "position": [0.0, float(camera_y), 0.0], "orientation": [-float(np.deg2rad(horizon)), 0.0, 0.0],
             "hfov": float(fov)}
    return [color, {**color, "uuid": "semantic", "type": "SEMANTIC"}] if semantic else [color]


def topdown_to_gridmap(topdown: np.ndarray, lower_bound: Sequence[float], resolution: float,
                       mirror: str = "z") -> GridMap:
    """Habitat's navmesh top-down view -> our GridMap.

    ``pathfinder.get_topdown_view(resolution, height)`` gives an (H, W) bool array whose
    pixel (0, 0) is at the navmesh's lower bound (Habitat x_min, z_min), columns growing with
    Habitat x and rows with Habitat z. With ``mirror="z"`` Habitat z is our -z, so rows grow
    as our z decreases (our convention) and the origin is (x_min, -z_min). With
    ``mirror="x"`` Habitat x is our -x and Habitat z our z, so both axes are flipped and the
    origin is (-(x_min + W res), z_min + H res)."""
    top = np.asarray(topdown, dtype=bool)
    if top.ndim != 2 or top.size == 0:
        raise ValueError(f"navmesh top-down view must be a non-empty (H, W) array, got shape {top.shape}")
    lb = np.asarray(lower_bound, dtype=float)
    h, w = top.shape
    if check_mirror(mirror) == "z":
        return GridMap(top.copy(), float(resolution), (float(lb[0]), float(-lb[2])))
    return GridMap(np.ascontiguousarray(top[::-1, ::-1]), float(resolution),
                   (float(-(lb[0] + w * resolution)), float(lb[2] + h * resolution)))


def mirror_agreement(topdown: np.ndarray, lower_bound: Sequence[float], resolution: float,
                     points: Sequence[Mapping[str, float]]) -> dict[str, float]:
    """Share of AI2-THOR reachable positions (dicts with x, z metres) that land on the
    walkable navmesh for each mirror convention: the right ``mirror`` is the one near 1."""
    if not points:
        raise ValueError("no reachable positions to compare with the navmesh")
    x = np.array([p["x"] for p in points], float)
    z = np.array([p["z"] for p in points], float)
    out = {}
    for m in ("z", "x"):
        g = topdown_to_gridmap(topdown, lower_bound, resolution, m)
        r, c = g.world_to_cell(x, z)
        out[m] = float(np.mean(g.is_walkable(r, c)))
    return out


def load_semantic_names(scene_dataset: str | Path) -> dict[int, str]:
    """semantic id -> object type from ai2thor-hab's ``configs/object_semantic_id_mapping.json``
    (beside the scene dataset config); {} when the file is absent."""
    p = Path(scene_dataset).expanduser().parent / "configs" / "object_semantic_id_mapping.json"
    if not p.is_file():
        return {}
    mapping = json.loads(p.read_text())
    if not isinstance(mapping, Mapping):
        raise ValueError(f"{p}: expected a JSON object {{object type: semantic id}}")
    return {int(v): str(k) for k, v in mapping.items()}


def semantic_objects(semantic: np.ndarray, names: Mapping[int, str], min_share: float = 0.0) -> list[tuple[str, float]]:
    """(object type, share of image pixels) from a semantic frame (H, W) of ids, for ids that
    ``names`` knows (0 and unknown ids are background/structure); sorted by type."""
    sem = np.asarray(semantic)
    if sem.ndim == 3 and sem.shape[2] == 1:
        sem = sem[..., 0]
    if sem.ndim != 2 or sem.size == 0:
        raise ValueError(f"semantic frame must be (H, W), got shape {sem.shape}")
    ids, counts = np.unique(sem, return_counts=True)
    shares: dict[str, float] = {}
    for i, c in zip(ids.tolist(), counts.tolist()):
        t = names.get(int(i))
        share = c / sem.size
        if t is None or share <= min_share:
            continue
        shares[t] = shares.get(t, 0.0) + share
    return sorted(shares.items())


class HabitatRenderer(Renderer):
    """Renders our poses in Habitat-Sim (see the module docstring).

    Args:
        scene_dataset: path of ``ai2thor-hab.scene_dataset_config.json``.
        width, height: image size in pixels.
        fov: horizontal field of view in degrees (as the other renderers).
        camera_y: camera height above the agent base, metres.
        horizon: camera pitch in degrees, positive looks down.
        floor_y: y of the floor (the agent base) in metres.
        semantic: also render the semantic camera (visible objects).
        mirror: the horizontal axis mirrored between AI2-THOR and the dataset ("z" or "x").
        refuse_off_navmesh: record a pose whose base is off the navmesh as refused.
        gpu_device: GPU index.
        agent_radius, agent_height: metres, for recomputing a navmesh the dataset lacks.
        min_share: an object covering no more than this share of the image is not listed.
    """

    def __init__(self, scene_dataset: str = DEFAULT_DATASET, width: Annotated[int, Integer(1)] = 224,
                 height: Annotated[int, Integer(1)] = 224, fov: Annotated[float, CAMERA_FOV] = 90.0,
                 camera_y: float = 1.5, horizon: float = 0.0, floor_y: float = 0.0, semantic: bool = True,
                 mirror: str = "z", refuse_off_navmesh: bool = True, gpu_device: int = 0,
                 agent_radius: float = 0.2, agent_height: float = 1.5,
                 min_share: Annotated[float, Share()] = 0.0):
        sensor_settings(width, height, fov, camera_y, horizon, semantic)  # validates
        check_mirror(mirror)
        if not -90.0 <= float(horizon) <= 90.0:
            raise ValueError(f"Habitat horizon must be in [-90, 90] degrees (positive looks down), got {horizon}")
        if float(agent_radius) <= 0 or float(agent_height) <= 0:
            raise ValueError(f"agent_radius and agent_height must be positive metres, got {agent_radius}, "
                             f"{agent_height}")
        self.scene_dataset, self.width, self.height, self.fov = str(scene_dataset), int(width), int(height), float(fov)
        self.camera_y, self.horizon, self.floor_y = float(camera_y), float(horizon), float(floor_y)
        self.semantic, self.mirror, self.refuse_off_navmesh = bool(semantic), mirror, bool(refuse_off_navmesh)
        self.gpu_device, self.agent_radius, self.agent_height = int(gpu_device), float(agent_radius), float(agent_height)
        self.min_share = float(min_share)
        self._sim, self._scene, self._names = None, None, None

    def make_config(self, scene_name: str):
        """The ``habitat_sim.Configuration`` for one scene of the dataset."""
        hs = require_habitat()
        sim_cfg = hs.SimulatorConfiguration()
        sim_cfg.scene_dataset_config_file = str(check_dataset(self.scene_dataset))
        sim_cfg.scene_id = scene_name
        sim_cfg.enable_physics = False
        sim_cfg.gpu_device_id = self.gpu_device
        specs = []
        for s in sensor_settings(self.width, self.height, self.fov, self.camera_y, self.horizon, self.semantic):
            spec = hs.CameraSensorSpec()
            spec.uuid = s["uuid"]
            spec.sensor_type = getattr(hs.SensorType, s["type"])
            spec.resolution = s["resolution"]
            spec.position = s["position"]
            spec.orientation = s["orientation"]
            spec.hfov = s["hfov"]
            specs.append(spec)
        agent_cfg = hs.agent.AgentConfiguration()
        agent_cfg.sensor_specifications = specs
        return hs.Configuration(sim_cfg, [agent_cfg])

    def _sim_for(self, name: str):
        if self._sim is None or self._scene != name:
            hs = require_habitat()
            if self._sim is not None:
                self._sim.close()
                self._sim = None
            self._sim, self._scene = hs.Simulator(self.make_config(name)), name
            if not self._sim.pathfinder.is_loaded:  # the dataset ships no navmesh: build one
                settings = hs.NavMeshSettings()
                settings.set_defaults()
                settings.agent_radius, settings.agent_height = self.agent_radius, self.agent_height
                if hasattr(settings, "include_static_objects"):
                    settings.include_static_objects = True
                self._sim.recompute_navmesh(self._sim.pathfinder, settings)
        return self._sim

    def navmesh_grid(self, scene_name: str, resolution: float = 0.05) -> GridMap:
        """The walkable map of a scene in our coordinates: its navmesh seen from above at the
        floor (``floor_y`` metres), ``resolution`` metres per pixel."""
        sim = self._sim_for(scene_name)
        lower, _ = sim.pathfinder.get_bounds()
        top = sim.pathfinder.get_topdown_view(float(resolution), self.floor_y)
        return topdown_to_gridmap(top, lower, resolution, self.mirror)

    def render(self, house, scene, poses: np.ndarray) -> list[Observation]:
        """Observations of ``house`` (a House whose ``data["scene"]`` or id names the scene) at
        ``poses`` (N, 3) [x, z, yaw_deg]; ``scene`` is unused."""
        hs = require_habitat()
        from habitat_sim.utils.common import quat_from_coeffs  # noqa: PLC0415

        name = (house.data.get("scene") if isinstance(house.data, dict) else None) or house.id
        sim = self._sim_for(name)
        if self._names is None:
            self._names = load_semantic_names(self.scene_dataset)
        agent = sim.initialize_agent(0)
        out = []
        for p in poses_array(poses):
            pose = (float(p[0]), float(p[1]), float(p[2]))
            position, q = pose_to_habitat(p, self.floor_y, self.mirror)
            if self.refuse_off_navmesh and sim.pathfinder.is_loaded and not sim.pathfinder.is_navigable(position):
                out.append(Observation(pose=pose, meta={"refused": True, "error": "pose is not on the navmesh"}))
                continue
            state = hs.AgentState()
            state.position = position
            state.rotation = quat_from_coeffs(wxyz_to_xyzw(q))
            agent.set_state(state)
            obs = sim.get_sensor_observations()
            rgb = np.ascontiguousarray(np.asarray(obs["color"])[..., :3], dtype=np.uint8)
            objects = semantic_objects(obs["semantic"], self._names, self.min_share) if "semantic" in obs else []
            out.append(Observation(pose=pose, image=rgb, objects=objects))
        return out

    def close(self) -> None:
        """Close the simulator."""
        if self._sim is not None:
            self._sim.close()
            self._sim, self._scene = None, None
