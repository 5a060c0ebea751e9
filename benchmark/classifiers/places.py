"""The Places-2 (Places365) 7-class subset and its seeded split.

Three layouts are read:

- a **torchvision Places365 root** (``places365=True`` and ``categories_places365.txt`` in
  the folder): ``torchvision.datasets.Places365(root, split="train-standard", small=True,
  download=False)`` gives the file list and category names;
- a **Places365 image folder** (``places365=True``, e.g. the extracted ``data_256/``),
  categories as sub-folders ``b/bedroom/...``;
- an **ImageFolder** with one sub-folder per class name (``places365=False``).

Places365 categories map onto our classes by :data:`PLACES_CATEGORIES` (both balcony
categories become ``balcony``). The paper's split is 28,000 / 3,500 / 3,500 images; we
draw it per class, 4,000 / 500 / 500, with a fixed seed (:func:`split`), from the
Places365-Standard training images (up to 5,000 per category).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

#: Places365 categories (as in ``categories_places365.txt``, without the leading ``/``)
#: behind each room class.
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
#: The paper's per-class split sizes (7 classes: 28,000 / 3,500 / 3,500 images).
PAPER_SPLIT = (4000, 500, 500)


def _categories(c: str) -> list[str]:
    if c not in PLACES_CATEGORIES:
        raise ValueError(f"class {c!r} has no Places365 category in PLACES_CATEGORIES "
                         f"(known: {sorted(PLACES_CATEGORIES)}); use an ImageFolder with a {c}/ folder instead")
    return PLACES_CATEGORIES[c]


def _from_torchvision(root: Path, classes: Sequence[str]) -> dict[str, list[Path]]:
    """Image paths per class from torchvision's Places365 file list (no download)."""
    from benchmark.classifiers.torch_common import require_torch  # noqa: PLC0415

    require_torch()
    from torchvision.datasets import Places365  # noqa: PLC0415

    try:
        ds = Places365(str(root), split="train-standard", small=True, download=False)
    except RuntimeError as e:
        raise FileNotFoundError(f"torchvision Places365 at {root}: {str(e).splitlines()[0]}") from None
    wanted = {}
    for c in classes:
        for cat in _categories(c):
            wanted["/" + cat] = c
    idx_to_class = {ds.class_to_idx[name]: c for name, c in wanted.items() if name in ds.class_to_idx}
    out: dict[str, list[Path]] = {c: [] for c in classes}
    for path, idx in ds.imgs:
        if idx in idx_to_class:
            out[idx_to_class[idx]].append(Path(path))
    for c in classes:
        if not out[c]:
            raise FileNotFoundError(f"no images for class {c!r} in the Places365 file list under {root}")
        out[c].sort()
        if not out[c][0].exists():
            raise FileNotFoundError(f"Places365 image {out[c][0]} is missing: extract "
                                    f"train_256_places365standard.tar under {root} (torchvision expects {ds.images_dir})")
    return out


def list_images(root: str | Path, classes: Sequence[str], places365: bool = False) -> dict[str, list[Path]]:
    """Image paths per class (sorted): from a torchvision Places365 root or a Places365
    image folder (``places365``), or from an ImageFolder with one folder per class."""
    root = Path(root)
    if not root.is_dir():
        raise FileNotFoundError(f"image folder not found: {root}")
    if places365 and (root / "categories_places365.txt").is_file():
        return _from_torchvision(root, classes)
    out = {}
    for c in classes:
        folders = [root / f for f in _categories(c)] if places365 else [root / c]
        files = sorted(p for f in folders if f.is_dir() for p in f.rglob("*") if p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise FileNotFoundError(f"no images for class {c!r} in {', '.join(str(f) for f in folders)}")
        out[c] = files
    return out


def split(images: dict[str, list[Path]], classes: Sequence[str], n_train: int = PAPER_SPLIT[0],
          n_val: int = PAPER_SPLIT[1], n_test: int = PAPER_SPLIT[2], seed: int = 0) -> dict[str, list[tuple[Path, int]]]:
    """Seeded per-class split -> {"train"|"val"|"test": [(path, class index), ...]}: each
    class draws ``n_train + n_val + n_test`` images without replacement. A class with fewer
    images gives what it has, in the same proportions. Same seed and files -> same split."""
    if min(n_train, n_val, n_test) < 0 or n_train + n_val + n_test == 0:
        raise ValueError(f"split sizes must be >= 0 and not all 0, got {n_train}/{n_val}/{n_test}")
    rng = np.random.default_rng(seed)
    out: dict[str, list[tuple[Path, int]]] = {"train": [], "val": [], "test": []}
    want = n_train + n_val + n_test
    for k, c in enumerate(classes):
        files = sorted(images[c])
        order = rng.permutation(len(files))
        n = min(want, len(files))
        a = int(round(n * n_train / want))
        b = a + int(round(n * n_val / want))
        chosen = [files[i] for i in order[:n]]
        out["train"] += [(p, k) for p in chosen[:a]]
        out["val"] += [(p, k) for p in chosen[a:b]]
        out["test"] += [(p, k) for p in chosen[b:n]]
    return out


def load_rgb(path: str | Path) -> np.ndarray:
    """An image file as an (H, W, 3) uint8 RGB array."""
    from benchmark.classifiers.torch_common import load_item_image  # noqa: PLC0415

    return load_item_image(Path(path))
