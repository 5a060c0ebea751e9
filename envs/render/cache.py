"""The render cache: observations of one house on disk, in a layout any renderer shares.

One folder per house (so a cache rendered on a GPU box can be copied to a laptop)::

    <folder>/poses.csv           index, x, z, yaw (metres, degrees), refused, image
    <folder>/observations.jsonl  one JSON object per view: objects [[type, amount], ...],
                                 visible_classes [...] or null, meta {...}
    <folder>/images/000123.png   RGB frames (simulators only)
    <folder>/COMPLETE            written last; a folder without it is ignored. Its first line
                                 is the number of views, then one ``<sha256> <file>`` line per
                                 file above: every read checks the files it reads against
                                 them, so a damaged render is refused, never used

Floats are written with ``repr`` precision, so a round trip gives equal observations.
Paths inside are relative, so a folder can be copied anywhere (a cache rendered on a GPU
box is swept on a laptop by copying it into the same place under ``results/cache/render``).
Writes go to a temporary sibling folder that is renamed into place; an older render is
moved aside first and removed last, so an interrupted write never leaves a half folder
that looks complete. Refused views (``meta["refused"]``) are kept, with no image; a render
in which every view was refused (what a house that failed to load looks like) is not
written at all, so it is never marked complete and the next run renders it again.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from PIL import Image

from envs.atomic import ordinary_temp_dir
from envs.render.observation import Observation

MARKER = "COMPLETE"
#: the render's poses table (every view's pose and whether it was refused)
POSES_FILE = "poses.csv"


def is_complete(folder: str | Path) -> bool:
    """True if ``folder`` holds a finished render."""
    return (Path(folder) / MARKER).exists()


def write_observations(folder: str | Path, observations: Sequence[Observation]) -> None:
    """Write ``observations`` to ``folder`` atomically (replacing an older render).

    Raises:
        ValueError: every one of the observations was refused (nothing is written: a failed
            load is retried by the next run, never cached as a result).
    """
    folder = Path(folder)
    if observations and all(o.meta.get("refused", False) for o in observations):
        first = str(observations[0].meta.get("error", "")).strip()[:200]
        raise ValueError(f"every one of {len(observations)} views was refused by the renderer (first: {first!r}); "
                         f"not cached in {folder}, the next run renders it again")
    # every file in memory first (its checksum from the same bytes), each written once
    lines = ["index,x,z,yaw,refused,image"]
    jsonl = []
    files: dict[str, bytes] = {}
    for i, o in enumerate(observations):
        image = ""
        if o.image is not None:
            img = np.asarray(o.image)
            if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
                raise ValueError(f"observation {i}: image must be (H, W, 3) uint8, got {img.shape} {img.dtype}")
            image = f"images/{i:06d}.png"
            buf = io.BytesIO()
            Image.fromarray(img).save(buf, format="PNG")
            files[image] = buf.getvalue()
        x, z, yaw = (float(v) for v in o.pose)
        lines.append(f"{i},{x!r},{z!r},{yaw!r},{int(bool(o.meta.get('refused', False)))},{image}")
        vis = None if o.visible_classes is None else np.asarray(o.visible_classes).astype(np.float64).tolist()
        jsonl.append(_ENCODER.encode({"objects": [[str(t), float(a)] for t, a in o.objects],
                                      "visible_classes": vis, "meta": o.meta}) + "\n")
    files["observations.jsonl"] = "".join(jsonl).encode("utf-8")
    files[POSES_FILE] = ("\n".join(lines) + "\n").encode("utf-8")
    marker = f"{len(observations)}\n" + "".join(f"{_digest(files[f])} {f}\n" for f in sorted(files))
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = ordinary_temp_dir(folder.parent, "." + folder.name + ".")  # the entry gets an ordinary folder's mode
    try:
        if any(f.startswith("images/") for f in files):
            (tmp / "images").mkdir()
        for f, data in files.items():
            (tmp / f).write_bytes(data)
        (tmp / MARKER).write_text(marker)
        old = None
        if folder.exists():
            old = Path(tempfile.mkdtemp(prefix="." + folder.name + ".old.", dir=folder.parent))
            os.replace(folder, old / "render")
        os.rename(tmp, folder)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _plain(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"observation meta value of type {type(o).__name__} is not JSON serialisable")


#: ``json.dumps(obj, default=_plain)``'s encoder, made once (``dumps`` makes one per call)
_ENCODER = json.JSONEncoder(default=_plain)


def _digest(data: bytes) -> str:
    """A file's checksum in the ``COMPLETE`` marker: the SHA-256 of its bytes, in hex."""
    return hashlib.sha256(data).hexdigest()


def _manifest(folder: Path) -> tuple[int, dict[str, str]]:
    """(number of views, {file: sha256}) from the folder's ``COMPLETE`` marker.

    Raises:
        ValueError: a marker without checksums (an older render) or a malformed one."""
    lines = (folder / MARKER).read_text().splitlines()
    sums = dict(reversed(ln.split(" ", 1)) for ln in lines[1:] if ln.strip())
    if not lines or not lines[0].strip().isdigit() or not sums:
        raise ValueError(f"{folder}: the render has no checksums ({MARKER} written by an older version): "
                         f"it is rendered again")
    return int(lines[0]), sums


def _read_checked(folder: Path, name: str, sums: dict[str, str]) -> bytes:
    """The bytes of ``folder/name`` after checking them against the render's checksum."""
    data = (folder / name).read_bytes()
    if name not in sums or _digest(data) != sums[name]:
        raise ValueError(f"{folder / name}: content does not match the render's checksum: the render is damaged")
    return data


def read_observations(folder: str | Path, images: bool = True) -> list[Observation]:
    """Observations written by :func:`write_observations` (``images=False`` skips frames),
    every file read checked against the render's checksums.

    Raises:
        FileNotFoundError: no complete render.
        ValueError: a damaged render (one line naming the file)."""
    folder = Path(folder)
    if not is_complete(folder):
        raise FileNotFoundError(f"no complete render in {folder}")
    n, sums = _manifest(folder)
    rows = _read_checked(folder, POSES_FILE, sums).decode("utf-8").splitlines()[1:]
    recs = [json.loads(line) for line in _read_checked(folder, "observations.jsonl", sums).decode("utf-8").splitlines()]
    if len(rows) != len(recs) or n != len(rows):
        raise ValueError(f"{folder}: poses.csv has {len(rows)} views, observations.jsonl {len(recs)}, "
                         f"{MARKER} says {n}: the render is damaged, delete the folder to render it again")
    out = []
    for row, rec in zip(rows, recs):
        _, x, z, yaw, _, image = row.split(",", 5)
        img = (np.array(Image.open(io.BytesIO(_read_checked(folder, image, sums))).convert("RGB"))
               if (image and images) else None)
        vis = rec.get("visible_classes")
        out.append(Observation(pose=(float(x), float(z), float(yaw)), image=img,
                               objects=[(str(t), float(a)) for t, a in rec.get("objects", [])],
                               visible_classes=None if vis is None else np.asarray(vis, dtype=np.float64),
                               meta=rec.get("meta", {})))
    return out


def poses_table(observations: Sequence[Observation]) -> tuple[np.ndarray, np.ndarray]:
    """The poses table a render of ``observations`` holds (:func:`read_poses` of the folder
    :func:`write_observations` wrote them to, equal bit for bit: a pose is written as the
    shortest text that reads back as the same float): poses (N, 3) and refused (N,) bool."""
    poses = np.array([o.pose for o in observations], dtype=float).reshape(-1, 3)
    return poses, np.array([bool(o.meta.get("refused", False)) for o in observations], dtype=bool)


def read_poses(folder: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """The poses table of a render: poses (N, 3) [x, z, yaw_deg] and refused (N,) bool.

    Raises:
        FileNotFoundError: no complete render.
        ValueError: a damaged render."""
    folder = Path(folder)
    if not is_complete(folder):
        raise FileNotFoundError(f"no complete render in {folder}")
    _, sums = _manifest(folder)
    rows = [r.split(",", 5) for r in _read_checked(folder, POSES_FILE, sums).decode("utf-8").splitlines()[1:]]
    poses = np.array([[float(r[1]), float(r[2]), float(r[3])] for r in rows], dtype=float).reshape(-1, 3)
    return poses, np.array([r[4] == "1" for r in rows], dtype=bool)
