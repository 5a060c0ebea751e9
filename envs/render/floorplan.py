"""The floorplan renderer: what a camera at a pose would see, from the house's floor plan.

For each pose, rays spanning the camera's horizontal field of view are cast over the map
along the shared digital lines (:mod:`envs.maps.rays`: the cells of
:func:`~envs.maps.rays.trace_ray`, from the path tables of :mod:`envs.maps.ray_paths`, where a ray
looks up only the cells in which it differs from its neighbour). Rays stop at walls, at the edge of the
floor, and at objects whose top is at least ``occluder_height`` metres (tall furniture);
lower objects are seen and the rays pass over them. The observation lists every object
type seen with the share of rays that touched it (objects resting on a seen object count
with it), and the share of the visible floor cells that belongs to each ground-truth class.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated

import numpy as np

from envs.kernel_cache import njit
from envs.maps.ray_paths import (
    PATH_CACHE_BYTES,
    after_differences,
    differences,
    end_paths,
    path_index,
    path_steps,
    ray_paths,
)
from envs.maps.rays import (
    BLOCKED,
    FREE,
    OUTSIDE,
    cast_rays,
    cone_ends,
    cone_thetas,
    line_start,
    line_step,
    ray_state,
)
from envs.maps.scene import Scene
from envs.ranges import CAMERA_FOV, NonNegative, Positive
from envs.render.base import Renderer
from envs.render.observation import Observation, poses_array


@dataclass
class View:
    """What one camera pose sees: visible floor cells and, per object index, the rays that hit it."""

    rows: np.ndarray
    cols: np.ndarray
    object_rays: dict[int, int]
    n_rays: int


def occluders(scene: Scene, occluder_height: float) -> np.ndarray:
    """(H, W) bool cells that stop a ray: walls, outside the floor, tall objects."""
    block = (scene.rooms < 0) | (scene.walls if scene.walls is not None else False)
    if scene.objects and scene.object_map is not None:
        tall = np.array([o.top >= occluder_height for o in scene.objects] + [False])
        block = block | tall[scene.object_map]
    return block


def view_from(scene: Scene, blocked: np.ndarray, pose: Sequence[float], fov: float, max_range_px: float) -> View:
    """Cast the camera's rays from ``pose`` (x, z, yaw degrees) and collect what they see."""
    grid = scene.grid
    r, c = grid.world_to_cell(pose[0], pose[1])
    r, c = int(r), int(c)
    if not grid.in_bounds(r, c):
        return View(np.zeros(0, np.int64), np.zeros(0, np.int64), {}, 0)
    thetas = cone_thetas(pose[2], fov, max_range_px)
    rows, cols, offsets, hits = cast_rays(blocked, r, c, thetas, max_range_px)
    omap = scene.object_map
    object_rays: dict[int, int] = {}
    if omap is not None:
        ray_of = np.repeat(np.arange(len(thetas)), np.diff(offsets))
        seen = omap[rows, cols]
        pairs = [np.stack([ray_of[seen >= 0], seen[seen >= 0]], 1)]
        hit_ok = hits[:, 0] >= 0
        hit_obj = np.full(len(thetas), -1)
        hit_obj[hit_ok] = omap[hits[hit_ok, 0], hits[hit_ok, 1]]
        m = hit_obj >= 0
        pairs.append(np.stack([np.arange(len(thetas))[m], hit_obj[m]], 1))
        allp = np.unique(np.vstack(pairs), axis=0)
        if len(allp):
            objs, counts = np.unique(allp[:, 1], return_counts=True)
            object_rays = {int(o): int(n) for o, n in zip(objs, counts)}
    lin = np.unique(rows.astype(np.int64) * grid.shape[1] + cols)
    return View(lin // grid.shape[1], lin % grid.shape[1], object_rays, len(thetas))


@njit(cache=True, nogil=True, inline="always")
def _touch(o, d, cnt, active, where, n_act):
    """Add ``d`` (+1 or -1) to the cells of the current ray on object ``o`` (-1: none); ``active``
    [:n_act] lists the objects with cells on it (``where``: each one's place there). Returns n_act."""
    if o < 0:
        return n_act
    cnt[o] += d
    if d > 0 and cnt[o] == 1:
        active[n_act] = o
        where[o] = n_act
        n_act += 1
    elif d < 0 and cnt[o] == 0:
        n_act -= 1
        last = active[n_act]
        active[where[o]] = last
        where[last] = where[o]
    return n_act


@njit(cache=True, nogil=True)
def _render_views(state, rooms, room_cls, object_map, rows, cols, yaws, offsets, max_range, n_cls, n_obj,
                  k, slot, pm, geo, plen, dstart, dj):
    """Per view: visible floor cells per class (each cell once) and rays touching each object.

    Ray ``t`` of view ``v`` has heading ``yaws[v] + offsets[t]`` and sees the cells of the digital
    line of :func:`envs.maps.rays.trace_ray` up to the first blocked cell (which it touches) or
    the map's edge, over the cell state of :func:`envs.maps.rays.ray_state` (free, blocked, off
    the map, or the last view that saw the cell: one load per cell). The lines are the paths of
    :func:`envs.maps.ray_paths.ray_paths`, walked as the vision cone walks them: a ray whose end
    neighbours the ray before's looks up only the indices where the two paths differ below
    where that ray stopped, and walks on only beyond it (other rays are walked whole). The
    objects a ray touches are kept as the object at each index of its path (``pobj``, up to
    where it stopped) and a count per object, changed where the path changes. A newly seen cell's
    counting is written out at each of the three walks: as a helper function (inlined or not),
    it made the kernel a fifth slower. A view's ray ends are found at once
    (:func:`envs.maps.rays.cone_ends`): with the path helpers that read without a branch, the
    renders of the perf houses at 0.05 m/px take about 0.9 of the time they took ray by ray."""
    h = state.shape[0] - 2
    w = state.shape[1] - 2
    n_views = rows.shape[0]
    n_rays = offsets.shape[0]
    nob = max(n_obj, 1)
    vis = np.zeros((n_views, n_cls), np.int64)
    obj_rays = np.zeros((n_views, nob), np.int64)
    n_cells = np.zeros(n_views, np.int64)
    cap = int(np.ceil(max_range)) + 3
    pobj = np.full(cap, -1, np.int64)  # the object at each index of the current ray's path
    cnt = np.zeros(nob, np.int64)  # the current ray's cells on each object
    active = np.zeros(nob, np.int64)
    where = np.zeros(nob, np.int64)
    n_act = 0
    cos_off = np.cos(offsets)
    sin_off = np.sin(offsets)
    ends_r = np.empty(n_rays, np.int64)  # a view's ray ends (offsets from its cell), found at once
    ends_c = np.empty(n_rays, np.int64)
    exact = np.empty(n_rays, np.bool_)
    ends_s = np.empty(n_rays, np.int64)  # and their paths
    # flat indices along the paths: a state cell (r + 1) * (w + 2) + c + 1, a map cell r * w + c
    w2 = w + 2
    flat_state = state.reshape(-1)
    flat_rooms = rooms.reshape(-1)
    flat_objects = object_map.reshape(-1)
    for v in range(n_views):
        r0 = rows[v]
        c0 = cols[v]
        if r0 < 0 or r0 >= h or c0 < 0 or c0 >= w:
            continue
        base_s = (r0 + 1) * w2 + c0 + 1
        base_c = r0 * w + c0
        yaw = yaws[v]
        cone_ends(r0, c0, yaw, offsets, cos_off, sin_off, max_range, ends_r, ends_c, exact)
        end_paths(ends_r, ends_c, max_range, k, slot, ends_s)
        prev = -1  # path of the ray before (-1: none, or walked whole)
        pstop = 0  # where it stopped (its length when it did not)
        pend = -1  # the last index of pobj it holds
        per = 0
        pec = 0
        last_r = -(1 << 62)
        last_c = -(1 << 62)
        for t in range(n_rays):
            r1 = r0 + ends_r[t]
            c1 = c0 + ends_c[t]
            if r1 == last_r and c1 == last_c:
                # the same digital line as the ray before: the same cells (already counted for
                # this view) and the same objects, each touched by one more ray
                for i in range(n_act):
                    obj_rays[v, active[i]] += 1
                continue
            last_r = r1
            last_c = c1
            er = r1 - r0
            ec = c1 - c0
            s = ends_s[t]
            a = er - per
            b = ec - pec
            if s < 0 or prev < 0 or a < -1 or a > 1 or b < -1 or b > 1:
                for i in range(n_act):  # a ray of its own: its objects start afresh
                    cnt[active[i]] = 0
                n_act = 0
                pend = -1  # (pobj beyond pend is never read)
            if s < 0:  # not a precomputed end: walk the line itself
                dr, dc, sr, sc, err = line_start(r0, c0, r1, c1)
                r = r0
                c = c0
                while True:
                    x = state[r + 1, c + 1]
                    if x == OUTSIDE:
                        break
                    if x != BLOCKED and x != v:
                        state[r + 1, c + 1] = v
                        n_cells[v] += 1
                        q = rooms[r, c]
                        if q >= 0 and room_cls[q] >= 0:
                            vis[v, room_cls[q]] += 1
                    n_act = _touch(object_map[r, c], 1, cnt, active, where, n_act)
                    if x == BLOCKED or (r == r1 and c == c1):
                        break
                    r, c, err = line_step(r, c, err, dr, dc, sr, sc)
                for i in range(n_act):
                    obj_rays[v, active[i]] += 1
                prev = -1
                continue
            # cell j of the path, minor coordinate mn: base + j * step + mn * mstep
            step_s, mstep_s = path_steps(geo, s, w2)
            step_c, mstep_c = path_steps(geo, s, w)
            walk_from = 0
            stop = -1
            if pend >= 0:  # the ray before was a neighbouring path: its cells except where they differ
                m, lim, i, e = differences(s, prev, a, b, plen, pstop, dstart)
                while i < e and dj[np.uint64(2 * i)] < lim:
                    j = np.int64(dj[np.uint64(2 * i)])
                    mn = np.int64(dj[np.uint64(2 * i + 1)])
                    fs = path_index(base_s, step_s, mstep_s, j, mn)
                    fc = path_index(base_c, step_c, mstep_c, j, mn)
                    x = flat_state[fs]
                    o = -1 if x == OUTSIDE else flat_objects[fc]
                    if o != pobj[j]:
                        n_act = _touch(pobj[j], -1, cnt, active, where, n_act)
                        n_act = _touch(o, 1, cnt, active, where, n_act)
                        pobj[j] = o
                    if x < FREE:
                        stop = j
                        break
                    if x != v:
                        flat_state[fs] = v
                        n_cells[v] += 1
                        q = flat_rooms[fc]
                        if q >= 0 and room_cls[q] >= 0:
                            vis[v, room_cls[q]] += 1
                    i += 1
                if stop < 0:
                    walk_from, stop = after_differences(i, e, dj, pstop, m)
            if stop < 0:
                for j in range(walk_from, pend + 1):  # what the walk rewrites, or lies beyond this path
                    n_act = _touch(pobj[j], -1, cnt, active, where, n_act)
                    pobj[j] = -1
                pend = min(pend, walk_from - 1)
                stop = plen[s]
                for j in range(walk_from, plen[s]):
                    mn = np.int64(pm[np.uint64(s), np.uint64(j)])
                    fs = path_index(base_s, step_s, mstep_s, j, mn)
                    fc = path_index(base_c, step_c, mstep_c, j, mn)
                    x = flat_state[fs]
                    o = -1 if x == OUTSIDE else flat_objects[fc]
                    pobj[j] = o
                    n_act = _touch(o, 1, cnt, active, where, n_act)
                    if x < FREE:
                        stop = j
                        break
                    if x != v:
                        flat_state[fs] = v
                        n_cells[v] += 1
                        q = flat_rooms[fc]
                        if q >= 0 and room_cls[q] >= 0:
                            vis[v, room_cls[q]] += 1
            end = min(stop, plen[s] - 1)
            for j in range(end + 1, pend + 1):  # beyond where this ray stopped
                n_act = _touch(pobj[j], -1, cnt, active, where, n_act)
                pobj[j] = -1
            pend = end
            for i in range(n_act):
                obj_rays[v, active[i]] += 1
            prev = s
            pstop = stop
            per = er
            pec = ec
    return vis, obj_rays, n_cells


class FloorplanRenderer(Renderer):
    """Offline observations for any ProcTHOR-schema house (no simulator, no GPU).

    Args:
        fov: horizontal field of view, degrees.
        max_range: how far the camera sees, metres.
        occluder_height: objects at least this tall (metres) block the view.
        include_children: objects resting on a seen object are seen too.
    """

    def __init__(self, fov: Annotated[float, CAMERA_FOV] = 90.0,
                 max_range: Annotated[float, Positive()] = 6.0,
                 occluder_height: Annotated[float, NonNegative()] = 1.2, include_children: bool = True):
        if not (0 < fov <= 360) or max_range <= 0:
            raise ValueError(f"FloorplanRenderer needs 0 < fov <= 360 degrees and max_range > 0 m; got {fov}, {max_range}")
        self.fov, self.max_range = fov, max_range
        self.occluder_height, self.include_children = occluder_height, include_children

    def render(self, house, scene: Scene, poses: np.ndarray) -> list[Observation]:
        poses = poses_array(poses)
        blocked = occluders(scene, self.occluder_height)
        n_cls = len(scene.classes)
        max_px = self.max_range / scene.grid.resolution
        r, c = scene.grid.world_to_cell(poses[:, 0], poses[:, 1])
        # every view's rays: the same offsets around its heading (cone_thetas centred on 0)
        offsets = cone_thetas(0.0, self.fov, max_px)
        omap = scene.object_map if scene.object_map is not None else np.full(scene.grid.shape, -1, np.int32)
        vis, obj_rays, n_cells = _render_views(
            ray_state(~blocked), np.ascontiguousarray(scene.rooms), np.asarray(scene.instance_classes, np.int64),
            np.ascontiguousarray(omap),
            r.astype(np.int64), c.astype(np.int64), np.deg2rad(poses[:, 2]), offsets, float(max_px), n_cls,
            len(scene.objects), *ray_paths(float(max_px), PATH_CACHE_BYTES))
        n_rays = len(offsets)
        total = vis.sum(axis=1)
        shares = np.zeros(vis.shape)
        seen = total > 0
        shares[seen] = vis[seen] / total[seen, None]
        # each object's share of a view's rays, counted for its type and (include_children) the
        # types resting on it; a type seen through several objects keeps its largest share
        types = [(o.object_type, *o.children) if self.include_children else (o.object_type,) for o in scene.objects]
        view_of, obj_of = np.nonzero(obj_rays) if scene.objects else (np.zeros(0, np.int64),) * 2
        share_of = (obj_rays[view_of, obj_of] / n_rays).tolist()
        first = np.searchsorted(view_of, np.arange(len(poses) + 1)).tolist()
        obj_of = obj_of.tolist()
        out = []
        for i, p in enumerate(poses.tolist()):
            objects: dict[str, float] = {}
            for j in range(first[i], first[i + 1]):
                share = share_of[j]
                for t in types[obj_of[j]]:
                    objects[t] = max(objects.get(t, 0.0), share)
            out.append(Observation(pose=(p[0], p[1], p[2]), objects=sorted(objects.items()),
                                   visible_classes=shares[i], meta={"n_visible_cells": int(n_cells[i])}))
        return out
