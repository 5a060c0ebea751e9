"""``python -m benchmark.commands.thor``: the command-line front of :mod:`envs.render.thor`."""

from __future__ import annotations

from pathlib import Path

from benchmark.commands import cli
from envs.render.thor import PLATFORMS, AI2THORRenderer


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmark.commands.thor reachable --scene NAME --out POINTS.json``: AI2-THOR's
    reachable positions of a scene (a name, or a ProcTHOR house JSON file) as a JSON list."""
    import json  # noqa: PLC0415

    from envs.world.house import House  # noqa: PLC0415

    ap = cli.ArgumentParser(description="AI2-THOR reachable positions of a scene")
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("reachable")
    r.add_argument("--scene", required=True, help="scene name (e.g. ArchitecTHOR-Val-00) or a house .json file")
    r.add_argument("--out", type=Path, required=True)
    r.add_argument("--platform", default="CloudRendering", choices=PLATFORMS)
    r.add_argument("--commit-id", default=None)
    a = ap.parse_args(argv)
    p = Path(a.scene)
    house = House(p.stem, json.loads(p.read_text())) if p.suffix == ".json" else House(a.scene, {"scene": a.scene})
    renderer = AI2THORRenderer(platform=a.platform, commit_id=a.commit_id)
    try:
        points = renderer.reachable_positions(house)
    finally:
        renderer.close()
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(points))
    print(f"{a.out}: {len(points)} reachable positions of {house.id}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
