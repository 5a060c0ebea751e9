"""``python -m benchmark.commands.baselines``: Table V on the SeLRoS maps, and match maps to houses.

    python -m benchmark.commands.baselines table5 [--data DIR] [--resolution R] [--out DIR] [metrics.key=value ...]
    python -m benchmark.commands.baselines match --houses FILE [--maps DIR] [--limit N] [--out FILE.csv]

Scoring one method's folder of maps is a Hydra app of its own over the ``external`` group:
``python -m benchmark.commands.baselines_score -m external=selros,vrf`` (see there).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import pandas as pd

from benchmark.commands import cli


def _match(a: argparse.Namespace) -> int:
    from benchmark.baselines.external import _glob_ids
    from benchmark.baselines.match import match_maps
    from benchmark.baselines.selros import GT_PATTERN, default_selros_dir
    from envs.atomic import atomic_write_text
    from envs.datasets.house_files import load_houses
    from envs.maps.label_png import read_instance_png

    folder = a.maps or default_selros_dir() / "ground_truth"
    paths = _glob_ids(folder, GT_PATTERN)  # ids by the naming rule: office_a_ground_truth.png -> office_a
    if not paths:
        raise FileNotFoundError(f"no {GT_PATTERN.replace('{id}', '*')} in {folder}")
    maps = {mid: read_instance_png(p) >= 0 for mid, p in paths.items()}
    t0 = time.perf_counter()
    houses = load_houses(a.houses, 0, a.limit)
    t1 = time.perf_counter()
    df = pd.DataFrame(match_maps(maps, a.map_resolution, houses, resolution=a.resolution,
                                 min_iou=a.min_iou))
    t2 = time.perf_counter()
    print(df.to_markdown(index=False, floatfmt=".3f"))
    print(f"\n{int(df['matched'].sum())} of {len(df)} maps matched (walkable-mask IoU >= {a.min_iou}, "
          f"ahead of the runner-up by 0.05); best IoU {df['iou'].min():.2f}-{df['iou'].max():.2f}")
    print(f"{len(maps)} maps x {len(houses)} houses at {a.resolution} m/px: loading {t1 - t0:.1f} s, "
          f"rasterising + matching {t2 - t1:.1f} s")
    if a.out:
        atomic_write_text(a.out, df.to_csv(index=False))
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    sub.add_parser("table5", add_help=False, help="SeLRoS, VRF, geometric and sanity rows on the SeLRoS maps "
                   "(options: python -m benchmark.commands.selros --help)")
    m = sub.add_parser("match", help="find the house each SeLRoS map was made from")
    m.add_argument("--houses", type=Path, required=True, help="ProcTHOR houses (.jsonl / .jsonl.gz)")
    m.add_argument("--maps", type=Path, default=None, help="folder of *_ground_truth.png (default: SeLRoS)")
    m.add_argument("--map-resolution", type=float, default=0.02, help="metres/pixel of the maps (SeLRoS: 0.02)")
    m.add_argument("--resolution", type=float, default=0.1, help="metres/pixel at which masks are compared")
    m.add_argument("--min-iou", type=float, default=0.8, help="walkable-mask IoU of a credible match")
    m.add_argument("--limit", type=int, default=None, help="first N houses")
    m.add_argument("--out", type=Path, default=None, help="CSV of the matches")
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["table5"]:
        from benchmark.commands.selros import main as table5_main

        return table5_main(argv[1:])
    a = ap.parse_args(argv)
    try:
        return _match(a)
    except (FileNotFoundError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
