"""``python -m benchmark.commands.draw_house``: the command-line front of :mod:`benchmark.reports.draw_house`."""

from __future__ import annotations

from pathlib import Path

from benchmark.commands import cli
from benchmark.reports.draw_house import draw_scene
from envs.datasets.house_files import load_houses
from envs.maps.scene import rasterise_house


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(description="draw one house's map and ground truth")
    ap.add_argument("--houses", type=Path, required=True, help=".json/.jsonl/.jsonl.gz house file")
    ap.add_argument("--index", type=int, default=0)
    ap.add_argument("--resolution", type=float, default=0.05, help="metres per pixel")
    ap.add_argument("--out", type=Path, default=Path("house.png"))
    a = ap.parse_args(argv)
    houses = load_houses(a.houses, a.index, a.index + 1)
    if not houses:
        ap.error(f"{a.houses} has no house at index {a.index}")
    draw_scene(rasterise_house(houses[0], resolution=a.resolution), a.out)
    print(a.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
