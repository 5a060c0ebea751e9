"""AI2-THOR renderer: RGB frames and visible objects at our poses, from a ProcTHOR house
dict or an AI2-THOR scene name (e.g. an ArchitecTHOR house).

Needs ``pip install 'roomseg-bench[thor]'`` and a machine that can run the Unity build
(AI2-THOR downloads it for ``commit_id`` on first start; headless GPU machines use
``platform=CloudRendering``, desktops with X can use ``Linux64``). Each pose is a
``TeleportFull`` (camera at ``camera_y`` metres, ``horizon`` degrees down); a teleport the
simulator refuses is recorded (``meta = {"refused": True, "error": ...}``) and skipped.
Visible objects are read from the instance masks: object type and the share of image pixels.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from envs.gridmap import GridMap
from envs.observation import Observation, poses_array
from envs.poses import pose_to_thor_teleport


def require_ai2thor():
    try:
        import ai2thor.controller  # noqa: PLC0415
        import ai2thor.platform  # noqa: F401, PLC0415
    except ImportError:
        raise ImportError("the AI2-THOR renderer needs ai2thor: pip install 'roomseg-bench[thor]'") from None
    return ai2thor


def controller_kwargs(scene, width: int = 224, height: int = 224, fov: float = 90.0, platform: str = "CloudRendering",
                      commit_id: str | None = None, grid_size: float = 0.25,
                      visibility_distance: float = 10.0) -> dict:
    """Keyword arguments of ``ai2thor.controller.Controller`` for ``scene`` (a house dict or
    a scene name), with instance segmentation on. ``commit_id=None`` uses the build the
    installed ai2thor package pins (``ai2thor.build.COMMIT_ID``); set it to reproduce a run."""
    ai2thor = require_ai2thor()
    plat = getattr(ai2thor.platform, platform, None)
    if plat is None:
        raise ValueError(f"unknown AI2-THOR platform {platform!r}; expected CloudRendering, Linux64 or OSXIntel64")
    kw = {"scene": scene, "platform": plat, "width": int(width), "height": int(height), "fieldOfView": float(fov),
          "renderInstanceSegmentation": True, "gridSize": float(grid_size), "snapToGrid": False,
          "visibilityDistance": float(visibility_distance)}
    if commit_id:
        kw["commit_id"] = commit_id
    return kw


def visible_objects(event, min_share: float = 0.0) -> list[tuple[str, float]]:
    """(object type, share of image pixels) per visible object type of an AI2-THOR event,
    from ``event.instance_masks`` and the types in ``event.metadata["objects"]``."""
    types = {o["objectId"]: o["objectType"] for o in event.metadata.get("objects", [])}
    shares: dict[str, float] = {}
    for oid, mask in (event.instance_masks or {}).items():
        m = np.asarray(mask)
        share = float(m.mean()) if m.size else 0.0
        if share <= min_share:
            continue
        t = types.get(oid) or str(oid).split("|")[0]
        shares[t] = shares.get(t, 0.0) + share
    return sorted(shares.items())


def reachable_grid(points: Sequence[dict], grid_size: float, resolution: float = 0.05,
                   margin: float = 0.5) -> GridMap:
    """An occupancy map from AI2-THOR reachable positions: each point marks the square of
    ``grid_size`` metres around it walkable."""
    if not points:
        raise ValueError("no reachable positions")
    xs = np.array([p["x"] for p in points], float)
    zs = np.array([p["z"] for p in points], float)
    x0, z1 = xs.min() - grid_size / 2 - margin, zs.max() + grid_size / 2 + margin
    w = int(np.ceil((xs.max() + grid_size / 2 + margin - x0) / resolution))
    h = int(np.ceil((z1 - (zs.min() - grid_size / 2 - margin)) / resolution))
    walk = np.zeros((h, w), bool)
    half = grid_size / 2
    for x, z in zip(xs, zs):
        c0, c1 = int(np.floor((x - half - x0) / resolution + 1e-9)), int(np.ceil((x + half - x0) / resolution - 1e-9))
        r0, r1 = int(np.floor((z1 - z - half) / resolution + 1e-9)), int(np.ceil((z1 - z + half) / resolution - 1e-9))
        walk[max(r0, 0):r1, max(c0, 0):c1] = True
    return GridMap(walk, resolution, (float(x0), float(z1)))


class AI2THORRenderer:
    """Args: width, height (pixels), fov (degrees), camera_y (metres; None: the house's agent
    height), horizon (degrees, positive looks down), platform, commit_id, grid_size (m)."""

    def __init__(self, width: int = 224, height: int = 224, fov: float = 90.0, camera_y: float | None = None,
                 horizon: float = 0.0, platform: str = "CloudRendering", commit_id: str | None = None,
                 grid_size: float = 0.25):
        self.width, self.height, self.fov = width, height, fov
        self.camera_y, self.horizon = camera_y, horizon
        self.platform, self.commit_id, self.grid_size = platform, commit_id, grid_size
        self._controller = None

    def _scene_of(self, house) -> tuple[object, float]:
        data = house.data
        scene = data.get("scene") if isinstance(data, dict) and "rooms" not in data else data
        y = self.camera_y
        if y is None:
            y = float(((data.get("metadata") or {}).get("agent") or {}).get("position", {}).get("y", 0.95))
        return scene, y

    def start(self, scene):
        """Start (or reset) the controller for ``scene``."""
        require_ai2thor()
        from ai2thor.controller import Controller  # noqa: PLC0415

        kw = controller_kwargs(scene, self.width, self.height, self.fov, self.platform, self.commit_id, self.grid_size)
        if self._controller is None:
            self._controller = Controller(**kw)
        else:
            self._controller.reset(scene=scene)
        return self._controller

    def reachable_positions(self, house) -> list[dict]:
        scene, _ = self._scene_of(house)
        ev = self.start(scene).step(action="GetReachablePositions")
        return list(ev.metadata.get("actionReturn") or [])

    def render_with(self, controller, poses: np.ndarray, camera_y: float) -> list[Observation]:
        """Teleport ``controller`` to each pose and read what it sees (testable with a stand-in)."""
        out = []
        for p in poses_array(poses):
            ev = controller.step(**pose_to_thor_teleport(p, camera_y, self.horizon))
            pose = (float(p[0]), float(p[1]), float(p[2]))
            if not ev.metadata.get("lastActionSuccess", False):
                out.append(Observation(pose=pose, meta={"refused": True,
                                                        "error": str(ev.metadata.get("errorMessage", ""))[:300]}))
                continue
            frame = None if ev.frame is None else np.ascontiguousarray(ev.frame[..., :3], dtype=np.uint8)
            out.append(Observation(pose=pose, image=frame, objects=visible_objects(ev)))
        return out

    def render(self, house, scene, poses: np.ndarray) -> list[Observation]:
        sc, y = self._scene_of(house)
        return self.render_with(self.start(sc), poses, y)

    def close(self) -> None:
        if self._controller is not None:
            self._controller.stop()
            self._controller = None
