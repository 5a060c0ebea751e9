"""AI2-THOR renderer: RGB frames and visible objects at our poses, from a ProcTHOR house
dict or an AI2-THOR scene name (e.g. ``ArchitecTHOR-Val-00``).

Needs ``pip install 'roomseg-bench[thor]'`` and a machine that can run the Unity build:
AI2-THOR downloads the build for ``commit_id`` into ``~/.ai2thor/releases/`` on first start
(or uses one copied there from another machine). Headless GPU machines use
``platform=CloudRendering`` (Vulkan); desktops with an X display can use ``Linux64``;
``auto`` picks Linux64 when ``$DISPLAY`` is set, else CloudRendering.

Loading a house is checked: ai2thor's ``Controller.reset`` sends ``CreateHouse`` (ProcTHOR)
or ``Reset`` + ``Initialize`` (a scene name) without raising when Unity reports a failure,
so after every load the last event's ``lastActionSuccess`` is read, and a refused load (or
one ai2thor raised for) fails that house with :class:`HouseLoadError`, whose one-line
message carries the simulator's own ``errorMessage``. Nothing is rendered for it, so no
render cache is written (and a render in which every view was refused is never marked
complete either, see :mod:`envs.render.cache`).

Each pose is one ``TeleportFull`` (agent at ``agent_y`` metres, ``horizon`` degrees down,
standing). A teleport the simulator refuses (unreachable, inside an object, bad argument)
is recorded as ``Observation(meta={"refused": True, "error": ...})`` with no image and the
renderer goes on; the pipeline keeps refused views in the render cache and leaves them out
of classification and aggregation. Visible objects come from the instance masks: each
simulated object (``event.metadata["objects"]``) seen, by ``objectType``, with the share of
image pixels it covers (walls, floors and ceilings are structure, not objects, and are
left out unless ``include_structure``).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Annotated

import numpy as np

from envs.maps.gridmap import GridMap
from envs.maps.poses import pose_to_thor_teleport, vertical_fov
from envs.ranges import CAMERA_FOV, Integer, Positive, Share
from envs.render.base import Renderer
from envs.render.observation import Observation, poses_array

#: Platform names accepted by :class:`AI2THORRenderer` ("auto": Linux64 with an X display, else CloudRendering).
PLATFORMS = ("auto", "CloudRendering", "Linux64", "OSXIntel64")
INSTALL = "pip install 'roomseg-bench[thor]'"


def require_ai2thor():
    """Import ai2thor (controller, platform, build) or raise a one-line ImportError saying what to install."""
    try:
        import ai2thor.build  # noqa: F401, PLC0415
        import ai2thor.controller  # noqa: F401, PLC0415
        import ai2thor.platform  # noqa: F401, PLC0415
    except ImportError:
        raise ImportError(f"the AI2-THOR renderer needs the ai2thor package: {INSTALL}") from None
    import ai2thor  # noqa: PLC0415

    return ai2thor


def resolve_platform(name: str, display: str | None = None) -> str:
    """Platform name to use: ``auto`` becomes Linux64 when an X display is set, else CloudRendering."""
    if name not in PLATFORMS:
        raise ValueError(f"unknown AI2-THOR platform {name!r}; expected one of {PLATFORMS}")
    if name != "auto":
        return name
    display = os.environ.get("DISPLAY") if display is None else display
    return "Linux64" if display else "CloudRendering"


def default_commit_id() -> str | None:
    """The Unity build the installed ai2thor package pins (``ai2thor.build.COMMIT_ID``)."""
    return require_ai2thor().build.COMMIT_ID


def thor_build_dir(platform: str = "CloudRendering", commit_id: str | None = None) -> Path:
    """Where ai2thor keeps (or will download) the Unity build of ``commit_id`` for ``platform``:
    ``~/.ai2thor/releases/thor-<platform>-<commit_id>``."""
    ai2thor = require_ai2thor()
    plat = resolve_platform(platform)
    commit = commit_id or ai2thor.build.COMMIT_ID
    return Path.home() / ".ai2thor" / "releases" / ai2thor.build.build_name(plat, commit)


def controller_kwargs(scene, width: int = 224, height: int = 224, fov: float = 90.0, platform: str = "CloudRendering",
                      commit_id: str | None = None, grid_size: float = 0.25, visibility_distance: float = 10.0,
                      quality: str | None = None, gpu_device: int | None = None,
                      local_executable_path: str | None = None) -> dict:
    """Keyword arguments of ``ai2thor.controller.Controller`` for ``scene`` (a ProcTHOR house
    dict or a scene name), with instance segmentation on. ``commit_id=None`` uses the build
    the installed ai2thor package pins; set it to reproduce a run. Unity initialisation
    parameters (fieldOfView, gridSize, ...) go through the Controller's ``**kwargs``.
    ``fov`` is the horizontal field of view in degrees, as for every renderer here; Unity's
    ``fieldOfView`` is the vertical one, so it is converted for non-square images."""
    ai2thor = require_ai2thor()
    plat = ai2thor.platform.STR_PLATFORM_MAP[resolve_platform(platform)]
    if not (isinstance(scene, dict) or (isinstance(scene, str) and scene)):
        raise ValueError(f"AI2-THOR scene must be a ProcTHOR house dict or a scene name, got {type(scene).__name__}")
    kw = {"scene": scene, "platform": plat, "width": int(width), "height": int(height),
          "fieldOfView": vertical_fov(float(fov), int(width), int(height)), "renderInstanceSegmentation": True,
          "gridSize": float(grid_size), "snapToGrid": False, "visibilityDistance": float(visibility_distance)}
    if commit_id:
        kw["commit_id"] = str(commit_id)
    if quality:
        kw["quality"] = quality
    if gpu_device is not None:
        kw["gpu_device"] = int(gpu_device)
    if local_executable_path:
        kw["local_executable_path"] = str(local_executable_path)
    return kw


class HouseLoadError(RuntimeError):
    """The simulator refused to load a house or scene; the message is one line with the
    simulator's own ``errorMessage``."""

    def __init__(self, name: str, action: str, message: str):
        self.house, self.action, self.error = str(name), str(action), str(message)
        super().__init__(f"house {self.house!r}: AI2-THOR could not load it ({self.action} failed): "
                         f"{self.error or 'no error message from the simulator'}")


def _first_line(e) -> str:
    return (str(e).strip().splitlines() or [type(e).__name__])[0][:300]


def _stop_quietly(controller) -> None:
    try:
        if getattr(controller, "server", None) is not None:
            controller.stop()
    except Exception:  # noqa: BLE001  the process is going away either way
        pass


def check_loaded(controller, name: str) -> None:
    """Raise :class:`HouseLoadError` unless the controller's last event (the one of the scene
    load: ``CreateHouse`` for a ProcTHOR house, ``Initialize`` after ``Reset`` for a scene
    name) reports ``lastActionSuccess``. ai2thor's ``Controller.reset`` sends ``CreateHouse``
    without checking it, so a build that does not match the houses would otherwise go
    unnoticed until every teleport is refused."""
    ev = getattr(controller, "last_event", None)
    md = getattr(ev, "metadata", None) or {}
    if not md.get("lastActionSuccess", False):
        raise HouseLoadError(name, md.get("lastAction") or "scene load", str(md.get("errorMessage") or "").strip()[:300])


def visible_objects(event, min_share: float = 0.0, include_structure: bool = False) -> list[tuple[str, float]]:
    """(object type, share of image pixels) per visible object type of an AI2-THOR event, sorted by type.

    Reads ``event.instance_masks`` (object id -> (H, W) bool) and the types in
    ``event.metadata["objects"]``; an instance whose share is not above ``min_share`` is
    dropped. Ids that are not simulated objects (walls, floors, ceilings) count only with
    ``include_structure``, typed by their id's prefix (``"wall|2|..."`` -> ``"wall"``)."""
    types = {o["objectId"]: o["objectType"] for o in (event.metadata.get("objects") or [])}
    masks = event.instance_masks if event.instance_masks is not None else {}
    shares: dict[str, float] = {}
    for oid, mask in masks.items():
        t = types.get(oid)
        if t is None:
            if not include_structure:
                continue
            t = str(oid).split("|")[0]
        m = np.asarray(mask)
        share = float(np.count_nonzero(m)) / m.size if m.size else 0.0
        if share <= min_share:
            continue
        shares[t] = shares.get(t, 0.0) + share
    return sorted(shares.items())


def reachable_grid(points: Sequence[dict], grid_size: float, resolution: float = 0.05,
                   margin: float = 0.5) -> GridMap:
    """An occupancy map from AI2-THOR reachable positions (dicts with x, z in metres): each
    point marks the square of ``grid_size`` metres around it walkable; ``margin`` metres of
    border; ``resolution`` metres per pixel."""
    if not points:
        raise ValueError("no reachable positions")
    if grid_size <= 0 or resolution <= 0:
        raise ValueError(f"grid_size and resolution must be positive metres, got {grid_size}, {resolution}")
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


class AI2THORRenderer(Renderer):
    """Renders our poses in AI2-THOR (see the module docstring).

    Args:
        width, height: image size in pixels.
        fov: horizontal field of view in degrees, (0, 180) (passed to Unity as the vertical one).
        agent_y: the agent's y in metres for ``TeleportFull`` (AI2-THOR puts the camera
            above it, about 1.5 m above the floor standing); None: the house's
            ``metadata.agent.position.y``, else 0.95.
        horizon: camera pitch in degrees, positive looks down, in [-90, 90].
        platform: auto | CloudRendering | Linux64 | OSXIntel64.
        commit_id: the Unity build; None: the one the installed ai2thor pins.
        grid_size: metres, AI2-THOR's grid for reachable positions.
        visibility_distance: metres.
        quality: AI2-THOR quality setting name, None for its default.
        gpu_device: GPU index for CloudRendering, None for the default.
        local_executable_path: a Unity build executable of your own (no download; ai2thor's
            ExternalBuild runs it as Linux64, so it needs an X display).
        min_share: an object covering no more than this share of the image is not listed.
    """

    def __init__(self, width: Annotated[int, Integer(1)] = 224, height: Annotated[int, Integer(1)] = 224,
                 fov: Annotated[float, CAMERA_FOV] = 90.0, agent_y: float | None = None, horizon: float = 0.0,
                 platform: str = "CloudRendering", commit_id: str | None = None,
                 grid_size: Annotated[float, Positive()] = 0.25, visibility_distance: float = 10.0,
                 quality: str | None = None, gpu_device: int | None = None,
                 local_executable_path: str | None = None, min_share: Annotated[float, Share()] = 0.0):
        if int(width) <= 0 or int(height) <= 0:
            raise ValueError(f"AI2-THOR image size must be positive pixels, got {width} x {height}")
        if not 0.0 < float(fov) < 180.0:
            raise ValueError(f"AI2-THOR fov must be in (0, 180) degrees, got {fov}")
        if not -90.0 <= float(horizon) <= 90.0:
            raise ValueError(f"AI2-THOR horizon must be in [-90, 90] degrees (positive looks down), got {horizon}")
        if float(grid_size) <= 0 or float(visibility_distance) <= 0:
            raise ValueError(f"grid_size and visibility_distance must be positive metres, got {grid_size}, "
                             f"{visibility_distance}")
        if not 0.0 <= float(min_share) < 1.0:
            raise ValueError(f"min_share must be in [0, 1), got {min_share}")
        resolve_platform(platform)
        self.width, self.height, self.fov = int(width), int(height), float(fov)
        self.agent_y, self.horizon = agent_y, float(horizon)
        self.platform, self.commit_id, self.grid_size = platform, commit_id, float(grid_size)
        self.visibility_distance, self.quality, self.gpu_device = float(visibility_distance), quality, gpu_device
        self.local_executable_path, self.min_share = local_executable_path, float(min_share)
        self._controller = None

    def scene_of(self, house) -> tuple[object, float]:
        """(what the Controller loads, agent y in metres) for a House: its dict when it has
        rooms (ProcTHOR), else ``data["scene"]`` (a scene name, e.g. ArchitecTHOR), else its id."""
        data = house.data if isinstance(house.data, dict) else {}
        scene = data if "rooms" in data else (data.get("scene") or house.id)
        y = self.agent_y
        if y is None:
            y = float(((data.get("metadata") or {}).get("agent") or {}).get("position", {}).get("y", 0.95))
        return scene, float(y)

    def controller_kwargs(self, scene) -> dict:
        """The Controller keyword arguments this renderer starts with for ``scene``."""
        return controller_kwargs(scene, self.width, self.height, self.fov, self.platform, self.commit_id,
                                 self.grid_size, self.visibility_distance, self.quality, self.gpu_device,
                                 self.local_executable_path)

    def start(self, scene, name: str | None = None):
        """Start the controller for ``scene`` (or reset the running one to it) and check that
        the scene loaded. ``name`` names the house in errors (default: the scene name or
        ``"house"``).

        Returns:
            the started ``ai2thor.controller.Controller``, with ``scene`` loaded.

        Raises:
            RuntimeError: the Unity process could not start (one line, pointing at the doctor).
            HouseLoadError: the simulator refused the scene (``Reset``/``Initialize``/
                ``CreateHouse`` reported ``lastActionSuccess`` false or raised); the message
                carries the simulator's own ``errorMessage``. The controller stays usable for
                the next house when it had started before; a first start that fails is stopped.
        """
        require_ai2thor()
        from ai2thor.controller import Controller  # noqa: PLC0415

        what = name or (scene if isinstance(scene, str) else "house")
        if self._controller is not None:
            try:
                self._controller.reset(scene=scene)
            except (ValueError, RuntimeError) as e:  # ai2thor raises for InvalidArgument-style failures
                raise HouseLoadError(what, self._last_action(self._controller), _first_line(e)) from None
            check_loaded(self._controller, what)
            return self._controller
        kw = self.controller_kwargs(scene)
        # __init__ called on our own instance so that a Unity process started before a
        # failing scene load can still be stopped (Controller() would lose the reference).
        controller = Controller.__new__(Controller)
        try:
            controller.__init__(**kw)
        except Exception as e:  # download, Vulkan/X display, build lookup, or the first scene load
            ev = getattr(controller, "last_event", None)
            started = getattr(controller, "server", None) is not None and ev is not None
            _stop_quietly(controller)
            if started and not ev.metadata.get("lastActionSuccess", True):
                raise HouseLoadError(what, self._last_action(controller), _first_line(e)) from None
            raise RuntimeError(f"AI2-THOR could not start (platform {resolve_platform(self.platform)}, build "
                               f"{self.commit_id or 'pinned by ai2thor'}): {_first_line(e)}; run "
                               "python -m benchmark.commands.doctor") from e
        self._controller = controller
        check_loaded(controller, what)
        return controller

    @staticmethod
    def _last_action(controller) -> str:
        ev = getattr(controller, "last_event", None)
        return str((ev.metadata.get("lastAction") if ev is not None else None) or "scene load")

    def reachable_positions(self, house) -> list[dict]:
        """AI2-THOR's reachable positions (dicts with x, y, z metres) of a house."""
        scene, _ = self.scene_of(house)
        ev = self.start(scene, house.id).step(action="GetReachablePositions")
        if not ev.metadata.get("lastActionSuccess", False):
            raise RuntimeError(f"house {house.id!r}: GetReachablePositions failed: {ev.metadata.get('errorMessage')}")
        return list(ev.metadata.get("actionReturn") or [])

    def render_with(self, controller, poses: np.ndarray, agent_y: float) -> list[Observation]:
        """Teleport ``controller`` (a started ``ai2thor.controller.Controller``) to each pose
        (N, 3) and read what it sees; refused teleports are recorded and skipped."""
        out = []
        for p in poses_array(poses):
            pose = (float(p[0]), float(p[1]), float(p[2]))
            try:
                ev = controller.step(**pose_to_thor_teleport(p, agent_y, self.horizon))
            except ValueError as e:  # ai2thor raises for InvalidArgument-style failures
                out.append(Observation(pose=pose, meta={"refused": True, "error": str(e).strip()[:300]}))
                continue
            if not ev.metadata.get("lastActionSuccess", False):
                out.append(Observation(pose=pose, meta={"refused": True,
                                                        "error": str(ev.metadata.get("errorMessage", ""))[:300]}))
                continue
            frame = None if ev.frame is None else np.ascontiguousarray(ev.frame[..., :3], dtype=np.uint8)
            out.append(Observation(pose=pose, image=frame, objects=visible_objects(ev, self.min_share)))
        return out

    def render(self, house, scene, poses: np.ndarray) -> list[Observation]:
        """Observations of ``house`` (a House) at ``poses`` (N, 3) [x, z, yaw_deg]; ``scene`` is unused."""
        sc, y = self.scene_of(house)
        return self.render_with(self.start(sc, house.id), poses, y)

    def close(self) -> None:
        """Stop the Unity process."""
        if self._controller is not None:
            self._controller.stop()
            self._controller = None
