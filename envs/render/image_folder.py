"""Observations from a folder of a robot's own images (``renderer=images``): no simulator.

A pose file (CSV or JSON, read by :func:`envs.maps.pose_files.read_poses` in an explicit
``frame``: ``ros`` x, y, theta; ``sim`` x, z, yaw; ``pixel`` row, col, yaw) lists one view per
row, with an ``image`` column (``image_column``) naming its picture: a path absolute or
relative to ``folder`` (default: the pose file's folder). An optional ``id`` column names
the view (default: the image name as written); it becomes ``Observation.meta["id"]``, which
``classifier=labels`` can match on.

Every listed image must exist (one line names the first missing one, the pose file and the
row) and be readable as RGB; each observation carries the (H, W, 3) uint8 image, so
``classifier=cnn|dinov2|vlm`` classify a user's own pictures.

:meth:`ImageFolderRenderer.observations` gives every listed view. :meth:`render` gives the
views at the requested poses (the runner's ``viewpoints=file`` on the same pose file): each
requested pose must equal exactly one listed pose within ``tolerance_m`` metres (x and z)
and ``tolerance_deg`` degrees.

``poses`` and ``folder`` may hold ``{house_id}`` (filled from the scene's house id).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image
from scipy.spatial import cKDTree

from envs.maps.gridmap import GridMap
from envs.maps.pose_files import FRAME_COLUMNS, read_poses, read_table
from envs.maps.scene import Scene
from envs.render.base import Renderer
from envs.render.observation import Observation, poses_array
from envs.world.house import House


def match_poses(listed: np.ndarray, wanted: np.ndarray, tolerance_m: float, tolerance_deg: float) -> list[list[int]]:
    """For each wanted pose, the listed poses equal to it within the tolerances.

    Args:
        listed: (M, 3) world x, z (metres), yaw (degrees).
        wanted: (N, 3) the same.
        tolerance_m: largest |dx| and |dz|, metres.
        tolerance_deg: largest heading difference, degrees (360-periodic).

    Returns:
        N lists of row indices into ``listed``, ascending.
    """
    listed = np.asarray(listed, dtype=float).reshape(-1, 3)
    wanted = np.asarray(wanted, dtype=float).reshape(-1, 3)
    if len(listed) == 0:
        return [[] for _ in range(len(wanted))]
    tree = cKDTree(listed[:, :2])
    out = []
    for x, z, yaw in wanted:
        near = tree.query_ball_point([x, z], r=tolerance_m * np.sqrt(2.0) + 1e-12)
        out.append(sorted(k for k in near
                          if abs(listed[k, 0] - x) <= tolerance_m and abs(listed[k, 1] - z) <= tolerance_m
                          and abs((listed[k, 2] - yaw + 180.0) % 360.0 - 180.0) <= tolerance_deg))
    return out


@dataclass(frozen=True)
class ImageViews:
    """The views a pose file lists.

    Attributes:
        poses: (N, 3) world x, z (metres), yaw (degrees).
        images: N image paths (checked to exist).
        ids: N view ids (the ``id`` column, or the image names as written).
        source: the pose file.
    """

    poses: np.ndarray
    images: list[Path]
    ids: list[str]
    source: Path


def load_rgb(path: Path, where: str) -> np.ndarray:
    """An image file as (H, W, 3) uint8 RGB, or one line naming it and ``where`` it was listed."""
    try:
        with Image.open(path) as im:
            return np.array(im.convert("RGB"))
    except OSError as e:
        raise ValueError(f"{where}: cannot read image {path} ({str(e).splitlines()[0] if str(e) else 'unreadable'})"
                         ) from None


class ImageFolderRenderer(Renderer):
    """Observations with RGB images from a folder and a pose file (see the module doc).

    Args:
        poses: the pose file (CSV / JSON) with an image column; may hold ``{house_id}``.
        frame: ``ros`` | ``sim`` | ``pixel``: the pose columns' frame.
        folder: where relative image names are looked up (default: the pose file's folder).
        image_column: the column naming each view's image.
        id_column: the column naming each view (absent: the image names).
        tolerance_m, tolerance_deg: pose match tolerances of :meth:`render`.
    """

    def __init__(self, poses: str, frame: str = "sim", folder: str | None = None, image_column: str = "image",
                 id_column: str = "id", tolerance_m: float = 1e-3, tolerance_deg: float = 0.5):
        if poses is None or not str(poses).strip():
            raise ValueError("renderer.poses is not set; expected a pose file listing each image and its pose")
        if frame not in FRAME_COLUMNS:
            raise ValueError(f"renderer.frame is {frame!r}; expected one of {list(FRAME_COLUMNS)}")
        if not (tolerance_m >= 0 and tolerance_deg >= 0):
            raise ValueError(f"renderer tolerances must be >= 0, got {tolerance_m} m, {tolerance_deg} degrees")
        self.poses_path, self.frame = str(poses), frame
        self.folder = None if folder is None else str(folder)
        self.image_column, self.id_column = image_column.strip().lower(), id_column.strip().lower()
        self.tolerance_m, self.tolerance_deg = float(tolerance_m), float(tolerance_deg)

    def _paths(self, house_id: str | None) -> tuple[Path, Path]:
        def fill(text: str) -> str:
            if "{house_id}" in text:
                if house_id is None:
                    raise ValueError(f"renderer path {text!r} holds {{house_id}} but no house id was given")
                return text.format(house_id=house_id)
            return text

        pose_file = Path(fill(self.poses_path)).expanduser()
        folder = Path(fill(self.folder)).expanduser() if self.folder is not None else pose_file.parent
        return pose_file, folder

    def views(self, house_id: str | None = None, grid: GridMap | None = None) -> ImageViews:
        """The listed views: poses (``grid`` needed for ``frame="pixel"``), image paths and ids.

        Raises:
            FileNotFoundError: the pose file, the image folder or an image is missing (one
                line naming the file, the row and the image).
            ValueError: a bad pose column or image column (one line naming the file).
        """
        pose_file, folder = self._paths(house_id)
        poses = read_poses(pose_file, self.frame, grid)
        df = read_table(pose_file)
        df.columns = [str(c).strip().lower() for c in df.columns]
        if self.image_column not in df.columns:
            raise ValueError(f"{pose_file}: no {self.image_column!r} column naming each view's image; found columns "
                             f"{list(df.columns)}")
        if not folder.is_dir():
            raise FileNotFoundError(f"image folder not found: {folder} (for {pose_file})")
        names = ["" if v is None or (isinstance(v, float) and np.isnan(v)) else str(v).strip()
                 for v in df[self.image_column].tolist()]
        paths = []
        for i, name in enumerate(names):
            if not name:
                raise ValueError(f"{pose_file}: column {self.image_column!r} is empty at row {i}; expected an image")
            p = Path(name).expanduser()
            paths.append(p if p.is_absolute() else folder / p)
        missing = [i for i, p in enumerate(paths) if not p.is_file()]
        if missing:
            i = missing[0]
            raise FileNotFoundError(f"{pose_file}: column {self.image_column!r} row {i} names {names[i]!r}, which "
                                    f"does not exist (looked for {paths[i]}); {len(missing)} of {len(paths)} images "
                                    f"missing")
        if self.id_column in df.columns:
            ids = [str(v).strip() for v in df[self.id_column].tolist()]
        else:
            ids = names
        dup = sorted(k for k, n in Counter(ids).items() if n > 1)
        if dup:
            raise ValueError(f"{pose_file}: view id(s) {dup[:5]} repeat (column "
                             f"{self.id_column if self.id_column in df.columns else self.image_column!r}); "
                             f"expected one row per view")
        return ImageViews(poses=poses, images=paths, ids=ids, source=pose_file)

    def _observe(self, v: ImageViews, rows: Sequence[int], house_id: str | None) -> list[Observation]:
        out = []
        for k in rows:
            img = load_rgb(v.images[k], f"{v.source} row {k}")
            meta = {"id": v.ids[k], "image_path": str(v.images[k])}
            if house_id is not None:
                meta["house_id"] = house_id
            out.append(Observation(pose=tuple(float(a) for a in v.poses[k]), image=img, meta=meta))
        return out

    def observations(self, house_id: str | None = None, grid: GridMap | None = None) -> list[Observation]:
        """Every listed view, in file order, with its (H, W, 3) uint8 image.

        Returns:
            N observations; ``meta`` has ``id``, ``image_path`` (and ``house_id`` when given).
        """
        v = self.views(house_id, grid)
        return self._observe(v, range(len(v.images)), house_id)

    def render(self, house: House | None, scene: Scene, poses: np.ndarray) -> list[Observation]:
        """The listed views at ``poses`` (N, 3), in that order (the house is not used).

        Returns:
            N observations with images; ValueError when a pose matches no listed view, or
            more than one.
        """
        hid = getattr(scene, "house_id", None)
        v = self.views(hid, getattr(scene, "grid", None))
        wanted = poses_array(poses)
        rows = []
        for i, near in enumerate(match_poses(v.poses, wanted, self.tolerance_m, self.tolerance_deg)):
            if len(near) != 1:
                x, z, yaw = wanted[i]
                what = "no view" if not near else f"{len(near)} views (rows {near[:3]})"
                raise ValueError(f"{v.source}: {what} within {self.tolerance_m} m and {self.tolerance_deg} degrees of "
                                 f"pose {i} at x={x:.4f}, z={z:.4f}, yaw={yaw:.2f}; expected exactly one")
            rows.append(near[0])
        return self._observe(v, rows, hid)


__all__ = ["ImageFolderRenderer", "ImageViews", "load_rgb", "match_poses"]
