"""``python -m benchmark.commands.baselines``: score external outputs, Table V, and match maps to houses.

    python -m benchmark.commands.baselines score --preset selros [--set pred_dir=...] [--out DIR]
    python -m benchmark.commands.baselines score --set gt_dir=G pred_dir=P pred_pattern={id}.png method=X
    python -m benchmark.commands.baselines table5 [--out results/selros]      # SeLRoS + VRF + geometric
    python -m benchmark.commands.baselines match --houses FILE [--maps DIR] [--limit N] [--out FILE.csv]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import pandas as pd
import yaml
from omegaconf import OmegaConf

from benchmark.baselines.external import pairs_from_manifest, report, score_directory, score_pairs
from benchmark.metrics import MetricParams

CONF = Path(__file__).resolve().parents[2] / "conf" / "external"

#: Keys of a scoring preset (conf/external/*.yaml) and their defaults.
PRESET_DEFAULTS = {"method": None, "gt_dir": None, "gt_pattern": "{id}_ground_truth.png", "pred_dir": None,
                   "pred_pattern": None, "manifest": None, "resolution": None, "pred_resolution": None,
                   "gt_format": "instance", "pred_format": "instance", "dataset": "external"}


def _overrides(sets: list[str]) -> dict:
    """``key=value`` strings -> dict; values are YAML scalars (numbers, null), else kept as text
    (so a pattern like ``{id}.png`` stays a string)."""
    out = {}
    for item in sets:
        key, eq, value = item.partition("=")
        if not eq or not key:
            raise ValueError(f"override {item!r} must look like key=value")
        try:
            v = yaml.safe_load(value)
        except yaml.YAMLError:
            v = value
        out[key.strip()] = v if v is None or isinstance(v, (int, float, bool)) else value
    return out


def load_preset(name: str | None, sets: list[str]) -> dict:
    """A preset from conf/external (or none) merged with ``key=value`` overrides, checked."""
    cfg = OmegaConf.create(PRESET_DEFAULTS)
    if name:
        path = CONF / f"{name}.yaml"
        if not path.exists():
            raise ValueError(f"unknown preset {name!r}; expected one of {sorted(p.stem for p in CONF.glob('*.yaml'))}")
        cfg = OmegaConf.merge(cfg, OmegaConf.load(path))
    cfg = OmegaConf.merge(cfg, _overrides(sets))
    root = OmegaConf.create({"paths": OmegaConf.load(CONF.parent / "paths" / "default.yaml"), "p": cfg})
    cfg = OmegaConf.to_container(root, resolve=True)["p"]
    unknown = set(cfg) - set(PRESET_DEFAULTS)
    if unknown:
        raise ValueError(f"unknown preset keys {sorted(unknown)}; expected {sorted(PRESET_DEFAULTS)}")
    if not cfg["method"]:
        raise ValueError("a method name is needed (preset key 'method', e.g. --set method=ROSE2)")
    if not cfg["manifest"] and not (cfg["gt_dir"] and cfg["pred_dir"] and cfg["pred_pattern"]):
        raise ValueError("give either manifest=FILE.csv or gt_dir, pred_dir and pred_pattern (with {id})")
    return cfg


def _score(p: dict, params: MetricParams) -> pd.DataFrame:
    kw = dict(dataset=p["dataset"], gt_format=p["gt_format"], pred_format=p["pred_format"],
              resolution=p["resolution"], pred_resolution=p["pred_resolution"])
    if p["manifest"]:
        return score_pairs(pairs_from_manifest(p["manifest"]), p["method"], params, **kw)
    return score_directory(p["gt_dir"], p["gt_pattern"], p["pred_dir"], p["pred_pattern"], p["method"], params, **kw)


def _match(a: argparse.Namespace) -> int:
    from benchmark.baselines.match import match_maps
    from benchmark.baselines.selros import SELROS_RESOLUTION, default_selros_dir
    from envs.atomic import atomic_write_text
    from envs.datasets.house_files import load_houses
    from envs.maps.label_png import read_instance_png

    folder = a.maps or default_selros_dir() / "ground_truth"
    paths = sorted(folder.glob("*_ground_truth.png"))
    if not paths:
        raise FileNotFoundError(f"no *_ground_truth.png in {folder}")
    maps = {p.name.split("_")[0]: read_instance_png(p) >= 0 for p in paths}
    t0 = time.perf_counter()
    houses = load_houses(a.houses, 0, a.limit)
    t1 = time.perf_counter()
    df = pd.DataFrame(match_maps(maps, a.map_resolution or SELROS_RESOLUTION, houses, resolution=a.resolution,
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
    ap = argparse.ArgumentParser(prog="python -m benchmark.commands.baselines", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("score", help="score a folder (or manifest) of another method's maps")
    s.add_argument("--preset", default=None, help="a file in conf/external (selros, vrf, rose2)")
    s.add_argument("--set", nargs="*", default=[], help=f"overrides, e.g. pred_dir=/path; keys: {list(PRESET_DEFAULTS)}")
    s.add_argument("--min-segment-px", type=int, default=MetricParams().min_segment_px)
    s.add_argument("--out", type=Path, help="folder for metrics.csv and table5.md")
    t = sub.add_parser("table5", help="SeLRoS, VRF and the geometric baselines on the SeLRoS maps")
    t.add_argument("--data", type=Path, default=None, help="the SeLRoS release folder (default: shared data)")
    t.add_argument("--out", type=Path)
    t.add_argument("--min-segment-px", type=int, default=MetricParams().min_segment_px)
    m = sub.add_parser("match", help="find the house each SeLRoS map was made from")
    m.add_argument("--houses", type=Path, required=True, help="ProcTHOR houses (.jsonl / .jsonl.gz)")
    m.add_argument("--maps", type=Path, default=None, help="folder of *_ground_truth.png (default: SeLRoS)")
    m.add_argument("--map-resolution", type=float, default=None, help="metres/pixel of the maps (default 0.02)")
    m.add_argument("--resolution", type=float, default=0.1, help="metres/pixel at which masks are compared")
    m.add_argument("--min-iou", type=float, default=0.8, help="walkable-mask IoU of a credible match")
    m.add_argument("--limit", type=int, default=None, help="first N houses")
    m.add_argument("--out", type=Path, default=None, help="CSV of the matches")
    a = ap.parse_args(argv)
    try:
        if a.cmd == "table5":
            from benchmark.commands.selros import main as selros_main

            return selros_main(["--geometric", "--min-segment-px", str(a.min_segment_px)]
                               + (["--data", str(a.data)] if a.data else []) + (["--out", str(a.out)] if a.out else []))
        if a.cmd == "match":
            return _match(a)
        p = load_preset(a.preset, a.set)
        params = MetricParams(min_segment_px=a.min_segment_px)
        df = _score(p, params)
    except (FileNotFoundError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    res = f"; maps at {p['resolution']} m/px" if p["resolution"] else ""
    report(df, params, a.out, res + ".")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
