"""``python -m benchmark.commands.coverage``: the command-line front of :mod:`benchmark.viewpoints`."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from benchmark.commands import cli
from benchmark.paths import procthor_houses
from benchmark.viewpoints import Autotrace, room_coverage


def report(n_poses: list[int], covered: int, total: int, missed: list[str], houses: str, offset: float,
           spacing: float) -> str:
    """The command's Markdown: one table row (houses; poses per house, mean / fewest / most; rooms
    with at least one pose) and a note naming the house file, the settings and every missed room.

    Args:
        n_poses: poses of each house, one int per house.
        covered, total: rooms with at least one pose, rooms (summed over houses).
        missed: one phrase per room with no pose ("house H room k (class), largest clearance x m").
        houses: how the houses are named in the note ("houses 0-149 of FILE").
        offset, spacing: the autotrace settings, metres."""
    table = ("| houses | poses per house (mean) | fewest | most | rooms with a pose |\n"
             "|---:|---:|---:|---:|---:|\n"
             f"| {len(n_poses)} | {np.mean(n_poses):.0f} | {min(n_poses)} | {max(n_poses)} | {covered} of {total} |")
    note = f"Autotrace (offset {offset:g} m, spacing {spacing:g} m) on {houses}. "
    if missed:
        note += ("Rooms with no pose (a room gets none when it is nowhere wider than twice the offset): "
                 + "; ".join(missed) + ".")
    else:
        note += "Every room has at least one pose."
    return f"{table}\n\n{note}\n"


def main(argv: list[str] | None = None) -> int:
    """Autotrace on a house file: poses per house and how many rooms get at least one pose."""

    from envs.datasets.house_files import load_houses
    from envs.maps.scene import rasterise_house

    default = procthor_houses()
    ap = cli.ArgumentParser(from_root=True, description="autotrace room coverage on a house file")
    ap.add_argument("--houses", type=Path, default=default)
    ap.add_argument("--range", default="0:150", help="house index range a:b")
    ap.add_argument("--offset", type=float, default=0.5, help="metres")
    ap.add_argument("--spacing", type=float, default=1.0, help="metres")
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the result as a Markdown table to this file, headed by the command that "
                         "made it (make docs-numbers: results/published/coverage.md, which docs/method.md "
                         "includes)")
    a = ap.parse_args(argv)
    try:
        start, stop = map(int, a.range.split(":"))
        if not 0 <= start < stop:
            raise ValueError
    except ValueError:
        ap.error(f"--range {a.range}: expected a:b with 0 <= a < b")
    at = Autotrace(offset=a.offset, spacing=a.spacing)
    n_poses, covered, total, missed = [], 0, 0, []
    for house in load_houses(a.houses, start, stop):
        scene = rasterise_house(house)
        poses = at.generate(scene)
        n_poses.append(len(poses))
        got, n, lost = room_coverage(scene, poses)
        covered, total = covered + got, total + n
        for k, clearance in lost:
            name = scene.classes[scene.instance_classes[k]]
            missed.append(f"{house.id} room {k} ({name}), largest clearance {clearance:.2f} m")
            print(f"{house.id}: room {k} ({name}) has no pose; "
                  f"largest clearance {clearance:.2f} m (offset {a.offset} m)")
    if not n_poses:
        print(f"error: {a.houses}: no house in --range {a.range}", file=sys.stderr)
        return 2
    print(f"{len(n_poses)} houses: {np.mean(n_poses):.0f} poses per house (min {min(n_poses)}, max {max(n_poses)}); "
          f"{covered} of {total} rooms have at least one pose")
    if a.out is not None:
        from benchmark.reports.published import write_published

        text = report(n_poses, covered, total, missed, f"houses {start}-{start + len(n_poses) - 1} of "
                      f"{Path(a.houses).name}", a.offset, a.spacing)
        err = write_published(a.out, published_command(a, default), text)
        if err is not None:
            print(f"error: {err}", file=sys.stderr)
            return 2
    return 0


def published_command(a, default: Path) -> str:  # noqa: ANN001 - the parsed arguments
    """The command line that makes the published file (the defaults but ``--range`` left out)."""
    parts = ["python -m benchmark.commands.coverage", f"--range {a.range}"]
    if Path(a.houses) != default:
        parts.append(f"--houses {a.houses}")
    if a.offset != 0.5:
        parts.append(f"--offset {a.offset:g}")
    if a.spacing != 1.0:
        parts.append(f"--spacing {a.spacing:g}")
    parts.append(f"--out {a.out}")
    return " ".join(parts)


if __name__ == "__main__":
    raise SystemExit(main())
