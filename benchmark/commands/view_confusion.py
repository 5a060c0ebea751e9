"""``python -m benchmark.commands.view_confusion``: a classifier's confusion matrix on rendered
views against the oracle's truth (the majority visible class), written in the format of the
``evaluate`` command's ``table1_<model>.json``, so that the oracle's ``confusion`` noise
(``classifier=oracle_confusion``) can draw wrong classes the way that classifier errs.

    python -m benchmark.commands.view_confusion --out conf/classifier/confusion/objects_synthetic.json \\
        classifier=objects env.seed_start=1000 env.n_houses=50

Extra ``key=value`` arguments are Hydra overrides of the root config (``conf/config.yaml``):
they choose the environment, viewpoints, renderer (one that gives visible classes: the
floorplan renderer) and classifier. Also writes a PNG of the row-normalised matrix beside.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

from benchmark.commands import cli


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True, help="JSON file to write (a PNG goes beside it)")
    ap.add_argument("overrides", nargs="*", help="Hydra overrides of the root config, key=value")
    a = ap.parse_args(argv)
    from benchmark.classifiers.evaluate import table1_metrics  # noqa: PLC0415
    from benchmark.commands.errors import cli_errors, one_line  # noqa: PLC0415
    from benchmark.reports.confusion import confusion_figure  # noqa: PLC0415

    try:
        from hydra.utils import instantiate  # noqa: PLC0415

        from benchmark.classifiers.noise import classifier_confusion  # noqa: PLC0415
        from benchmark.config import build_method, compose  # noqa: PLC0415
        from benchmark.harness.runner import select_houses  # noqa: PLC0415
        from envs.atomic import atomic_write_text  # noqa: PLC0415

        cfg = compose("config", a.overrides)
        env = instantiate(cfg.env)
        ids = select_houses(env.house_ids(), cfg.run.get("houses"), cfg.run.get("limit"))
        t = time.perf_counter()
        counts, blind = classifier_confusion(env, instantiate(cfg.viewpoints), instantiate(cfg.renderer),
                                             build_method(cfg), ids, progress=True)
        seconds = time.perf_counter() - t
        classes = list(cfg.classes)
        rows = counts.sum(1) > 0
        t_idx, p_idx = np.nonzero(counts)
        y_true = np.repeat(t_idx, counts[t_idx, p_idx])
        y_pred = np.repeat(p_idx, counts[t_idx, p_idx])
        m = table1_metrics(y_true, y_pred, len(classes))
        record = {"model": str(cfg.classifier._target_).rsplit(".", 1)[-1], "split": "rendered views",
                  "data": f"env {cfg.env.get('name', '')}: {len(ids)} houses ({ids[0]} .. {ids[-1]})",
                  "n_images": int(counts.sum()), "n_views_no_floor": blind, "seconds": round(seconds, 2),
                  "classes": classes, "overrides": list(a.overrides), "truth": "majority visible class",
                  **{k: m[k] for k in ("precision", "recall", "accuracy", "f1")},
                  "confusion": counts.tolist(), "classes_with_views": [c for c, r in zip(classes, rows) if r]}
        a.out.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(a.out, json.dumps(record, indent=1) + "\n")
        confusion_figure(counts, classes, a.out.with_suffix(".png"),
                         title=f"{record['model']} on {record['n_images']} rendered views")
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    print(f"{record['model']}: per-view accuracy {record['accuracy']:.4f} over {record['n_images']} views of "
          f"{len(ids)} houses ({blind} saw no floor) in {seconds:.1f} s -> {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
