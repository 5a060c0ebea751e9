"""``python -m benchmark.baselines``: score external outputs, Table V, and match maps to houses.

    python -m benchmark.baselines score --preset selros [--set pred_dir=...] [--out DIR]
    python -m benchmark.baselines table5 [--out results/selros]      # SeLRoS + VRF + geometric
    python -m benchmark.baselines match --houses FILE [--maps DIR] [--limit N]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import pandas as pd
from omegaconf import OmegaConf

from benchmark.baselines.external import report, score_directory
from benchmark.metrics import MetricParams

CONF = Path(__file__).resolve().parents[2] / "conf" / "external"


def _preset(name: str, sets: list[str]) -> dict:
    path = CONF / f"{name}.yaml"
    if not path.exists():
        raise ValueError(f"unknown preset {name!r}; expected one of {sorted(p.stem for p in CONF.glob('*.yaml'))}")
    cfg = OmegaConf.merge(OmegaConf.load(path), OmegaConf.from_dotlist(sets))
    return OmegaConf.to_container(cfg, resolve=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmark.baselines", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("score", help="score a folder of another method's maps")
    s.add_argument("--preset", required=True, help="a file in conf/external (selros, vrf, rose2)")
    s.add_argument("--set", nargs="*", default=[], help="overrides, e.g. pred_dir=/path")
    s.add_argument("--min-segment-px", type=int, default=MetricParams().min_segment_px)
    s.add_argument("--out", type=Path)
    t = sub.add_parser("table5", help="SeLRoS, VRF and the geometric baselines on the SeLRoS maps")
    t.add_argument("--out", type=Path)
    t.add_argument("--min-segment-px", type=int, default=MetricParams().min_segment_px)
    m = sub.add_parser("match", help="find the house each SeLRoS map was made from")
    m.add_argument("--houses", type=Path, required=True)
    m.add_argument("--maps", type=Path, default=None, help="folder of *_ground_truth.png (default: SeLRoS)")
    m.add_argument("--limit", type=int, default=None, help="first N houses")
    a = ap.parse_args(argv)
    try:
        if a.cmd == "score":
            p = _preset(a.preset, a.set)
            params = MetricParams(min_segment_px=a.min_segment_px)
            df = score_directory(p["gt_dir"], p["gt_pattern"], p["pred_dir"], p["pred_pattern"], p["method"],
                                 params, dataset=p.get("dataset", "external"), resolution=p.get("resolution"))
        elif a.cmd == "table5":
            from benchmark.selros_table import main as selros_main

            return selros_main(["--geometric", "--min-segment-px", str(a.min_segment_px)] +
                               (["--out", str(a.out)] if a.out else []))
        else:
            from benchmark.baselines.match import match_maps
            from benchmark.selros_table import SELROS_RESOLUTION, default_selros_dir
            from envs.house import load_houses
            from envs.mapio import read_instance_png

            folder = a.maps or default_selros_dir() / "ground_truth"
            maps = {p.name.split("_")[0]: read_instance_png(p) >= 0 for p in sorted(folder.glob("*_ground_truth.png"))}
            t0 = time.perf_counter()
            rows = match_maps(maps, SELROS_RESOLUTION, load_houses(a.houses, 0, a.limit))
            print(pd.DataFrame(rows).to_markdown(index=False, floatfmt=".3f"))
            print(f"\n{len(maps)} maps x {a.limit or 'all'} houses in {time.perf_counter() - t0:.1f} s")
            return 0
    except (FileNotFoundError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    report(df, params, a.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
