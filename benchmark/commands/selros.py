"""``python -m benchmark.commands.selros``: the SeLRoS release's SeLRoS and VRF outputs (and,
with ``--geometric``, the geometric baselines) scored against its ground truth."""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from benchmark.baselines.external import report
from benchmark.baselines.selros import (
    SELROS_RESOLUTION,
    default_selros_dir,
    geometric_rows,
    selros_rows,
)
from benchmark.metrics import MetricParams


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="SeLRoS / VRF outputs vs the SeLRoS ground truth")
    ap.add_argument("--data", type=Path, default=default_selros_dir())
    ap.add_argument("--min-segment-px", type=int, default=MetricParams().min_segment_px)
    ap.add_argument("--connectivity", type=int, default=MetricParams().connectivity)
    ap.add_argument("--match", default=MetricParams().match)
    ap.add_argument("--out", type=Path, default=None, help="folder for metrics.csv")
    ap.add_argument("--geometric", action="store_true", help="add the geometric baselines on the same maps")
    a = ap.parse_args(argv)
    params = MetricParams(match=a.match, connectivity=a.connectivity, min_segment_px=a.min_segment_px)
    df = selros_rows(a.data, params)
    if a.geometric:
        df = pd.concat([df, geometric_rows(a.data, params)], ignore_index=True)
    report(df, params, a.out, f"; maps at {SELROS_RESOLUTION} m/px.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
