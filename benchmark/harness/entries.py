"""Cache entries of the harness, checked when read: a bad entry raises :class:`BadEntry` (the
caller recomputes it, with one warning naming the file). One validator per kind of entry
(raw label maps, classifications, renders, poses, SLAM estimates), and what the harness reads
back from a render for its view-accuracy column."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from benchmark.view_accuracy import true_labels
from envs.render.observation import poses_array


class BadEntry(ValueError):
    """A cache entry that fails validation (it is recomputed, with a warning naming it)."""


def check_labels_entry(z: Mapping[str, np.ndarray], shape: tuple[int, int], n_classes: int) -> np.ndarray:
    """A cached raw label map, checked: (H, W) integers in -1..C-1 on the scene's grid.

    Returns:
        (H, W) int32 labels.

    Raises:
        BadEntry: a missing array, another shape or dtype, or a label out of range."""
    if "raw" not in z:
        raise BadEntry("no 'raw' array")
    raw = z["raw"]
    if raw.shape != tuple(shape) or not np.issubdtype(raw.dtype, np.integer):
        raise BadEntry(f"raw labels {raw.dtype} {raw.shape}, expected integers {tuple(shape)}")
    if raw.size and (raw.min() < -1 or raw.max() >= n_classes):
        raise BadEntry(f"raw labels in [{raw.min()}, {raw.max()}], expected -1..{n_classes - 1}")
    return raw.astype(np.int32)


def check_poses(poses: np.ndarray, scene) -> None:
    """Poses (N, 3) must be finite and stand on walkable cells of ``scene.grid``.

    Raises:
        BadEntry: the count of offending poses and the first one."""
    if not np.isfinite(poses).all():
        raise BadEntry(f"{int((~np.isfinite(poses).all(axis=1)).sum())} pose(s) are not finite")
    r, c = scene.grid.world_to_cell(poses[:, 0], poses[:, 1])
    on = scene.grid.is_walkable(r, c)
    if not on.all():
        i = int(np.nonzero(~on)[0][0])
        raise BadEntry(f"{int((~on).sum())} of {len(poses)} poses lie off the walkable map "
                       f"(e.g. view {i} at x={poses[i, 0]:.3f}, z={poses[i, 1]:.3f})")


def check_render(observations: Sequence, scene) -> None:
    """Validate a cached render against the house's map.

    Raises:
        BadEntry: no views, a non-finite pose, or a pose off the map or on a cell that is
            not walkable (counts and the first offending pose in the message)."""
    if not observations:
        raise BadEntry("no views")
    check_poses(poses_array([o.pose for o in observations]), scene)
    for i, o in enumerate(observations):
        for t, a in o.objects:
            if not isinstance(t, str) or not math.isfinite(a) or a < 0:
                raise BadEntry(f"view {i}: object entry ({t!r}, {a!r}) is not (type, amount >= 0)")


def check_seen(z: Mapping[str, np.ndarray], n_views: int, n_classes: int) -> np.ndarray | None:
    """The optional ``seen`` array of a classify entry: (N,) integers in -1..C-1, or None.

    Raises:
        BadEntry: another shape or dtype, or a class out of range."""
    if "seen" not in z:
        return None
    seen = np.asarray(z["seen"])
    if seen.shape != (n_views,) or not np.issubdtype(seen.dtype, np.integer):
        raise BadEntry(f"seen has {seen.dtype} {seen.shape}, expected integers ({n_views},)")
    if seen.size and (seen.min() < -1 or seen.max() >= n_classes):
        raise BadEntry(f"seen classes in [{seen.min()}, {seen.max()}], expected -1..{n_classes - 1}")
    return seen


def check_classified(z: Mapping[str, np.ndarray], n_classes: int | None,
                     views: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray, int]:
    """Validate a cached classification; ``views`` = (poses, refused) of the house's render
    when that entry exists, so that counts and poses must agree between the two files.

    Returns:
        (poses (N, 3), proba (N, C), n_refused).

    Raises:
        BadEntry: a missing array, a wrong shape, a non-finite value, rows that are not
            probabilities, or counts that disagree with the render.
    """
    missing = [k for k in ("poses", "proba", "n_refused") if k not in z]
    if missing:
        raise BadEntry(f"missing array(s) {missing}")
    poses, proba, n_ref = np.asarray(z["poses"]), np.asarray(z["proba"]), np.asarray(z["n_refused"])
    if poses.ndim != 2 or poses.shape[1] != 3 or len(poses) == 0:
        raise BadEntry(f"poses have shape {poses.shape}, expected (N >= 1, 3)")
    want = (len(poses), n_classes if n_classes is not None else (proba.shape[1] if proba.ndim == 2 else -1))
    if proba.shape != want:
        raise BadEntry(f"proba has shape {proba.shape}, expected {want}")
    if not (np.isfinite(poses).all() and np.isfinite(proba).all()):
        raise BadEntry("non-finite values")
    if (proba < 0).any() or not np.allclose(proba.sum(axis=1), 1.0, atol=1e-6):
        raise BadEntry("proba rows are not probabilities (negative, or not summing to 1)")
    if n_ref.shape != () or not np.issubdtype(n_ref.dtype, np.integer) or int(n_ref) < 0:
        raise BadEntry(f"n_refused is {n_ref!r}, expected an integer >= 0")
    if views is not None:
        vposes, refused = views
        if len(vposes) != len(poses) + int(n_ref) or int(refused.sum()) != int(n_ref):
            raise BadEntry(f"{len(poses)} classified + {int(n_ref)} refused views, but the render has "
                           f"{len(vposes)} views ({int(refused.sum())} refused)")
        if not np.allclose(vposes[~refused], poses):
            raise BadEntry("poses differ from the render's")
    return poses, proba.astype(np.float64), int(n_ref)


def seen_from_render(render_folder: str | Path, poses: np.ndarray) -> np.ndarray | None:
    """Each classified view's majority visible class (the oracle's truth) read back from a
    house's render cache, for classifications cached before they kept it.

    Args:
        render_folder: the house's render cache folder (:mod:`envs.render.cache`).
        poses: (N, 3) poses of the classified (not refused) views.

    Returns:
        (N,) int class per view (-1: no floor seen), or None when the render is not cached, its
        views carry no visible classes (simulator renderers) or do not match ``poses``.
    """
    from envs.render import cache as render_cache  # noqa: PLC0415

    if not render_cache.is_complete(render_folder):
        return None
    obs = [o for o in render_cache.read_observations(render_folder, images=False) if not o.meta.get("refused", False)]
    if len(obs) != len(poses) or any(o.visible_classes is None for o in obs):
        return None
    if not np.allclose(np.asarray([o.pose for o in obs], dtype=float), np.asarray(poses, dtype=float), atol=1e-6):
        return None
    return true_labels(obs)


_SLAM_ARRAYS = ("true", "estimate", "odometry", "view_index", "travelled", "closures", "wrong", "online")
_SLAM_SCALARS = ("chi2", "dof", "kidnapped_m", "converged", "iterations", "rejected", "tracking_lost", "relocalised")


def slam_arrays(est) -> dict[str, np.ndarray]:
    """A :class:`benchmark.conditions.slam.SlamEstimate` as named arrays (a cache entry; ``online``
    (0, 3) where the estimate has none, no loop closure found). ``views_at`` is not kept: the
    entry serves both settings, and the stage it is handed back to chooses."""
    out = {k: np.asarray(getattr(est, k)) for k in _SLAM_ARRAYS if k != "online"}
    out["online"] = np.zeros((0, 3)) if est.online is None else np.asarray(est.online, np.float64)
    out.update({k: np.asarray(getattr(est, k)) for k in _SLAM_SCALARS})
    return out


def check_slam_entry(z: Mapping[str, np.ndarray], n_views: int):
    """A cached SLAM estimate (:func:`slam_arrays`), checked: (M, 3) trajectories, one integer
    node index per each of the ``n_views`` views it was made along, (K, 2) integer node pairs.

    Returns:
        The :class:`benchmark.conditions.slam.SlamEstimate`.

    Raises:
        BadEntry: a missing array, shapes that disagree or indices that are not integers."""
    from benchmark.conditions.slam import SlamEstimate

    missing = [k for k in (*_SLAM_ARRAYS, *_SLAM_SCALARS) if k not in z]
    if missing:
        raise BadEntry(f"no {', '.join(missing)}")
    a = {k: np.asarray(z[k]) for k in (*_SLAM_ARRAYS, *_SLAM_SCALARS)}
    ints = [k for k in ("view_index", "closures", "wrong") if not np.issubdtype(a[k].dtype, np.integer)]
    if ints:
        raise BadEntry(f"{', '.join(ints)} hold {a[ints[0]].dtype}, expected integer node indices")
    m = len(a["true"])
    shapes_ok = (a["true"].shape == a["estimate"].shape == a["odometry"].shape == (m, 3)
                 and a["travelled"].shape == (m,) and a["view_index"].shape == (n_views,)
                 and (n_views == 0 or 0 <= a["view_index"].min() <= a["view_index"].max() < m)
                 and all(a[k].ndim == 2 and a[k].shape[1] == 2 for k in ("closures", "wrong"))
                 and a["online"].shape in ((0, 3), (n_views, 3)))
    if not shapes_ok:
        raise BadEntry(f"true {a['true'].shape}, estimate {a['estimate'].shape}, view_index {a['view_index'].shape}: "
                       f"expected (M, 3) trajectories and one node per each of {n_views} views")
    return SlamEstimate(a["true"], a["estimate"], a["odometry"], a["view_index"].astype(np.int64), a["travelled"],
                        a["closures"].astype(np.int64), a["wrong"].astype(np.int64), float(a["chi2"]), int(a["dof"]),
                        float(a["kidnapped_m"]), bool(a["converged"]), int(a["iterations"]), int(a["rejected"]),
                        a["online"] if len(a["online"]) else None, tracking_lost=int(a["tracking_lost"]),
                        relocalised=int(a["relocalised"]))


__all__ = ["BadEntry", "check_labels_entry", "check_slam_entry", "slam_arrays", "check_poses", "check_render", "check_seen", "check_classified",
           "seen_from_render"]
