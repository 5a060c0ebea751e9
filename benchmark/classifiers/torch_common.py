"""Shared torch helpers for the image classifiers: lazy imports, devices and dtypes,
transforms, batching, image-item datasets and checkpoints. Nothing here imports torch at
module import time, so the core installs and runs without it."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)
INSTALL_HINT = ("pip install -e '.[models]' in the checkout (the roomseg-bench[models] extra; make setup-test "
                "installs it with torch pinned, make setup installs no torch)")


def require_torch():
    """Import and return torch (and check torchvision), or raise one line saying what to install."""
    try:
        import torch  # noqa: PLC0415
        import torchvision  # noqa: F401, PLC0415
    except ImportError:
        raise ImportError(f"the image classifiers need torch and torchvision: {INSTALL_HINT}") from None
    return torch


def require_transformers(what: str):
    """Import and return transformers, or raise one line naming ``what`` needs it."""
    try:
        import transformers  # noqa: PLC0415
    except ImportError:
        raise ImportError(f"{what} needs transformers: {INSTALL_HINT}") from None
    return transformers


def pick_device(device: str = "auto") -> str:
    """``auto`` -> ``cuda`` when a GPU is there, else ``cpu``; an explicit ``cuda[:i]``
    without a GPU is a one-line error."""
    torch = require_torch()
    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if not isinstance(device, str) or not (device == "cpu" or device == "mps" or device.startswith("cuda")):
        raise ValueError(f"device must be auto, cpu, mps or cuda[:i], got {device!r}")
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise RuntimeError(f"device {device!r} asked for, but no CUDA GPU is available (use device=cpu or auto)")
    return device


def resolve_dtype(dtype: str, device: str):
    """A torch dtype from a config string. ``auto``: float32 off CUDA (full precision),
    bfloat16 on a CUDA GPU that supports it, else float16."""
    torch = require_torch()
    table = {"float32": torch.float32, "float16": torch.float16, "bfloat16": torch.bfloat16}
    if dtype == "auto":
        if not device.startswith("cuda"):
            return torch.float32
        return torch.bfloat16 if torch.cuda.is_bf16_supported() else torch.float16
    if dtype not in table:
        raise ValueError(f"dtype must be auto, float32, float16 or bfloat16, got {dtype!r}")
    return table[dtype]


def eval_transform(image_size: int = 224):
    """(H, W, 3) uint8 -> (3, S, S) float: resize the short side to S * 256/224, centre crop
    S x S pixels, ImageNet normalisation (torchvision transforms v2)."""
    require_torch()
    import torch  # noqa: PLC0415
    from torchvision.transforms import v2  # noqa: PLC0415

    return v2.Compose([v2.ToImage(), v2.Resize(int(round(image_size * 256 / 224)), antialias=True),
                       v2.CenterCrop(image_size), v2.ToDtype(torch.float32, scale=True),
                       v2.Normalize(IMAGENET_MEAN, IMAGENET_STD)])


def train_transform(image_size: int = 224, degrees: float = 15.0, distortion: float = 0.2):
    """The paper's augmentation: random rotation (+-``degrees``), perspective (``distortion``
    0..1, half the time), random resized crop to S x S pixels, horizontal flip; ImageNet
    normalisation."""
    require_torch()
    import torch  # noqa: PLC0415
    from torchvision.transforms import v2  # noqa: PLC0415

    return v2.Compose([v2.ToImage(), v2.RandomRotation(degrees), v2.RandomPerspective(distortion, p=0.5),
                       v2.RandomResizedCrop(image_size, scale=(0.6, 1.0), antialias=True),
                       v2.RandomHorizontalFlip(), v2.ToDtype(torch.float32, scale=True),
                       v2.Normalize(IMAGENET_MEAN, IMAGENET_STD)])


def check_image(img: Any, where: str) -> np.ndarray:
    """``img`` as an (H, W, 3) uint8 array, or a ValueError naming ``where``."""
    arr = np.asarray(img)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"{where}: image must be (H, W, 3) RGB, got shape {arr.shape}")
    if arr.dtype != np.uint8:
        raise ValueError(f"{where}: image must be uint8 RGB, got dtype {arr.dtype}")
    return arr


def images_of(observations: Sequence) -> list[np.ndarray]:
    """The RGB frames of the observations; a view without one is an error naming its index."""
    out = []
    for i, o in enumerate(observations):
        img = getattr(o, "image", None)
        if img is None:
            raise ValueError(f"observation {i} has no image: image classifiers need a simulator renderer "
                             "(renderer=ai2thor|habitat) or a render cache with images")
        out.append(check_image(img, f"observation {i}"))
    return out


def batches(items: Sequence[Any], size: int) -> Iterator[Sequence[Any]]:
    """Consecutive slices of at most ``size`` items."""
    if size < 1:
        raise ValueError(f"batch size must be >= 1, got {size}")
    for i in range(0, len(items), size):
        yield items[i:i + size]


def load_item_image(x: Any) -> np.ndarray:
    """An item's image: an (H, W, 3) uint8 array as is, or an image file read as RGB."""
    if isinstance(x, np.ndarray):
        return check_image(x, "image array")
    from PIL import Image  # noqa: PLC0415

    with Image.open(x) as im:
        return np.array(im.convert("RGB"))  # a writable copy


class ItemDataset:
    """Map-style dataset over (image path or array, class index) items for a torch
    DataLoader: ``transform(image)`` and the label, or the raw uint8 image when
    ``transform`` is None."""

    def __init__(self, items: Sequence[tuple[Any, int]], transform=None):
        self.items, self.transform = list(items), transform

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i: int):
        x, k = self.items[i]
        img = load_item_image(x)
        return (self.transform(img) if self.transform is not None else img), int(k)


def _as_list(batch: list) -> list:
    return batch


def image_chunks(items: Sequence[tuple[Any, int]], chunk: int, workers: int = 0) -> Iterator[list[np.ndarray]]:
    """The items' raw images in order, ``chunk`` at a time, decoded by ``workers`` processes
    (0: in this process). Keeps only one chunk (plus prefetch) in memory."""
    torch = require_torch()
    loader = torch.utils.data.DataLoader(ItemDataset(items), batch_size=chunk, shuffle=False,
                                         num_workers=workers, collate_fn=_as_list)
    for batch in loader:
        yield [img for img, _ in batch]


def save_checkpoint(path: str | Path, model, classes: Sequence[str], extra: dict | None = None) -> None:
    """Save weights, the class list and ``extra`` (architecture, epoch, ...) atomically."""
    torch = require_torch()
    import io  # noqa: PLC0415

    from envs.atomic import atomic_write_bytes  # noqa: PLC0415

    buf = io.BytesIO()
    torch.save({"state_dict": model.state_dict(), "classes": list(classes), "extra": extra or {}}, buf)
    atomic_write_bytes(path, buf.getvalue())


def load_checkpoint(path: str | Path, model, classes: Sequence[str], expect: dict | None = None) -> dict:
    """Load weights saved by :func:`save_checkpoint` into ``model``; the class list and the
    ``expect`` entries of its ``extra`` (e.g. ``{"arch": "resnet50"}``) must match.
    Returns ``extra``."""
    torch = require_torch()
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint not found: {path} (train one with python -m benchmark.commands.train)")
    try:
        ck = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:
        raise ValueError(f"checkpoint {path} could not be read ({type(e).__name__}: {str(e)[:200]})") from None
    if not isinstance(ck, dict) or "state_dict" not in ck or "classes" not in ck:
        raise ValueError(f"checkpoint {path} is not one of ours (expected state_dict and classes)")
    if list(ck["classes"]) != list(classes):
        raise ValueError(f"checkpoint {path} was trained for classes {ck['classes']}, not {list(classes)}")
    extra = ck.get("extra", {}) or {}
    for k, v in (expect or {}).items():
        if k in extra and extra[k] != v:
            raise ValueError(f"checkpoint {path} has {k}={extra[k]!r}, the config asks for {v!r}")
    model.load_state_dict(ck["state_dict"])
    return extra
