"""Opening map-like images: the one place every reader of occupancy maps, ground truth, label
and instance PNGs and external predictions opens an image file.

An image header declares the image's size; decoding allocates it. A header declaring
100000 x 100000 pixels is a few bytes on disk and 10 GB (grey) to 30 GB (colour) once
decoded. :func:`open_image` reads the header (Pillow opens images lazily) and checks the
declared size against the map-size limit *before* anything is decoded: over the limit is
one line naming the file, the size and the limit (a ``ValueError``, which the commands
report as exit status 2 and a sweep as that map's failure). Pillow's own decompression-bomb
check (``PIL.Image.MAX_IMAGE_PIXELS``, an error above 179 M pixels) is never what the user
sees: an image Pillow refuses is re-read header-only to name its size in the same line.

The limit is :data:`envs.maps.scene.MAX_MAP_PIXELS` (20 M pixels, about 223 x 223 m at
0.05 m/px) unless the caller passes another (``env.max_map_pixels``, ``max_map_pixels=``
of ``roomseg-segment``); ``None`` is no limit.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from PIL import Image

from envs.maps.scene import MAX_MAP_PIXELS, check_max_map_pixels

#: Held while Pillow's own size check is switched off to read a refused header.
_PIL_CHECK_LOCK = threading.Lock()


def _declared_size_unchecked(path: Path) -> tuple[int, int]:
    """(width, height) from the header of an image Pillow's own check refused to open."""
    with _PIL_CHECK_LOCK:
        saved = Image.MAX_IMAGE_PIXELS
        Image.MAX_IMAGE_PIXELS = None
        try:
            with Image.open(path) as img:
                return img.size
        finally:
            Image.MAX_IMAGE_PIXELS = saved


def _too_big(path: Path, what: str, size: tuple[int, int], limit: int) -> ValueError:
    w, h = size
    return ValueError(f"{path}: {what} declares {w} x {h} = {w * h} pixels, over the map-size limit of {limit} "
                      f"pixels (max_map_pixels); expected a smaller image, or raise max_map_pixels")


@contextmanager
def open_image(path: str | Path, what: str = "the image", max_pixels: int | None = MAX_MAP_PIXELS
               ) -> Iterator[Image.Image]:
    """Open an image with its declared size checked against ``max_pixels`` before decoding.

    Args:
        path: the image file.
        what: whose image it is, for the error lines (``"the ground-truth image"``).
        max_pixels: the largest width x height accepted; ``None``: no limit.

    Yields:
        The opened, not yet decoded ``PIL.Image.Image`` (closed on leaving the block).

    Raises:
        FileNotFoundError: ``path`` does not exist (one line naming it).
        ValueError: one line naming the file: over the limit (with the declared size and
            the limit), or not readable as an image.
    """
    path = Path(path).expanduser()
    limit = check_max_map_pixels(max_pixels)
    if not path.is_file():
        raise FileNotFoundError(f"{what} not found: {path}")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            img = Image.open(path)
    except Image.DecompressionBombError:
        size = _declared_size_unchecked(path)
        if limit is not None and size[0] * size[1] > limit:
            raise _too_big(path, what, size, limit) from None
        # a larger limit than Pillow's, chosen by the caller: open without Pillow's check
        with _PIL_CHECK_LOCK:
            saved = Image.MAX_IMAGE_PIXELS
            Image.MAX_IMAGE_PIXELS = None
            try:
                img = Image.open(path)
            finally:
                Image.MAX_IMAGE_PIXELS = saved
    except OSError as e:
        raise ValueError(f"{path}: cannot read {what} ({e})") from None
    with img:
        if limit is not None and img.size[0] * img.size[1] > limit:
            raise _too_big(path, what, img.size, limit)
        yield img


def image_size(path: str | Path, what: str = "the image", max_pixels: int | None = MAX_MAP_PIXELS
               ) -> tuple[int, int]:
    """(width, height) in pixels from the header, checked as :func:`open_image` does."""
    with open_image(path, what, max_pixels) as img:
        return img.size


def read_image(path: str | Path, what: str = "the image", mode: str | None = None,
               max_pixels: int | None = MAX_MAP_PIXELS) -> np.ndarray:
    """Decode an image after its size check (:func:`open_image`).

    Args:
        path: the image file.
        what: whose image it is, for the error lines.
        mode: a Pillow mode to convert to (``"RGB"``, ``"L"``, ...), or None to keep the
            file's own (a 16-bit grey PNG stays 16-bit).
        max_pixels: the largest width x height accepted; ``None``: no limit.

    Returns:
        The pixels: (H, W) or (H, W, C) array of the mode's dtype (uint8 for L/RGB/RGBA,
        uint16 for 16-bit grey, int32 for mode I).

    Raises:
        FileNotFoundError / ValueError: as :func:`open_image`; also a file whose pixel data
        is truncated or corrupt (one line naming it).
    """
    with open_image(path, what, max_pixels) as img:
        try:
            if mode is not None and img.mode != mode:
                return np.asarray(img.convert(mode))
            img.load()
            return np.asarray(img)
        except OSError as e:
            raise ValueError(f"{Path(path)}: cannot read {what} ({e})") from None


__all__ = ["image_size", "open_image", "read_image"]
