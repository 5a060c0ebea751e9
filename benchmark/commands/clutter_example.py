"""``python -m benchmark.commands.clutter_example OUT``: write furnished office maps, each
also without its furniture, in the style of the IPA room-segmentation test maps (white free
space, black walls, furniture in shades of grey, ``rooms_white`` ground truth), then print
the sweeps that segment and score them.

Each map (0.05 m/px, plain PNG, ids ``office_00`` ..):

* rooms on a grid of ``nx`` x ``ny`` (2 x 2 or 3 x 2), 4.0-6.0 m a side, walls 0.1 m
  (black, 0), a 0.9 m door in the wall between neighbouring rooms (every pair of
  neighbours), white (255) floor, a 0.3 m black margin around the building;
* furniture drawn in grey (:data:`DESK` 178 for desks and tables, :data:`GREYS` 192-215 for
  chairs, cupboards and shelves: the levels of real furnished test maps): desks along the
  walls with a chair in front, cupboards against walls, and in rooms of at least 5 x 5 m a
  *desk island*: four desks in a closed ring around a free pocket of about 1.2 x 1.0 m that
  no robot can reach. Nothing stands within 1.0 m of a door;
* ``furnished/<id>.png`` (with furniture), ``empty/<id>.png`` (the same walls, no
  furniture), and the same ``<id>_gt.png`` in both: each room's floor white, walls and a
  black line across each doorway (``gt_format=rooms_white``).

Same seed, same maps (byte for byte). :func:`two_room_office` is the hand-made map of the
tests (two rooms, a desk island in the second).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from PIL import Image

from benchmark.commands import cli

#: Metres per pixel of every map written here.
RESOLUTION = 0.05
#: Grey of desks and tables (the commonest furniture level of real furnished test maps).
DESK = 178
#: Greys of chairs, cupboards and shelves.
GREYS = (192, 200, 205, 211, 215)
WHITE, BLACK = 255, 0
WALL_M, DOOR_M, MARGIN_M, DOOR_CLEAR_M = 0.1, 0.9, 0.3, 1.0


@dataclass
class Office:
    """One map as arrays (row 0 = top; 0.05 m/px).

    Attributes:
        furnished: (H, W) uint8 image with furniture.
        empty: (H, W) uint8 image, the same walls and no furniture.
        gt: (H, W) uint8 ``rooms_white`` ground truth (rooms white, walls and doorway lines black).
        rooms: (H, W) int32 room index of each floor pixel (-1 walls / outside).
        pockets: (H, W) bool, the free cells enclosed by furniture (unreachable).
        n_rooms: number of rooms.
    """

    furnished: np.ndarray
    empty: np.ndarray
    gt: np.ndarray
    rooms: np.ndarray
    pockets: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), bool))
    n_rooms: int = 0


def _px(m: float) -> int:
    return int(round(m / RESOLUTION))


def _building(widths: list[int], heights: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray, list]:
    """Walls and floors of a grid of rooms (pixel sizes). Returns (image, gt, rooms, doors),
    doors as (r0, r1, c0, c1) pixel boxes of each opening."""
    m, w = _px(MARGIN_M), _px(WALL_M)
    cols = np.cumsum([m] + [w + x for x in widths]) .tolist()  # left wall of each room column
    rows = np.cumsum([m] + [w + y for y in heights]).tolist()
    shape = (rows[-1] + w + m, cols[-1] + w + m)
    img = np.full(shape, BLACK, np.uint8)
    rooms = np.full(shape, -1, np.int32)
    k = 0
    boxes = {}
    for j, hy in enumerate(heights):
        for i, wx in enumerate(widths):
            r0, c0 = rows[j] + w, cols[i] + w
            img[r0:r0 + hy, c0:c0 + wx] = WHITE
            rooms[r0:r0 + hy, c0:c0 + wx] = k
            boxes[(i, j)] = (r0, r0 + hy, c0, c0 + wx)
            k += 1
    gt = img.copy()
    doors = []
    d = _px(DOOR_M)
    for (i, j), (r0, r1, c0, c1) in boxes.items():
        if (i + 1, j) in boxes:  # door in the wall to the right, centred on the shared wall
            rr0, rr1 = max(r0, boxes[(i + 1, j)][0]), min(r1, boxes[(i + 1, j)][1])
            mid = (rr0 + rr1) // 2
            doors.append((mid - d // 2, mid - d // 2 + d, c1, c1 + w))
        if (i, j + 1) in boxes:  # door in the wall below
            cc0, cc1 = max(c0, boxes[(i, j + 1)][2]), min(c1, boxes[(i, j + 1)][3])
            mid = (cc0 + cc1) // 2
            doors.append((r1, r1 + w, mid - d // 2, mid - d // 2 + d))
    for r0, r1, c0, c1 in doors:
        img[r0:r1, c0:c1] = WHITE  # gt keeps the doorway black: the line between two rooms
    return img, gt, rooms, doors


def _free_for_furniture(rooms: np.ndarray, doors: list) -> np.ndarray:
    """Floor cells where furniture may stand: not within DOOR_CLEAR_M of a door opening."""
    ok = rooms >= 0
    c = _px(DOOR_CLEAR_M)
    for r0, r1, c0, c1 in doors:
        ok[max(r0 - c, 0):r1 + c, max(c0 - c, 0):c1 + c] = False
    return ok


def _place(img: np.ndarray, allowed: np.ndarray, box: tuple[int, int, int, int], grey: int) -> bool:
    r0, r1, c0, c1 = box
    if r0 < 0 or c0 < 0 or r1 > img.shape[0] or c1 > img.shape[1] or not allowed[r0:r1, c0:c1].all():
        return False
    img[r0:r1, c0:c1] = grey
    allowed[max(r0 - 2, 0):r1 + 2, max(c0 - 2, 0):c1 + 2] = False  # a 0.1 m gap to the next piece
    return True


def desk_island(img: np.ndarray, allowed: np.ndarray, centre: tuple[int, int]) -> np.ndarray | None:
    """Four desks (0.6 m deep) in a closed ring around a 1.2 x 1.0 m free pocket, centred at
    ``centre`` (row, col). Returns the pocket's (H, W) bool mask, or None if it does not fit."""
    t, ph, pw = _px(0.6), _px(1.0), _px(1.2)
    r, c = centre
    r0, c0 = r - ph // 2 - t, c - pw // 2 - t
    r1, c1 = r0 + ph + 2 * t, c0 + pw + 2 * t
    if r0 < 0 or c0 < 0 or r1 > img.shape[0] or c1 > img.shape[1] or not allowed[r0:r1, c0:c1].all():
        return None
    img[r0:r1, c0:c1] = DESK
    img[r0 + t:r1 - t, c0 + t:c1 - t] = WHITE
    pocket = np.zeros(img.shape, bool)
    pocket[r0 + t:r1 - t, c0 + t:c1 - t] = True
    allowed[max(r0 - 2, 0):r1 + 2, max(c0 - 2, 0):c1 + 2] = False
    return pocket


def _furnish_room(img, allowed, box, rng: np.random.Generator, pockets: np.ndarray, tries: int = 40) -> None:
    r0, r1, c0, c1 = box
    h, w = r1 - r0, c1 - c0
    if h >= _px(5.0) and w >= _px(5.0):
        p = desk_island(img, allowed, ((r0 + r1) // 2, (c0 + c1) // 2))
        if p is not None:
            pockets |= p
    dd, dw, ch = _px(0.7), _px(1.4), _px(0.5)
    want, placed = int(rng.integers(2, 5)), 0
    for _ in range(tries):  # desks along the top or bottom wall, a chair in front
        if placed == want:
            break
        c = int(rng.integers(c0, max(c1 - dw, c0 + 1)))
        top = rng.random() < 0.5
        desk = (r0, r0 + dd, c, c + dw) if top else (r1 - dd, r1, c, c + dw)
        if _place(img, allowed, desk, DESK):
            placed += 1
            cr = r0 + dd + 2 if top else r1 - dd - 2 - ch
            _place(img, allowed, (cr, cr + ch, c + dw // 2 - ch // 2, c + dw // 2 + ch - ch // 2),
                   int(rng.choice(GREYS)))
    want, placed = int(rng.integers(1, 4)), 0
    cd, cw = _px(0.5), _px(1.0)
    for _ in range(tries):  # cupboards against the left or right wall
        if placed == want:
            break
        r = int(rng.integers(r0, max(r1 - cw, r0 + 1)))
        box = (r, r + cw, c0, c0 + cd) if rng.random() < 0.5 else (r, r + cw, c1 - cd, c1)
        placed += _place(img, allowed, box, int(rng.choice(GREYS)))


def office(seed: int) -> Office:
    """A seeded furnished office (see the module doc)."""
    rng = np.random.default_rng(seed)
    nx = int(rng.integers(2, 4))
    widths = [_px(float(rng.choice([4.0, 5.0, 6.0]))) for _ in range(nx)]
    heights = [_px(float(rng.choice([4.0, 5.0, 6.0]))) for _ in range(2)]
    empty, gt, rooms, doors = _building(widths, heights)
    img = empty.copy()
    allowed = _free_for_furniture(rooms, doors)
    pockets = np.zeros(img.shape, bool)
    for k in range(int(rooms.max()) + 1):
        rr, cc = np.nonzero(rooms == k)
        _furnish_room(img, allowed, (rr.min(), rr.max() + 1, cc.min(), cc.max() + 1), rng, pockets)
    return Office(img, empty, gt, rooms, pockets, int(rooms.max()) + 1)


def two_room_office() -> Office:
    """The tests' hand-made map: two rooms (5 x 5 m and 6 x 5 m) joined by a 0.9 m door;
    in the first, two desks (178) on the top wall with a chair (211) each and a cupboard
    (200); in the second, a desk island (178) in the top-right corner, a closed ring of
    desks around a 1.2 x 1.0 m pocket, and a cupboard (200) on the bottom wall."""
    empty, gt, rooms, doors = _building([_px(5.0), _px(6.0)], [_px(5.0)])
    img = empty.copy()
    allowed = _free_for_furniture(rooms, doors)
    r0, c0 = np.argwhere(rooms == 0).min(axis=0)
    s0, d0 = np.argwhere(rooms == 1).min(axis=0)
    s1, d1 = np.argwhere(rooms == 1).max(axis=0) + 1
    dd, dw = _px(0.7), _px(1.4)
    for c in (c0 + _px(0.3), c0 + _px(2.5)):  # two desks on the top wall of room 0, a chair each
        _place(img, allowed, (r0, r0 + dd, c, c + dw), DESK)
        _place(img, allowed, (r0 + dd + 2, r0 + dd + 2 + _px(0.5), c + _px(0.45), c + _px(0.95)), 211)
    _place(img, allowed, (r0 + _px(4.5), r0 + _px(5.0), c0 + _px(3.0), c0 + _px(4.0)), 200)  # cupboard
    # the island's ring (2.4 x 2.2 m outside) flush with the top and right walls of room 1
    pocket = desk_island(img, allowed, (s0 + _px(1.1), d1 - _px(1.2)))
    if pocket is None:  # the layout above leaves room for it; a change that does not fails here
        raise RuntimeError("two_room_office: the desk island does not fit")
    _place(img, allowed, (s1 - _px(0.5), s1, d0 + _px(1.5), d0 + _px(2.5)), 200)  # cupboard
    return Office(img, empty, gt, rooms, pocket, 2)


def write_office(folder: Path, map_id: str, o: Office) -> None:
    """``furnished/<id>.png``, ``empty/<id>.png`` and ``<id>_gt.png`` in both."""
    for sub, img in (("furnished", o.furnished), ("empty", o.empty)):
        d = folder / sub
        d.mkdir(parents=True, exist_ok=True)
        Image.fromarray(img).save(d / f"{map_id}.png")
        Image.fromarray(o.gt).save(d / f"{map_id}_gt.png")


def write_offices(folder: str | Path, n: int = 7, seed: int = 0) -> list[str]:
    """``n`` seeded offices (seeds ``seed`` ..) into ``folder``. Returns the map ids."""
    folder = Path(folder)
    ids = []
    for k in range(n):
        mid = f"office_{k:02d}"
        write_office(folder, mid, office(seed + k))
        ids.append(mid)
    return ids


def sweep_command(folder: Path, sub: str) -> str:
    return (f"roomseg-bench -m env=maps env.dir={folder / sub} \"env.maps='{{id}}.png'\" env.image_resolution="
            f"{RESOLUTION} env.gt_format=rooms_white env.image_preset=white_only "
            f"segmenter=distance,morphological,voronoi run.name=clutter_{sub}")


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path, help="folder to write (furnished/ and empty/ inside)")
    ap.add_argument("--maps", type=int, default=7, help="number of offices (default 7)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the first office (default 0)")
    ap.add_argument("--hand-made", action="store_true",
                    help="write only the tests' two-room office (id two_rooms) instead of seeded ones")
    a = ap.parse_args(argv)
    if a.maps < 1 or a.seed < 0:
        print(f"error: --maps must be >= 1 and --seed >= 0, got {a.maps}, {a.seed}", file=sys.stderr)
        return 2
    if a.hand_made:
        write_office(a.out, "two_rooms", two_room_office())
        ids = ["two_rooms"]
    else:
        ids = write_offices(a.out, a.maps, a.seed)
    print(f"wrote {len(ids)} offices ({ids[0]} .. {ids[-1]}) to {a.out}/furnished and {a.out}/empty; segment them:")
    for sub in ("furnished", "empty"):
        print("  " + sweep_command(a.out, sub))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
