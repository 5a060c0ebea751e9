"""``python -m benchmark.commands.annotations``: the command-line front of :mod:`envs.maps.annotations`."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from envs.maps.annotations import ROOM_MODES, describe, import_room_map


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="room annotations in roomseg-bench's layout")
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
    a = ap.parse_args(argv)
    if a.cmd == "import":
        out = import_room_map(a.map, json.loads(a.colours.read_text()), a.resolution, tuple(a.origin), a.out, a.rooms)
        print(describe(out))
        return 0
    folders = sorted(p for p in a.root.iterdir() if p.is_dir()) if a.root.is_dir() else []
    if not folders:
        print(f"no house folders under {a.root}")
        return 1
    bad = 0
    for f in folders:
        try:
            print(describe(f))
        except (FileNotFoundError, ValueError) as e:
            bad += 1
            print(f"{f.name}: {e}")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
