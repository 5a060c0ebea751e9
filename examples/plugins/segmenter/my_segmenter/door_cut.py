"""A segmenter of your own: rooms are what stays apart when the doorways are closed.

The walkable area is eroded by a disk of diameter ``door_width_m``, which closes every gap
narrower than that (doorways); each connected part left of at least ``min_area_m2`` is a
room's seed, and the seeds grow back over the walkable area by watershed on the distance
to obstacles. A simplified version of the bundled ``morphological`` segmenter, which tries
a whole range of erosions: here there is one, set in metres.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from skimage.morphology import disk
from skimage.segmentation import watershed


class DoorCut:
    """Close doorways, label what stays apart, grow it back.

    Args:
        door_width_m: gaps narrower than this (metres) are closed.
        min_area_m2: seeds smaller than this (m²) are dropped (their pixels join a neighbour).
    """

    def __init__(self, door_width_m: float = 1.0, min_area_m2: float = 1.0):
        for key, v in (("door_width_m", door_width_m), ("min_area_m2", min_area_m2)):
            if isinstance(v, bool) or not isinstance(v, int | float) or not v > 0:
                raise ValueError(f"segmenter.{key}={v!r}: expected a number > 0")
        self.door_width_m = float(door_width_m)
        self.min_area_m2 = float(min_area_m2)

    def __call__(self, grid) -> np.ndarray:
        """(H, W) int32 room ids 0..R-1 on walkable cells, -1 elsewhere (``grid.walkable``,
        ``grid.resolution`` in m/px)."""
        free = np.asarray(grid.walkable, bool)
        radius_px = max(1, int(round(self.door_width_m / 2 / grid.resolution)))
        seeds, n = ndimage.label(ndimage.binary_erosion(free, structure=disk(radius_px)))
        sizes = np.bincount(seeds.ravel(), minlength=n + 1) * grid.resolution**2
        keep = np.nonzero(sizes[1:] >= self.min_area_m2)[0] + 1
        out = np.full(free.shape, -1, dtype=np.int32)
        if len(keep) == 0:  # nothing room-sized is left: the walkable area is one room
            out[free] = 0
            return out
        markers = np.zeros(free.shape, dtype=np.int32)
        for new_id, old in enumerate(keep, start=1):
            markers[seeds == old] = new_id
        grown = watershed(-ndimage.distance_transform_edt(free), markers, mask=free)
        out[grown > 0] = grown[grown > 0] - 1
        return out
