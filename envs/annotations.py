"""Ground-truth annotations of houses that have no ProcTHOR house JSON (ArchitecTHOR).

Layout, one folder per house (``<root>/<house>/``):

* ``labels.png`` + ``labels.json``: the class label map written by
  :func:`envs.mapio.write_label_png` (sidecar: class names, colours, ``resolution`` in
  metres per pixel, ``origin`` = world (x, z) of the top-left corner of pixel (0, 0));
* ``instances.png`` (optional): one colour per room; without it each connected region of
  one class is a room;
* ``walkable.png`` (optional): white = walkable (e.g. the simulator's navmesh seen from
  above); without it every labelled pixel is walkable.

``python -m envs.annotations import --instances MAP.png --classes MAP.json --resolution 0.02
--origin X Z --out ROOT/HOUSE`` converts an instance-coloured map whose JSON gives each
room colour a class (``{"#rrggbb": "kitchen", ...}``) into that layout.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image
from scipy import ndimage

from envs.atomic import atomic_write_text
from envs.classes import PAPER_CLASSES, class_index
from envs.gridmap import GridMap
from envs.mapio import read_instance_png, read_label_png, write_label_png
from envs.scene import Scene


def load_annotation(folder: str | Path, house_id: str | None = None, classes: Sequence[str] = PAPER_CLASSES) -> Scene:
    """A Scene from an annotation folder (see the module docstring)."""
    folder = Path(folder)
    if not (folder / "labels.png").exists():
        raise FileNotFoundError(f"no annotation at {folder}/labels.png (convert one with python -m envs.annotations import)")
    labels, names = read_label_png(folder / "labels.png")
    meta = json.loads((folder / "labels.json").read_text())
    if meta.get("resolution") is None or meta.get("origin") is None:
        raise ValueError(f"{folder}/labels.json must give 'resolution' (m/px) and 'origin' ([x, z] metres)")
    remap = np.array([class_index(classes, n) for n in names] + [-1])
    sem = remap[labels]  # -1 stays -1 (last entry)
    walk = (np.asarray(Image.open(folder / "walkable.png").convert("L")) > 127) if (folder / "walkable.png").exists() \
        else sem >= 0
    if walk.shape != sem.shape:
        raise ValueError(f"{folder}: walkable.png {walk.shape} and labels.png {sem.shape} differ in size")
    if (folder / "instances.png").exists():
        inst = read_instance_png(folder / "instances.png", min_pixels=1)
    else:
        inst = np.full(sem.shape, -1, np.int32)
        n = 0
        for k in np.unique(sem[sem >= 0]):
            lab, m = ndimage.label(sem == k)
            inst[lab > 0] = lab[lab > 0] - 1 + n
            n += m
    rooms = np.where(sem >= 0, inst, -1).astype(np.int32)
    inst_cls = np.array([int(np.bincount(sem[(rooms == i) & (sem >= 0)]).argmax()) for i in range(rooms.max() + 1)])
    grid = GridMap(walk, float(meta["resolution"]), tuple(meta["origin"]))
    return Scene(house_id or folder.name, grid, rooms, np.where(walk, rooms, -1).astype(np.int32), inst_cls,
                 [f"room|{i}" for i in range(len(inst_cls))], tuple(classes))


def import_instance_map(instances_png: Path, colour_classes: dict[str, str], resolution: float,
                        origin: tuple[float, float], out: Path, classes: Sequence[str] = PAPER_CLASSES) -> Path:
    """Convert an instance-coloured map + colour->class JSON into the annotation layout."""
    inst, colors = read_instance_png(instances_png, min_pixels=1, return_colors=True)
    lut = {}
    for key, cls in colour_classes.items():
        h = key.lstrip("#")
        lut[(int(h[0:2], 16), int(h[2:4], 16), int(h[4:6], 16))] = class_index(classes, cls)
    labels = np.full(inst.shape, -1, np.int32)
    for i, c in enumerate(colors):
        if tuple(int(v) for v in c) not in lut:
            raise ValueError(f"{instances_png}: room colour #{int(c[0]):02x}{int(c[1]):02x}{int(c[2]):02x} has no class "
                             "in the colour JSON")
        labels[inst == i] = lut[tuple(int(v) for v in c)]
    out.mkdir(parents=True, exist_ok=True)
    write_label_png(out / "labels.png", labels, classes, resolution=resolution, origin=origin, legend=False)
    Image.open(instances_png).convert("RGB").save(out / "instances.png")
    atomic_write_text(out / "SOURCE.txt", f"imported from {instances_png}\n")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="convert room annotations into roomseg-bench's layout")
    sub = ap.add_subparsers(dest="cmd", required=True)
    i = sub.add_parser("import")
    i.add_argument("--instances", type=Path, required=True, help="instance-coloured PNG (black = outside)")
    i.add_argument("--classes", type=Path, required=True, help='JSON {"#rrggbb": "kitchen", ...}')
    i.add_argument("--resolution", type=float, required=True, help="metres per pixel")
    i.add_argument("--origin", type=float, nargs=2, required=True, metavar=("X", "Z"))
    i.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    print(import_instance_map(a.instances, json.loads(a.classes.read_text()), a.resolution, tuple(a.origin), a.out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
