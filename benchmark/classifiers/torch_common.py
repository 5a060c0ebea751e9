"""Shared torch helpers for the image classifiers: lazy imports, devices, transforms,
batching and checkpoints. Nothing here imports torch at module import time."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


def require_torch():
    """Import torch, or raise one line saying what to install."""
    try:
        import torch  # noqa: PLC0415
        import torchvision  # noqa: F401, PLC0415
    except ImportError:
        raise ImportError("the image classifiers need torch and torchvision: "
                          "pip install 'roomseg-bench[models]' (or make setup)") from None
    return torch


def pick_device(device: str = "auto") -> str:
    """``auto`` -> cuda when available, else cpu; an explicit cuda without a GPU is an error."""
    torch = require_torch()
    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise RuntimeError(f"device {device!r} asked for, but no CUDA GPU is available (use device=cpu or auto)")
    return device


def eval_transform(image_size: int = 224):
    """Resize, centre crop, ImageNet normalisation (torchvision transforms v2)."""
    require_torch()
    import torch  # noqa: PLC0415
    from torchvision.transforms import v2  # noqa: PLC0415

    return v2.Compose([v2.ToImage(), v2.Resize(int(round(image_size * 256 / 224)), antialias=True),
                       v2.CenterCrop(image_size), v2.ToDtype(torch.float32, scale=True),
                       v2.Normalize(IMAGENET_MEAN, IMAGENET_STD)])


def train_transform(image_size: int = 224, degrees: float = 15.0, distortion: float = 0.2):
    """The paper's augmentation: rotation, perspective, random resized crop, horizontal flip."""
    require_torch()
    import torch  # noqa: PLC0415
    from torchvision.transforms import v2  # noqa: PLC0415

    return v2.Compose([v2.ToImage(), v2.RandomRotation(degrees), v2.RandomPerspective(distortion, p=0.5),
                       v2.RandomResizedCrop(image_size, scale=(0.6, 1.0), antialias=True),
                       v2.RandomHorizontalFlip(), v2.ToDtype(torch.float32, scale=True),
                       v2.Normalize(IMAGENET_MEAN, IMAGENET_STD)])


def images_of(observations: Sequence) -> list[np.ndarray]:
    """The RGB frames of the observations; a view without one is an error naming it."""
    out = []
    for i, o in enumerate(observations):
        img = getattr(o, "image", None)
        if img is None:
            raise ValueError(f"observation {i} has no image: image classifiers need a simulator renderer "
                             "(renderer=ai2thor|habitat) or a render cache with images")
        img = np.asarray(img)
        if img.ndim != 3 or img.shape[2] != 3:
            raise ValueError(f"observation {i}: image must be (H, W, 3) RGB, got shape {img.shape}")
        out.append(img)
    return out


def batches(items: Sequence[Any], size: int) -> Iterator[Sequence[Any]]:
    if size < 1:
        raise ValueError(f"batch size must be >= 1, got {size}")
    for i in range(0, len(items), size):
        yield items[i:i + size]


def save_checkpoint(path: str | Path, model, classes: Sequence[str], extra: dict | None = None) -> None:
    """Save weights + class list atomically."""
    torch = require_torch()
    import io  # noqa: PLC0415

    from envs.atomic import atomic_write_bytes  # noqa: PLC0415

    buf = io.BytesIO()
    torch.save({"state_dict": model.state_dict(), "classes": list(classes), "extra": extra or {}}, buf)
    atomic_write_bytes(path, buf.getvalue())


def load_checkpoint(path: str | Path, model, classes: Sequence[str]) -> dict:
    """Load weights saved by :func:`save_checkpoint`; the class lists must match."""
    torch = require_torch()
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"checkpoint not found: {path} (train one with python -m benchmark.classifiers.train)")
    ck = torch.load(path, map_location="cpu", weights_only=True)
    if list(ck["classes"]) != list(classes):
        raise ValueError(f"checkpoint {path} was trained for classes {ck['classes']}, not {list(classes)}")
    model.load_state_dict(ck["state_dict"])
    return ck.get("extra", {})
