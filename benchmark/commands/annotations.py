"""``python -m benchmark.commands.annotations``: the command-line front of :mod:`envs.maps.annotations`."""

from __future__ import annotations

import json
from pathlib import Path

from benchmark.commands import cli
from envs.maps.annotations import (
    MIN_ON_WALKABLE,
    MIN_WALKABLE_COVERED,
    ROOM_MODES,
    agreement_line,
    describe,
    import_room_map,
)


def main(argv: list[str] | None = None) -> int:
    """``import``: convert a colour-coded room map into an annotation folder, then print its
    summary and how it sits on the folder's navmesh map (``walkable.png``, written first by
    ``python -m benchmark.commands.navmesh navmesh``). ``check ROOT``: the same for every
    house folder under ROOT. A share below its threshold prints a WARNING line (the exit
    status stays 0 unless ``--strict``); a folder that cannot be read exits 1.

    Returns:
        exit status.
    """
    ap = cli.ArgumentParser(description="room annotations in roomseg-bench's layout")
    sub = ap.add_subparsers(dest="cmd", required=True)
    i = sub.add_parser("import", help="convert a colour-coded room map into an annotation folder")
    i.add_argument("--map", type=Path, required=True, help="colour-coded room map PNG (black = outside)")
    i.add_argument("--colours", type=Path, required=True, help='JSON {"#rrggbb": "kitchen", ...}')
    i.add_argument("--resolution", type=float, required=True, help="metres per pixel")
    i.add_argument("--origin", type=float, nargs=2, required=True, metavar=("X", "Z"),
                   help="world x, z (metres) of the top-left corner of pixel (0, 0)")
    i.add_argument("--rooms", choices=ROOM_MODES, default="colour",
                   help="colour: one room per colour; components: one room per connected region of a colour")
    i.add_argument("--out", type=Path, required=True, help="the house's annotation folder")
    c = sub.add_parser("check", help="summarise every house folder under ROOT")
    c.add_argument("root", type=Path)
    for p in (i, c):
        p.add_argument("--min-on-walkable", type=float, default=MIN_ON_WALKABLE,
                       help="warn when a smaller share (0-1) of annotated pixels lies on walkable navmesh cells")
        p.add_argument("--min-covered", type=float, default=MIN_WALKABLE_COVERED,
                       help="warn when a smaller share (0-1) of walkable navmesh cells lies in an annotated room")
        p.add_argument("--strict", action="store_true", help="a warning makes the exit status 1")
    a = ap.parse_args(argv)
    if a.cmd == "import":
        out = import_room_map(a.map, json.loads(a.colours.read_text()), a.resolution, tuple(a.origin), a.out, a.rooms)
        print(describe(out))
        line, ok = agreement_line(out, a.min_on_walkable, a.min_covered)
        print(line)
        return 1 if (a.strict and not ok) else 0
    folders = sorted(p for p in a.root.iterdir() if p.is_dir()) if a.root.is_dir() else []
    if not folders:
        print(f"no house folders under {a.root}")
        return 1
    bad = warned = 0
    for f in folders:
        try:
            print(describe(f))
            line, ok = agreement_line(f, a.min_on_walkable, a.min_covered)
            print("  " + line)
            warned += not ok
        except (FileNotFoundError, ValueError) as e:
            bad += 1
            print(f"{f.name}: {e}")
    if warned:
        print(f"{warned} of {len(folders)} house(s) do not sit on their navmesh map (WARNING lines above)")
    return 1 if bad or (a.strict and warned) else 0


if __name__ == "__main__":
    raise SystemExit(main())
