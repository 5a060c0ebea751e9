"""The robot-condition stages of a pipeline, with their caches: the map the robot builds along
its views (``mapping=scan``, possibly at a SLAM estimate, with the ground truth brought into its
frame), the route a SLAM pose error drives, and how much of the house the views covered.

:class:`RobotStages` is a part of :class:`benchmark.harness.pipeline.Pipeline` (its stages,
entries and cached-stage helper are the pipeline's); the view transforms themselves (pose
error, label noise) are the :class:`benchmark.method.Method`'s.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from benchmark.harness.cache import atomic_save_npz, load_npz, read_entry, write_entry
from benchmark.harness.entries import BadEntry, check_slam_entry, slam_arrays
from envs.atomic import file_identity
from envs.memo import ByteLRU
from envs.render.observation import poses_array

if TYPE_CHECKING:
    from benchmark.conditions.slam import SlamEstimate

#: the camera of the coverage columns when the renderer does not say (the floorplan
#: renderer's defaults): field of view (degrees), range (metres), occluding height (metres).
COVERAGE_FOV, COVERAGE_RANGE, COVERAGE_OCCLUDER = 90.0, 6.0, 1.2


#: bytes of SLAM estimates and finished robot maps a process keeps (:data:`_ROBOT_MEMO`): a
#: condition's maps and estimates are the same for every method and segmenter of a sweep, so
#: a worker reads and aligns each once (a ProcTHOR house's map with its ground truth in the
#: map's frame: about 0.35 MB at 0.05 m/px)
ROBOT_MEMO_BYTES = 128 * 2**20
#: bytes of render poses tables a process keeps (:data:`_POSES_MEMO`; a house's views: about
#: 10 kB): every method of every condition on the same views checks its classification against them
POSES_MEMO_BYTES = 16 * 2**20
#: kept per process, read-only: (render entry path, identity of its poses.csv) -> (poses (N, 3),
#: refused (N,)), read from the entry or taken from the views just rendered into it; a rewritten
#: entry has another identity, so it is read again
_POSES_MEMO = ByteLRU()
#: kept per process, read-only: ("slam", entry path, file identity) -> the loaded estimate;
#: ("grid", map entry path, identities of the map's and the estimate's entries) -> the map's
#: free cells (each job gets its own copy), the row columns of
#: :meth:`RobotStages._robot_grid` and the ground truth in the map's frame. A rewritten entry
#: (atomic renames: another file) has another identity, so it is read again.
_ROBOT_MEMO = ByteLRU()
#: kept per process: (environment key, house id) -> the house's lowest wall top (metres), what
#: the scan plane is checked against (:func:`envs.maps.scan.house_wall_height`; a generated house
#: is built again to read it)
_WALL_HEIGHTS = ByteLRU()


def _read_only(*arrays: np.ndarray) -> int:
    """Mark ``arrays`` read-only (they are shared by the jobs of a process); their bytes."""
    for a in arrays:
        a.setflags(write=False)
    return sum(a.nbytes for a in arrays)


def rooms_mapped(instances: np.ndarray, free: np.ndarray) -> dict[str, int]:
    """How many ground-truth rooms the robot saw: those its map reaches.

    Args:
        instances: (H, W) int room ids (-1: no room), in the map's frame.
        free: (H, W) bool, the robot map's free cells.

    Returns:
        ``rooms_mapped``: rooms with at least one free cell of the map (a room the robot never
        saw gets no label, so it is missed by matched IoU and PQ); ``rooms_total``: rooms."""
    ids = np.unique(instances[instances >= 0])
    seen = np.unique(instances[free & (instances >= 0)])
    return {"rooms_mapped": int(len(seen)), "rooms_total": int(len(ids))}


class RobotStages:
    """The robot's map and coverage for a :class:`benchmark.harness.pipeline.Pipeline` (which
    provides ``stage``, ``entry``, ``env``, ``inputs`` and ``_cached``)."""

    # ---- the robot's map (mapping=scan ...), shared by the method and the segmenters
    @property
    def mapping(self) -> Any:
        return self.stage("mapping")

    def _robot_grid(self, hid: str, scene, poses: np.ndarray | None, timings: dict) -> tuple[Any, dict[str, Any]]:
        """The occupancy map the robot has: the house's floor plan without a ``mapping`` stage,
        else the map it builds along its views, or along a mapping run of its own
        (``mapping.route: explore``), cached per house, views and mapping settings.

        Args:
            poses: (N, 3) the true poses of the views in capture order (None: the viewpoints
                stage makes them, for segmenters).

        Returns:
            (GridMap on the scene's grid, row columns describing it: agreement with the floor
            plan's walkable space).
        """
        if self.inputs.get("mapping") is None:
            return scene.grid, {"map_free_iou": 1.0, "map_missed_share": 0.0}
        from envs.maps.gridmap import GridMap

        path = self.entry("robot_map", hid)
        memo_key = self._robot_memo_key(hid, path)
        if memo_key is not None and (kept := _ROBOT_MEMO.get(memo_key)) is not None:
            free, info, frames = kept
            if frames is not None:
                self._frames[hid] = frames
            # the stages get their own map (a segmenter may write to it, or need a writable buffer)
            return GridMap(free.copy(), scene.grid.resolution, scene.grid.origin), dict(info)
        made: dict[str, np.ndarray] = {}

        def views() -> np.ndarray:  # the true views in capture order, made once when needed
            if "v" not in made:
                if poses is not None:
                    made["v"] = poses
                else:
                    t = time.perf_counter()
                    made["v"] = poses_array(self.stage("viewpoints").generate(scene))
                    timings["t_viewpoints"] = time.perf_counter() - t
            return made["v"]

        def load(path: Path) -> np.ndarray:
            free = load_npz(path)["free"]
            if free.shape != scene.grid.shape or free.dtype != np.bool_:
                raise BadEntry(f"free has {free.dtype} {free.shape}, expected bool {scene.grid.shape}")
            return free

        def compute() -> np.ndarray:
            # a SLAM robot's scans sit at its estimate (timed apart: t_slam)
            est = self._slam_estimate(hid, scene, views(), timings) if self._slam_shapes_map() else None
            t = time.perf_counter()
            kw = {} if est is None else {"estimate": (est.true, est.estimate, est.view_index)}
            if getattr(self.mapping, "uses_exploration", False):  # mapping=explored: the explorer's own map
                kw["exploration"] = self._exploration(scene, views())
            if getattr(self.mapping, "route", "views") == "explore":  # a mapping run of its own
                if est is not None:
                    raise ValueError("mapping.route=explore with a SLAM pose error that places the scans: the "
                                     "estimate follows the views; expected mapping.route=views with it")
                from benchmark.conditions.exploration import exploration_route

                route = exploration_route(scene)
            else:
                route = views()
            free = np.asarray(self.mapping(scene, route, house=self.env.house(hid), **kw), dtype=bool)
            timings["t_map"] = time.perf_counter() - t
            return free

        def save(path: Path, free: np.ndarray) -> None:
            atomic_save_npz(path, free=free)

        free = self._cached("map", path, load, compute, save)
        walk = scene.grid.walkable
        info: dict[str, Any] = {}
        est = self._slam_estimate(hid, scene, views(), timings) if self._slam_shapes_map() else None
        if est is not None:
            # the map is in the robot's frame: the ground truth comes to it (issue 37, item 2)
            from benchmark.conditions.alignment import align_rigid, to_map_frame

            theta, shift = align_rigid(est.estimate[:, :2], est.true[:, :2])
            inst = to_map_frame(scene.instances, scene.grid, theta, shift, fill=-1)
            if (scene.instances >= 0).any() and not (inst >= 0).any():
                raise ValueError(f"house {hid!r}: the SLAM estimate diverged (ATE {est.stats()['ate_rmse_m']:.1f} m): "
                                 f"aligned to the true route it puts every room off the map grid "
                                 f"({np.degrees(theta):.0f} deg, {np.hypot(*shift):.1f} m); not scored")
            walk = to_map_frame(walk.astype(np.int8), scene.grid, theta, shift, fill=0).astype(bool)
            self._frames[hid] = (inst, walk)
            info["ate_rmse_m"] = est.stats()["ate_rmse_m"]
            info["slam_converged"] = est.stats()["slam_converged"]  # 0: the solve was cut off (no verdict rests on it)
            info["map_align_deg"], info["map_align_m"] = float(np.degrees(theta)), float(np.hypot(*shift))
        union = int((free | walk).sum())
        info.update({"map_free_iou": float((free & walk).sum() / union) if union else 1.0,
                     "map_missed_share": float((walk & ~free).sum() / max(int(walk.sum()), 1))})
        info.update(rooms_mapped(self._ground_truth(hid, scene)[0], free))
        memo_key = self._robot_memo_key(hid, path)
        if memo_key is not None:
            frames = self._frames.get(hid) if est is not None else None
            kept = free.copy()
            nbytes = _read_only(kept, *(frames or ()))
            _ROBOT_MEMO.put(memo_key, (kept, dict(info), frames), nbytes + 4096, ROBOT_MEMO_BYTES)
        return GridMap(free, scene.grid.resolution, scene.grid.origin), info

    def _robot_memo_key(self, hid: str, path: Path) -> tuple | None:
        """The key of house ``hid``'s finished robot map in :data:`_ROBOT_MEMO`: its map entry and
        the estimate's it was built at, as files (None while one is missing, or with
        ``run.force`` of the map)."""
        if "map" in self.force:
            return None
        ids = (file_identity(path), file_identity(self.entry("slam", hid)) if self._slam_shapes_map() else 0)
        return None if None in ids else ("grid", str(path), ids)

    def _slam_shapes_map(self) -> bool:
        """True when the robot's map is built at a SLAM estimate that errs (``pose_error=odometry``):
        the configs :func:`benchmark.config.shapes_map` names, the one test the cache keys of the
        map and of its estimate follow (``runner.stage_keys``)."""
        from benchmark.config import shapes_map

        if self.inputs.get("mapping") is None or not shapes_map(self.inputs):
            return False
        stage = self.stage("pose_error")
        return stage is not None and hasattr(stage, "estimate") and not stage.is_clean

    def _ground_truth(self, hid: str, scene) -> tuple[np.ndarray, np.ndarray]:
        """(instances (H, W), walkable (H, W)) of the ground truth in the frame of the robot's
        map: the house's own unless the map was built at a SLAM estimate (:meth:`_robot_grid`)."""
        return self._frames.get(hid, (scene.instances, scene.grid.walkable))

    def _slam_estimate(self, hid: str, scene, views: np.ndarray, timings: dict | None = None,
                       seen: np.ndarray | None = None):
        """The robot's one pose estimate (:class:`benchmark.conditions.slam.SlamEstimate`) along its views,
        when its ``pose_error`` stage is a SLAM that makes one and errs; else None.

        Where it shapes the robot's map, it is cached beside the map (``slam`` entries, keyed
        like it: house, views, mapping and pose error), so every method of a condition shares
        one solve; the stage is handed the estimate back, so that the views it moves agree.
        ``seen``: :meth:`_scan_plane`'s answer when the caller has it already (else made here)."""
        stage = self.stage("pose_error")
        if stage is None or not hasattr(stage, "estimate") or stage.is_clean:
            return None
        grid, spacing = self._route_grid(scene), self._scan_spacing()
        seen = self._scan_plane(hid, scene) if seen is None else seen
        if not self._slam_shapes_map():
            return stage.estimate(grid, views, hid, spacing, seen)
        def load(path: Path) -> SlamEstimate:
            return check_slam_entry(load_npz(path), len(views))

        def compute() -> SlamEstimate:
            t = time.perf_counter()
            est = stage.estimate(grid, views, hid, spacing, seen)
            if timings is not None:
                timings["t_slam"] = time.perf_counter() - t
            return est

        def save(path: Path, est: SlamEstimate) -> None:
            atomic_save_npz(path, **slam_arrays(est))

        path = self.entry("slam", hid)
        est = stage.known(grid, views, hid, spacing, seen)
        if est is not None and path.exists():
            return est
        if est is not None:  # made here before its entry was written: stored, not timed again
            timings = None
        ident = None if "map" in self.force else file_identity(path)
        kept = _ROBOT_MEMO.get(("slam", str(path), ident)) if ident is not None else None
        if kept is not None and len(kept.view_index) == len(views):
            est = kept
        else:
            est = self._cached("map", path, load, compute, save)
            ident = None if "map" in self.force else file_identity(path)
            if ident is not None:
                arrays = [v for v in vars(est).values() if isinstance(v, np.ndarray)]
                _ROBOT_MEMO.put(("slam", str(path), ident), est, _read_only(*arrays) + 4096, ROBOT_MEMO_BYTES)
        stage.remember(grid, views, hid, spacing, est, seen)
        return est

    def _scan_plane(self, hid: str, scene) -> np.ndarray | None:
        """(H, W) bool what the robot's scan plane hits, as its ``mapping`` stage scans it (walls and
        furniture at the scan height, legs, closed doors): the scans its SLAM front end matches.
        None without a scanning ``mapping`` stage (the front end scans the route grid)."""
        settings = getattr(self.mapping, "settings", None)
        if settings is None or not hasattr(settings, "height"):
            return None
        from envs.maps.scan import house_wall_height, scan_plane

        # the house's walls: read once per house and process where the environment is shared
        key = (self.env_key, hid)
        wall = _WALL_HEIGHTS.get(key) if self.env_key is not None else None
        if wall is None:
            wall = house_wall_height(self.env.house(hid))
            if self.env_key is not None:
                _WALL_HEIGHTS.put(key, wall, 64, 2**20)
        return scan_plane(scene, settings, wall)  # the mapping stage's own plane (kept per scene)

    def _scan_spacing(self) -> float | None:
        """Metres driven between the robot's scans (its ``mapping`` stage's; None without one)."""
        return getattr(getattr(self.mapping, "settings", None), "spacing", None)

    def _exploration(self, scene, views: np.ndarray):
        """The exploration that made ``views`` ((N, 3), capture order): the viewpoints stage's
        last one when it made these views, else explored again (deterministic per house).

        Raises:
            ValueError: the viewpoints stage does not explore, or explores other views."""
        stage = self.stage("viewpoints")
        if not hasattr(stage, "explore"):
            raise ValueError(f"mapping=explored: the robot's own exploration map needs an exploring viewpoints "
                             f"stage (viewpoints=frontier); got {type(stage).__name__}")
        last = getattr(stage, "last", None)
        if last is None or not np.array_equal(last.poses, views):
            last = stage.explore(scene)
        if not np.array_equal(last.poses, views):
            raise ValueError(f"house {scene.house_id!r}: the exploration gives {len(last.poses)} views, the rendered "
                             f"views are {len(views)} others; expected the same (stale render cache?)")
        return last

    def _route_grid(self, scene):
        """The cells the robot can drive: the floor plan's walkable cells less the doors its
        ``mapping`` stage closes (:func:`envs.maps.scan.closed_doors`)."""
        settings = getattr(self.mapping, "settings", None)
        if settings is None or not getattr(settings, "door_closed", 0):
            return scene.grid
        from envs.maps.gridmap import GridMap
        from envs.maps.scan import closed_doors

        closed = closed_doors(scene, settings.door_closed, settings.seed)
        return GridMap(scene.grid.walkable & ~closed, scene.grid.resolution, scene.grid.origin)

    # ---- what the views covered
    def _render_poses(self, hid: str) -> np.ndarray:
        """Every view's true pose in capture order (refused ones included): the robot's path."""
        return self._render_table(hid)[0]

    def _render_table(self, hid: str) -> tuple[np.ndarray, np.ndarray]:
        """The render's poses table (:func:`envs.render.cache.read_poses`: (N, 3) poses, (N,)
        refused). The house's map, its route, its coverage and the check of its classification
        all ask, in every job on these views: read once per render entry and process, unless
        this process rendered or read its views (:data:`_POSES_MEMO`, read-only)."""
        from envs.render import cache as render_cache

        path = self.entry("render", hid)
        ident = file_identity(path / render_cache.POSES_FILE)
        kept = _POSES_MEMO.get((str(path), ident)) if ident is not None else None
        if kept is not None:
            return kept
        table = render_cache.read_poses(path)
        self._keep_render_table(path, table, ident)  # the identity of the file as it was before the read
        return table

    def _keep_render_table(self, path: Path, table: tuple[np.ndarray, np.ndarray],
                           ident: tuple[int, int, int] | None = None) -> None:
        """Keep ``table`` as the poses table of the render entry ``path`` (read-only): read from
        the entry, or taken from the views just rendered into it or read from it
        (:func:`envs.render.cache.poses_table`), which the entry's ``poses.csv`` holds. ``ident``:
        that file's identity (:func:`envs.atomic.file_identity`) when it was read; None: now."""
        from envs.render import cache as render_cache

        ident = ident if ident is not None else file_identity(path / render_cache.POSES_FILE)
        if ident is not None:
            _POSES_MEMO.put((str(path), ident), table, _read_only(*table) + 256, POSES_MEMO_BYTES)

    def _coverage(self, hid: str, scene, timings: dict) -> dict[str, float]:
        """How much of the house the views saw (:func:`benchmark.conditions.coverage.view_coverage`) with
        the renderer's field of view and range (90 degrees, 6 m when it has none) and the
        floor plan's occluders (walls, tall furniture): cached per render."""
        from benchmark.conditions.coverage import view_coverage
        from envs.render.floorplan import occluders

        def load(path: Path) -> dict[str, float]:
            cov = dict(read_entry(path))
            for k in ("coverage_area", "coverage_rooms"):
                v = cov.get(k)
                if isinstance(v, bool) or not isinstance(v, int | float) or not 0.0 <= v <= 1.0:
                    raise BadEntry(f"{k} is {v!r}, expected a share in [0, 1]")
            return cov

        def compute() -> dict[str, float]:
            t = time.perf_counter()
            fov = float(getattr(self.stage("renderer"), "fov", COVERAGE_FOV) or COVERAGE_FOV)
            rng = float(getattr(self.stage("renderer"), "max_range", COVERAGE_RANGE) or COVERAGE_RANGE)
            height = float(getattr(self.stage("renderer"), "occluder_height", COVERAGE_OCCLUDER))
            cov = view_coverage(scene, self._render_poses(hid), fov, rng, occluders(scene, height))
            timings["t_coverage"] = time.perf_counter() - t
            return {"coverage_area": float(cov["coverage_area"]), "coverage_rooms": float(cov["coverage_rooms"])}

        return self._cached("render", self.entry("coverage", hid), load, compute, lambda p, v: write_entry(p, v))
