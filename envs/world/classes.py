"""Room classes, the mapping from dataset room types to classes, and class colours."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

#: The paper's seven room classes, in their fixed default order (class index = position).
PAPER_CLASSES: tuple[str, ...] = (
    "balcony",
    "bathroom",
    "bedroom",
    "corridor",
    "dining_room",
    "kitchen",
    "living_room",
)

#: Dataset ``roomType`` -> class: the defaults, the one place they live. ProcTHOR-10k uses
#: the first four; the synthetic generator also writes Balcony, Corridor and DiningRoom;
#: Hallway is how other ProcTHOR-schema house sets name a corridor. An environment's
#: ``room_types`` setting (``env.room_types``) adds to or overrides these
#: (:func:`room_type_mapping`).
ROOM_TYPE_TO_CLASS: dict[str, str] = {
    "Kitchen": "kitchen",
    "LivingRoom": "living_room",
    "Bedroom": "bedroom",
    "Bathroom": "bathroom",
    "Balcony": "balcony",
    "Corridor": "corridor",
    "Hallway": "corridor",
    "DiningRoom": "dining_room",
}

#: Name of the setting that maps room types to classes, quoted by every error about one.
ROOM_TYPES_SETTING = "env.room_types"


def room_type_mapping(overrides: Mapping[str, str | None] | None = None) -> dict[str, str]:
    """The default room-type mapping with ``overrides`` applied.

    Args:
        overrides: room type -> class name to add or replace; a ``None`` value removes
            the type (its houses then fail as having an unknown room type).

    Returns:
        dict room type -> class name.
    """
    out = dict(ROOM_TYPE_TO_CLASS)
    for k, v in (overrides or {}).items():
        if not isinstance(k, str) or not k:
            raise ValueError(f"{ROOM_TYPES_SETTING}: room type {k!r} is not a non-empty string")
        if v is None:
            out.pop(k, None)
        elif isinstance(v, str) and v:
            out[k] = v
        else:
            raise ValueError(f"{ROOM_TYPES_SETTING}.{k}: expected a class name or null, got {v!r}")
    return out


#: Fixed RGB colours (0-255) per class, used by every figure and PNG writer: the seven
#: colours of the Okabe-Ito palette (its black is the background), told apart with the
#: common colour-vision deficiencies. Open-plan neighbours (kitchen | dining | living) get
#: green | vermillion | orange, which also differ in lightness.
CLASS_COLORS: dict[str, tuple[int, int, int]] = {
    "balcony": (86, 180, 233),      # sky blue
    "bathroom": (0, 114, 178),      # blue
    "bedroom": (204, 121, 167),     # reddish purple
    "corridor": (240, 228, 66),     # yellow
    "dining_room": (213, 94, 0),    # vermillion
    "kitchen": (0, 158, 115),       # bluish green
    "living_room": (230, 159, 0),   # orange
}
#: Colour of unlabelled walkable pixels and of non-walkable background.
UNLABELLED_COLOR: tuple[int, int, int] = (200, 200, 200)
BACKGROUND_COLOR: tuple[int, int, int] = (0, 0, 0)

_FALLBACK_PALETTE = [
    (166, 206, 227), (178, 223, 138), (251, 154, 153), (253, 191, 111),
    (202, 178, 214), (255, 255, 153), (177, 89, 40), (128, 128, 128),
]


def class_index(classes: Sequence[str], name: str) -> int:
    """Index of ``name`` in ``classes``; a clear error when it is not one of them."""
    try:
        return list(classes).index(name)
    except ValueError:
        raise ValueError(f"unknown room class {name!r}; expected one of {list(classes)}") from None


def room_type_to_class_index(
    room_type: str,
    classes: Sequence[str] = PAPER_CLASSES,
    mapping: Mapping[str, str] = ROOM_TYPE_TO_CLASS,
) -> int:
    """Class index of a ProcTHOR ``roomType`` (e.g. ``"LivingRoom"`` -> index of living_room).

    Returns:
        int position of the mapped class in ``classes``.
    """
    if room_type not in mapping:
        raise ValueError(
            f"unknown room type {room_type!r}: map it to a class in {ROOM_TYPES_SETTING} "
            f"(known types: {sorted(mapping)})"
        )
    name = mapping[room_type]
    if name not in classes:
        raise ValueError(
            f"room type {room_type!r} maps to class {name!r}, which is not in classes {list(classes)}; "
            f"change {ROOM_TYPES_SETTING} or the class list"
        )
    return class_index(classes, name)


def class_colors(classes: Sequence[str]) -> list[tuple[int, int, int]]:
    """RGB colour per class, in class order (paper classes keep their fixed colours)."""
    out = []
    extra = 0
    for name in classes:
        if name in CLASS_COLORS:
            out.append(CLASS_COLORS[name])
        else:
            out.append(_FALLBACK_PALETTE[extra % len(_FALLBACK_PALETTE)])
            extra += 1
    return out
