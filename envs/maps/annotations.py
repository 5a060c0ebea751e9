"""Ground-truth annotations of houses that have no ProcTHOR house JSON (ArchitecTHOR).

Layout, one folder per house (``<root>/<house>/``):

* ``labels.png`` + ``labels.json`` (required): the class label map as written by
  :func:`envs.maps.label_png.write_label_png`: a colour PNG in the class colours, and a sidecar
  with ``classes`` (names), ``colors``, ``resolution`` (metres per pixel) and ``origin``
  (world x, z in metres of the top-left corner of pixel (0, 0); rows grow as z decreases,
  as every map here). Unlabelled / outside pixels are the sidecar's unlabelled or
  background colour.
* ``instances.png`` (optional, same size): one colour per room, black outside. Without it
  each connected region of one class is a room.
* ``walkable.png`` (optional): white = walkable, e.g. the simulator's navmesh seen from
  above (``python -m benchmark.commands.navmesh navmesh``). With a ``walkable.json`` (resolution,
  origin) it may be on its own grid: the labels are carried onto it (nearest, by world
  position). Without ``walkable.json`` it must have the label map's size. Without
  ``walkable.png`` every labelled pixel is walkable.

Before the ground truth is trusted it is checked against the navmesh map
(:func:`walkable_agreement`, printed by ``import`` and ``check``): the share of annotated
pixels whose world position lies on a walkable cell, and the share of walkable cells that
lie in an annotated room. An annotation drawn in the other axis convention (see
``python -m benchmark.commands.navmesh mirror``), with a wrong origin or resolution, lands
off the navmesh and drops both shares; below the thresholds (:data:`MIN_ON_WALKABLE`,
:data:`MIN_WALKABLE_COVERED`) the commands print a warning. A correct annotation does not
reach 100 % on walkable: rooms include furniture and the agent-radius margin along walls,
which the navmesh leaves out.

``python -m benchmark.commands.annotations import --map MAP.png --colours MAP.json --resolution 0.02
--origin X Z --out ROOT/HOUSE`` converts a colour-coded room map whose JSON gives each
colour a class (``{"#rrggbb": "kitchen", ...}``) into that layout: ``--rooms colour`` (one
room per colour, an instance map) or ``--rooms components`` (one room per connected region
of a colour, a class-coloured map). ``python -m benchmark.commands.annotations check ROOT`` prints what
each house folder holds.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from PIL import Image
from scipy import ndimage

from envs.atomic import atomic_write_text
from envs.maps.gridmap import GridMap
from envs.maps.images import read_image
from envs.maps.label_png import read_instance_png, read_label_png, write_label_png
from envs.maps.scene import Scene, scene_on_grid
from envs.world.classes import PAPER_CLASSES, class_index

ROOM_MODES = ("colour", "components")
#: Warn when fewer annotated pixels than this share lie on walkable navmesh cells.
MIN_ON_WALKABLE = 0.5
#: Warn when fewer walkable navmesh cells than this share lie in an annotated room.
MIN_WALKABLE_COVERED = 0.9


def _grid_meta(path: Path) -> tuple[float, tuple[float, float]]:
    meta = json.loads(path.read_text())
    res, origin = meta.get("resolution"), meta.get("origin")
    if res is None or origin is None or len(origin) != 2 or float(res) <= 0:
        raise ValueError(f"{path} must give 'resolution' (metres per pixel, > 0) and 'origin' ([x, z] metres), "
                         f"got resolution={res!r}, origin={origin!r}")
    return float(res), (float(origin[0]), float(origin[1]))


def components_as_rooms(labels: np.ndarray) -> np.ndarray:
    """(H, W) class labels (-1 none) -> (H, W) int32 room ids: one per 4-connected region of one class."""
    inst = np.full(labels.shape, -1, np.int32)
    n = 0
    for k in np.unique(labels[labels >= 0]):
        lab, m = ndimage.label(labels == k)
        inst[lab > 0] = lab[lab > 0] - 1 + n
        n += m
    return inst


def rooms_and_classes(labels: np.ndarray, instances: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Room ids renumbered 0..R-1 on labelled pixels (-1 elsewhere) and each room's class
    (the most common label of its pixels)."""
    ids = np.where(labels >= 0, instances, -1)
    present = np.unique(ids[ids >= 0])
    lut = np.full(int(ids.max()) + 2 if ids.size else 1, -1, np.int32)
    lut[present] = np.arange(len(present), dtype=np.int32)
    rooms = np.where(ids >= 0, lut[ids], -1).astype(np.int32)
    cls = np.array([int(np.bincount(labels[rooms == i]).argmax()) for i in range(len(present))], dtype=np.int64)
    return rooms, cls


def load_annotation(folder: str | Path, house_id: str | None = None, classes: Sequence[str] = PAPER_CLASSES) -> Scene:
    """A Scene (grid, room instances, room classes in ``classes`` order) from an annotation
    folder (layout in the module docstring)."""
    folder = Path(folder)
    if not (folder / "labels.png").is_file():
        raise FileNotFoundError(f"no annotation at {folder}/labels.png: convert the house's annotation with "
                                "python -m benchmark.commands.annotations import (see docs/gpu.md)")
    labels_local, names = read_label_png(folder / "labels.png")
    res, origin = _grid_meta(folder / "labels.json")
    used = set(np.unique(labels_local[labels_local >= 0]).tolist())
    remap = np.array([class_index(classes, n) if i in used else -1 for i, n in enumerate(names)] + [-1], dtype=np.int32)
    labels = remap[labels_local]  # -1 indexes the last entry and stays -1
    if not (labels >= 0).any():
        raise ValueError(f"{folder}/labels.png has no labelled pixel")
    if (folder / "instances.png").is_file():
        inst = read_instance_png(folder / "instances.png", min_pixels=1, assign="drop")
        if inst.shape != labels.shape:
            raise ValueError(f"{folder}: instances.png {inst.shape} and labels.png {labels.shape} differ in size")
    else:
        inst = components_as_rooms(labels)
    rooms, room_cls = rooms_and_classes(labels, inst)
    if not len(room_cls):
        raise ValueError(f"{folder}: no room has a labelled pixel (instances.png and labels.png do not overlap)")
    walk_png, walk_json = folder / "walkable.png", folder / "walkable.json"
    own = walk_png.is_file() and walk_json.is_file()
    if walk_png.is_file() and not own:
        walk = read_image(walk_png, "the navmesh map", "L") > 127
        if walk.shape != labels.shape:
            raise ValueError(f"{folder}: walkable.png {walk.shape} and labels.png {labels.shape} differ in size "
                             "(add a walkable.json with its resolution and origin to put it on its own grid)")
    else:
        walk = rooms >= 0
    grid = GridMap(walk, res, origin)
    hid = house_id or folder.name
    scene = Scene(hid, grid, rooms, np.where(walk, rooms, -1).astype(np.int32), room_cls,
                  [f"room|{i}" for i in range(len(room_cls))], tuple(classes))
    if own:
        wres, worigin = _grid_meta(walk_json)
        wgrid = GridMap(read_image(walk_png, "the navmesh map", "L") > 127, wres, worigin)
        scene = scene_on_grid(scene, wgrid)
    return scene


def _labels_grid(folder: Path) -> tuple[np.ndarray, GridMap]:
    labels, _ = read_label_png(folder / "labels.png")
    res, origin = _grid_meta(folder / "labels.json")
    return labels, GridMap(labels >= 0, res, origin)


def walkable_agreement(folder: str | Path) -> dict | None:
    """How an annotation folder's labels sit on its navmesh map (``walkable.png``), by
    world position (each pixel's centre looked up on the other grid; the two may differ in
    resolution and origin when ``walkable.json`` is there).

    Returns:
        None when the folder has no ``walkable.png``; else a dict with ``annotated`` (labelled
        pixels), ``on_walkable`` (share of them on a walkable cell, 0-1), ``walkable``
        (walkable cells) and ``covered`` (share of them inside a labelled pixel, 0-1).
    """
    folder = Path(folder)
    walk_png, walk_json = folder / "walkable.png", folder / "walkable.json"
    if not walk_png.is_file():
        return None
    if not (folder / "labels.png").is_file():
        raise FileNotFoundError(f"no annotation at {folder}/labels.png")
    labels, lgrid = _labels_grid(folder)
    walk = read_image(walk_png, "the navmesh map", "L") > 127
    if walk_json.is_file():
        wres, worigin = _grid_meta(walk_json)
        wgrid = GridMap(walk, wres, worigin)
    else:
        if walk.shape != labels.shape:
            raise ValueError(f"{folder}: walkable.png {walk.shape} and labels.png {labels.shape} differ in size "
                             "and there is no walkable.json")
        wgrid = GridMap(walk, lgrid.resolution, lgrid.origin)

    def share_on(src: GridMap, dst: GridMap) -> tuple[int, float]:
        rr, cc = np.nonzero(src.walkable)
        if not len(rr):
            return 0, 0.0
        r, c = dst.world_to_cell(*src.pixel_to_world(rr, cc))
        ok = dst.in_bounds(r, c)
        hit = np.zeros(len(rr), bool)
        hit[ok] = dst.walkable[r[ok], c[ok]]
        return int(len(rr)), float(hit.mean())

    n_ann, on = share_on(lgrid, wgrid)
    n_walk, covered = share_on(wgrid, lgrid)
    return {"annotated": n_ann, "on_walkable": on, "walkable": n_walk, "covered": covered}


def agreement_line(folder: str | Path, min_on_walkable: float = MIN_ON_WALKABLE,
                   min_covered: float = MIN_WALKABLE_COVERED) -> tuple[str, bool]:
    """One line about :func:`walkable_agreement` and whether it passed the thresholds
    (shares 0-1). Returns (line, ok); a folder without ``walkable.png`` is ok with a line
    saying the check was not possible."""
    a = walkable_agreement(folder)
    name = Path(folder).name
    if a is None:
        return f"{name}: no walkable.png, not checked against the navmesh", True
    ok = a["on_walkable"] >= min_on_walkable and a["covered"] >= min_covered
    line = (f"{name}: {a['on_walkable']:.1%} of {a['annotated']} annotated px on walkable cells "
            f"(warn below {min_on_walkable:.0%}), {a['covered']:.1%} of {a['walkable']} walkable cells in a room "
            f"(warn below {min_covered:.0%})")
    if not ok:
        line = ("WARNING " + line + ": the annotation does not sit on the navmesh; check the axis convention "
                "(navmesh mirror), --origin and --resolution")
    return line, ok


def write_walkable(folder: str | Path, grid: GridMap) -> Path:
    """Write ``grid`` as ``walkable.png`` (white = walkable) + ``walkable.json`` (resolution, origin) in ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / ".walkable.png.tmp"
    Image.fromarray(grid.walkable.astype(np.uint8) * 255).save(tmp, format="PNG")
    tmp.replace(folder / "walkable.png")
    atomic_write_text(folder / "walkable.json", json.dumps({"resolution": grid.resolution, "origin": list(grid.origin),
                                                           "shape": list(grid.shape)}, indent=1))
    return folder / "walkable.png"


def parse_colour(key: str) -> tuple[int, int, int]:
    """``"#rrggbb"`` (or ``"rrggbb"``) -> (r, g, b)."""
    h = str(key).strip().lstrip("#")
    if len(h) != 6:
        raise ValueError(f"colour {key!r} is not of the form #rrggbb")
    try:
        return int(h[0:2], 16), int(h[2:4], 16), int(h[4:6], 16)
    except ValueError:
        raise ValueError(f"colour {key!r} is not of the form #rrggbb") from None


def import_room_map(map_png: str | Path, colour_classes: Mapping[str, str], resolution: float,
                    origin: tuple[float, float], out: str | Path, rooms: str = "colour",
                    classes: Sequence[str] = PAPER_CLASSES) -> Path:
    """Convert a colour-coded room map (black = outside) + colour -> class names into the
    annotation layout in ``out``: ``labels.png``/``labels.json`` and, with
    ``rooms="colour"``, ``instances.png`` (one room per colour). ``resolution`` metres per
    pixel, ``origin`` world (x, z) metres of the top-left corner."""
    map_png, out = Path(map_png), Path(out)
    if rooms not in ROOM_MODES:
        raise ValueError(f"rooms must be one of {ROOM_MODES}, got {rooms!r}")
    if not float(resolution) > 0:
        raise ValueError(f"resolution must be positive metres per pixel, got {resolution}")
    lut = {parse_colour(k): class_index(classes, v) for k, v in colour_classes.items()}
    inst, colours = read_instance_png(map_png, min_pixels=1, return_colors=True)
    labels = np.full(inst.shape, -1, np.int32)
    for i, c in enumerate(colours):
        key = tuple(int(v) for v in c)
        if key not in lut:
            raise ValueError(f"{map_png}: colour #{key[0]:02x}{key[1]:02x}{key[2]:02x} has no class in the colour JSON")
        labels[inst == i] = lut[key]
    out.mkdir(parents=True, exist_ok=True)
    write_label_png(out / "labels.png", labels, classes, resolution=float(resolution),
                    origin=(float(origin[0]), float(origin[1])), legend=False)
    if rooms == "colour":
        tmp = out / ".instances.png.tmp"
        Image.fromarray(read_image(map_png, "the annotation map", "RGB")).save(tmp, format="PNG")
        tmp.replace(out / "instances.png")
    elif (out / "instances.png").exists():
        (out / "instances.png").unlink()
    atomic_write_text(out / "SOURCE.txt", f"imported from {map_png} (rooms={rooms}, resolution={resolution} m/px, "
                                          f"origin={tuple(origin)})\n")
    return out


def describe(folder: str | Path, classes: Sequence[str] = PAPER_CLASSES) -> str:
    """One line about an annotation folder: rooms per class, grid, walkable area."""
    s = load_annotation(folder, classes=classes)
    counts = np.bincount(np.asarray(s.instance_classes, dtype=np.int64), minlength=len(classes))
    per = ", ".join(f"{c} {n}" for c, n in zip(classes, counts) if n)
    area = float(s.grid.walkable.sum()) * s.grid.resolution ** 2
    return (f"{Path(folder).name}: {len(s.instance_classes)} rooms ({per}); {s.grid.shape[1]} x {s.grid.shape[0]} px "
            f"at {s.grid.resolution} m/px, origin {s.grid.origin}; walkable {area:.1f} m2")
