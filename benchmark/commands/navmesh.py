"""``python -m benchmark.commands.navmesh``: the command-line front of :mod:`envs.render.habitat`."""

from __future__ import annotations

import json
from pathlib import Path

from benchmark.commands import cli
from envs.render.habitat import DEFAULT_DATASET, HabitatRenderer, mirror_agreement


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmark.commands.navmesh navmesh --scene NAME --out ROOT/NAME [--resolution 0.05]``:
    write a scene's navmesh top-down view into an annotation folder as ``walkable.png`` +
    ``walkable.json`` (its grid; the labels are carried onto it, see :mod:`envs.maps.annotations`).
    ``python -m benchmark.commands.navmesh mirror --scene NAME --reachable POINTS.json``: the
    share of AI2-THOR's reachable positions (``python -m benchmark.commands.thor reachable``)
    on the navmesh for each ``mirror``."""
    import os  # noqa: PLC0415

    from envs.maps.annotations import write_walkable  # noqa: PLC0415

    ap = cli.ArgumentParser(description="navmesh top-down view of an ai2thor-hab scene")
    sub = ap.add_subparsers(dest="cmd", required=True)
    n = sub.add_parser("navmesh")
    n.add_argument("--scene", required=True)
    n.add_argument("--out", type=Path, required=True, help="the house's annotation folder")
    n.add_argument("--resolution", type=float, default=0.05, help="metres per pixel")
    n.add_argument("--mirror", choices=("z", "x"), default="z", help="axis mirrored between AI2-THOR and Habitat")
    n.add_argument("--dataset", default=os.environ.get("ROOMSEG_HAB_DATASET", DEFAULT_DATASET))
    m = sub.add_parser("mirror")
    m.add_argument("--scene", required=True)
    m.add_argument("--reachable", type=Path, required=True, help="JSON list of {x, y, z} from AI2-THOR")
    m.add_argument("--resolution", type=float, default=0.05, help="metres per pixel")
    m.add_argument("--dataset", default=os.environ.get("ROOMSEG_HAB_DATASET", DEFAULT_DATASET))
    a = ap.parse_args(argv)
    if a.cmd == "mirror":
        r = HabitatRenderer(a.dataset)
        sim = r._sim_for(a.scene)
        lower, _ = sim.pathfinder.get_bounds()
        top = sim.pathfinder.get_topdown_view(a.resolution, r.floor_y)
        for k, v in mirror_agreement(top, lower, a.resolution, json.loads(a.reachable.read_text())).items():
            print(f"mirror={k}: {v:.1%} of AI2-THOR's reachable positions on the navmesh")
        return 0
    g = HabitatRenderer(a.dataset, mirror=a.mirror).navmesh_grid(a.scene, a.resolution)
    path = write_walkable(a.out, g)
    print(f"{path}: {g.shape[1]} x {g.shape[0]} px at {g.resolution} m/px, origin (x, z) = {g.origin}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
