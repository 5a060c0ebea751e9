"""``python -m benchmark.commands.view_confusion``: a classifier's confusion matrix on rendered
views against the oracle's truth (the majority visible class), written in the format of the
``evaluate`` command's ``table1_<model>.json``, so that the oracle's ``confusion`` noise
(``classifier=oracle_confusion``) can draw wrong classes the way that classifier errs.

    python -m benchmark.commands.view_confusion --out conf/classifier/confusion/objects_synthetic.json \\
        classifier=objects env.seed_start=1000 env.n_houses=50

Extra ``key=value`` arguments are Hydra overrides of the root config (``conf/config.yaml``):
they choose the environment, viewpoints, renderer (one that gives visible classes: the
floorplan renderer) and classifier. Also writes a PNG of the row-normalised matrix beside.
``--markdown PATH`` writes the matrix's summary (:func:`summary`) as a Markdown file headed by
the command (make docs-numbers: ``results/published/oracle_confusion.md``, which docs/method.md
includes), with or without ``--out``.
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
    ap.add_argument("--out", type=Path, default=None, help="JSON file to write (a PNG goes beside it)")
    ap.add_argument("--markdown", type=Path, default=None,
                    help="Markdown file to write: views, accuracy and where each class's errors go, headed by "
                         "the command")
    ap.add_argument("overrides", nargs="*", help="Hydra overrides of the root config, key=value")
    a = ap.parse_args(argv)
    if a.out is None and a.markdown is None:
        ap.error("nothing to write: give --out FILE.json, --markdown FILE.md or both")
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
        if a.out is not None:
            a.out.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(a.out, json.dumps(record, indent=1) + "\n")
            confusion_figure(counts, classes, a.out.with_suffix(".png"),
                             title=f"{record['model']} on {record['n_images']} rendered views")
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    if a.markdown is not None:
        from benchmark.reports.published import write_published  # noqa: PLC0415

        command = ["python -m benchmark.commands.view_confusion", f"--markdown {a.markdown}", *a.overrides]
        err = write_published(a.markdown, " ".join(command), summary(record))
        if err is not None:
            print(f"error: {err}", file=sys.stderr)
            return 2
    written = " and ".join(str(p) for p in (a.out, a.markdown) if p is not None)
    print(f"{record['model']}: per-view accuracy {record['accuracy']:.4f} over {record['n_images']} views of "
          f"{len(ids)} houses ({blind} saw no floor) in {seconds:.1f} s -> {written}")
    return 0


def summary(record: dict) -> str:
    """Markdown of a confusion record (the JSON this command writes): per true class its views,
    the share it gets right and the wrong class most of its errors go to, a row for all views,
    then a note naming the data and the truth.

    Args:
        record: ``classes`` (C names), ``confusion`` (C x C counts, rows the true class, columns
            the predicted one), ``model``, ``data``, ``n_images``, ``accuracy`` (a share) and
            ``truth``.
    Returns:
        the table and the note; shares in percent."""
    import pandas as pd  # noqa: PLC0415

    m = np.asarray(record["confusion"], dtype=np.int64)
    classes = list(record["classes"])
    if m.shape != (len(classes), len(classes)):
        raise ValueError(f"confusion {m.shape}: expected {len(classes)} x {len(classes)} for the classes {classes}")
    rows = []
    for i, name in enumerate(classes):
        n = int(m[i].sum())
        if n == 0:
            continue
        wrong = m[i].copy()
        wrong[i] = 0
        errors = int(wrong.sum())
        j = int(np.argmax(wrong))  # ties: the first class in order
        rows.append({"true class": name, "views": f"{n:,}", "right %": f"{100 * m[i, i] / n:.1f}",
                     "errors": f"{errors:,}",
                     "errors' most common class": classes[j] if errors else "–",
                     "its share of the errors %": f"{100 * wrong[j] / errors:.0f}" if errors else "–"})
    wrong = m.sum() - np.trace(m)
    rows.append({"true class": "all", "views": f"{int(m.sum()):,}", "right %": f"{100 * np.trace(m) / m.sum():.1f}",
                 "errors": f"{int(wrong):,}", "errors' most common class": "", "its share of the errors %": ""})
    table = pd.DataFrame(rows).to_markdown(index=False, colalign=["left", "right", "right", "right", "left", "right"],
                                                  disable_numparse=True)
    note = (f"{record['model']} on rendered views ({record['data']}), truth: the {record['truth']}; "
            "`all`: pooled over views.")
    return f"{table}\n\n{note}\n"


if __name__ == "__main__":
    raise SystemExit(main())
