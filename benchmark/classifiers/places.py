"""The Places-2 (Places365) 7-class subset and its seeded split.

Two layouts are read: a Places365 image root (``data_256/`` or ``data_large/`` of
Places365-Standard, categories as ``b/bedroom/…``), mapped to our classes by
:data:`PLACES_CATEGORIES`; or an ImageFolder with one sub-folder per class name. The
paper's split is 28,000 / 3,500 / 3,500 images: 4,000 / 500 / 500 per class, drawn with a
fixed seed (``split``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

#: Places365 categories (folder paths under the image root) behind each room class.
PLACES_CATEGORIES: dict[str, list[str]] = {
    "balcony": ["b/balcony/exterior", "b/balcony/interior"],
    "bathroom": ["b/bathroom"],
    "bedroom": ["b/bedroom"],
    "corridor": ["c/corridor"],
    "dining_room": ["d/dining_room"],
    "kitchen": ["k/kitchen"],
    "living_room": ["l/living_room"],
}
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")


def list_images(root: str | Path, classes: Sequence[str], places365: bool = False) -> dict[str, list[Path]]:
    """Image paths per class (sorted), from a Places365 root or an ImageFolder."""
    root = Path(root)
    if not root.is_dir():
        raise FileNotFoundError(f"image folder not found: {root}")
    out = {}
    for c in classes:
        folders = [root / f for f in PLACES_CATEGORIES.get(c, [])] if places365 else [root / c]
        files = sorted(p for f in folders if f.is_dir() for p in f.rglob("*") if p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            where = ", ".join(str(f) for f in folders) or f"(no Places365 category for {c!r})"
            raise FileNotFoundError(f"no images for class {c!r} in {where}")
        out[c] = files
    return out


def split(images: dict[str, list[Path]], classes: Sequence[str], n_train: int = 4000, n_val: int = 500,
          n_test: int = 500, seed: int = 0) -> dict[str, list[tuple[Path, int]]]:
    """Seeded per-class split -> {"train"|"val"|"test": [(path, class index), ...]}.
    A class with fewer images than asked gives what it has, in the same proportions."""
    rng = np.random.default_rng(seed)
    out: dict[str, list[tuple[Path, int]]] = {"train": [], "val": [], "test": []}
    want = n_train + n_val + n_test
    for k, c in enumerate(classes):
        files = list(images[c])
        order = rng.permutation(len(files))
        n = min(want, len(files))
        a = int(round(n * n_train / want))
        b = a + int(round(n * n_val / want))
        chosen = [files[i] for i in order[:n]]
        out["train"] += [(p, k) for p in chosen[:a]]
        out["val"] += [(p, k) for p in chosen[a:b]]
        out["test"] += [(p, k) for p in chosen[b:n]]
    return out


def load_rgb(path: Path) -> np.ndarray:
    from PIL import Image  # noqa: PLC0415

    return np.asarray(Image.open(path).convert("RGB"))
