"""Habitat-Sim renderer for the ArchitecTHOR houses of the ai2thor-hab scene dataset.

Needs habitat-sim (conda: ``conda install habitat-sim -c conda-forge -c aihabitat``; no
Linux wheel on PyPI) and the ai2thor-hab scenes. One RGB camera (and a semantic camera
when ``semantic``) with the same horizontal field of view as the other renderers, at
``camera_y`` metres; our poses are converted with :mod:`envs.poses`.
"""

from __future__ import annotations

import numpy as np

from envs.observation import Observation, poses_array
from envs.poses import thor_to_habitat_position, thor_yaw_to_habitat_quat


def require_habitat():
    try:
        import habitat_sim  # noqa: PLC0415
    except ImportError:
        raise ImportError("the Habitat renderer needs habitat-sim, which has no pip wheel for Linux: "
                          "conda install habitat-sim -c conda-forge -c aihabitat") from None
    return habitat_sim


def sensor_settings(width: int, height: int, fov: float, camera_y: float, semantic: bool) -> list[dict]:
    """The camera sensors as plain settings (uuid, type, resolution [H, W], position, hfov)."""
    out = [{"uuid": "color", "type": "COLOR", "resolution": [int(height), int(width)],
            "position": [0.0, float(camera_y), 0.0], "hfov": float(fov)}]
    if semantic:
        out.append({**out[0], "uuid": "semantic", "type": "SEMANTIC"})
    return out


def topdown_to_gridmap(topdown: np.ndarray, lower_bound, resolution: float):
    """Habitat's navmesh top-down view -> our GridMap.

    ``pathfinder.get_topdown_view(resolution, height)`` gives an (H, W) bool array whose
    pixel (0, 0) is at the navmesh's lower bound (x_min, z_min in Habitat coordinates), rows
    growing with Habitat z. Habitat z is -z in AI2-THOR, so rows grow as our z decreases,
    which is our convention: the origin (top-left corner) is (x_min, -z_min)."""
    from envs.gridmap import GridMap  # noqa: PLC0415

    lb = np.asarray(lower_bound, dtype=float)
    return GridMap(np.asarray(topdown, dtype=bool), float(resolution), (float(lb[0]), float(-lb[2])))


class HabitatRenderer:
    """Args: scene_dataset (path of the ``*.scene_dataset_config.json``), width, height
    (pixels), fov (degrees), camera_y (metres), semantic (also render the semantic sensor)."""

    def __init__(self, scene_dataset: str, width: int = 224, height: int = 224, fov: float = 90.0,
                 camera_y: float = 0.9, semantic: bool = True, gpu_device: int = 0):
        self.scene_dataset, self.width, self.height, self.fov = scene_dataset, width, height, fov
        self.camera_y, self.semantic, self.gpu_device = camera_y, semantic, gpu_device
        self._sim, self._scene = None, None

    def _make_sim(self, scene_name: str):
        hs = require_habitat()
        from pathlib import Path  # noqa: PLC0415

        if not Path(self.scene_dataset).exists():
            raise FileNotFoundError(f"ai2thor-hab scene dataset config not found: {self.scene_dataset}")
        sim_cfg = hs.SimulatorConfiguration()
        sim_cfg.scene_dataset_config_file = self.scene_dataset
        sim_cfg.scene_id = scene_name
        sim_cfg.enable_physics = False
        sim_cfg.gpu_device_id = self.gpu_device
        specs = []
        for s in sensor_settings(self.width, self.height, self.fov, self.camera_y, self.semantic):
            spec = hs.CameraSensorSpec()
            spec.uuid = s["uuid"]
            spec.sensor_type = getattr(hs.SensorType, s["type"])
            spec.resolution = s["resolution"]
            spec.position = s["position"]
            spec.hfov = s["hfov"]
            specs.append(spec)
        agent_cfg = hs.agent.AgentConfiguration()
        agent_cfg.sensor_specifications = specs
        return hs.Simulator(hs.Configuration(sim_cfg, [agent_cfg]))

    def _sim_for(self, name: str):
        if self._sim is None or self._scene != name:
            if self._sim is not None:
                self._sim.close()
            self._sim, self._scene = self._make_sim(name), name
        return self._sim

    def navmesh_grid(self, scene_name: str, resolution: float = 0.05, floor_y: float = 0.0):
        """The walkable map of a scene: its navmesh seen from above at ``floor_y`` metres."""
        sim = self._sim_for(scene_name)
        lower, _ = sim.pathfinder.get_bounds()
        return topdown_to_gridmap(sim.pathfinder.get_topdown_view(resolution, floor_y), lower, resolution)

    def render(self, house, scene, poses: np.ndarray) -> list[Observation]:
        hs = require_habitat()
        name = (house.data.get("scene") if isinstance(house.data, dict) else None) or house.id
        self._sim_for(name)
        agent = self._sim.initialize_agent(0)
        out = []
        for p in poses_array(poses):
            state = hs.AgentState()
            state.position = thor_to_habitat_position(p[0], 0.0, p[1])
            w, x, y, z = thor_yaw_to_habitat_quat(p[2])
            state.rotation = np.quaternion(w, x, y, z)  # numpy-quaternion, a habitat-sim dependency
            agent.set_state(state)
            obs = self._sim.get_sensor_observations()
            rgb = np.ascontiguousarray(obs["color"][..., :3], dtype=np.uint8)
            meta = {}
            if "semantic" in obs:
                ids, counts = np.unique(obs["semantic"], return_counts=True)
                meta["semantic_ids"] = {int(i): float(c) / obs["semantic"].size for i, c in zip(ids, counts)}
            out.append(Observation(pose=(float(p[0]), float(p[1]), float(p[2])), image=rgb, meta=meta))
        return out


def main(argv: list[str] | None = None) -> int:
    """``python -m envs.habitat_renderer navmesh --scene NAME --out walkable.png [--resolution 0.05]``:
    write a scene's navmesh top-down view as an annotation folder's ``walkable.png`` and
    print its origin (the label map must share this grid)."""
    import argparse  # noqa: PLC0415
    import os  # noqa: PLC0415
    from pathlib import Path  # noqa: PLC0415

    from PIL import Image  # noqa: PLC0415

    ap = argparse.ArgumentParser(description="navmesh top-down view of an ai2thor-hab scene")
    sub = ap.add_subparsers(dest="cmd", required=True)
    n = sub.add_parser("navmesh")
    n.add_argument("--scene", required=True)
    n.add_argument("--out", type=Path, required=True)
    n.add_argument("--resolution", type=float, default=0.05, help="metres per pixel")
    n.add_argument("--dataset", default=os.environ.get("ROOMSEG_HAB_DATASET",
                                                       "data/ai2thor-hab/ai2thor-hab.scene_dataset_config.json"))
    a = ap.parse_args(argv)
    g = HabitatRenderer(a.dataset).navmesh_grid(a.scene, a.resolution)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray((g.walkable * 255).astype(np.uint8)).save(a.out)
    print(f"{a.out}: {g.shape[1]} x {g.shape[0]} px at {g.resolution} m/px, origin (x, z) = {g.origin}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
