"""The runner behind ``roomseg-bench`` (:mod:`benchmark.commands.bench`).

Builds every stage from ``conf/`` with ``_target_``, runs the configured houses through
:class:`benchmark.harness.pipeline.Pipeline` and writes, into the job's output folder:
``metrics.csv`` (one row per house), ``summary.json`` (counts, failures and why, wall
time) and ``resolved_config.yaml``. Examples::

    roomseg-bench                                   # defaults from conf/config.yaml
    roomseg-bench aggregator=vision_cone run.limit=5
    roomseg-bench -m aggregator=graph_knn,vision_cone postprocess=none,default
    roomseg-bench experiment=table4                 # a paper table's sweep
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from pathlib import Path
from typing import Any

import pandas as pd
from hydra.core.hydra_config import HydraConfig
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from benchmark.harness.cache import atomic_write_json, atomic_write_text, config_key
from benchmark.harness.pipeline import Pipeline, expand_force
from benchmark.harness.progress import house_progress, job_label
from benchmark.harness.store import Job
from benchmark.metrics import describe
from benchmark.paths import CONF_DIR

log = logging.getLogger("roomseg-bench")


#: env config keys that select houses rather than change them (left out of cache keys).
SELECTION_KEYS = ("start", "stop", "n_houses", "seed_start", "name", "houses")

#: first columns of metrics.csv, in this order; the rest follow alphabetically.
LEADING_COLUMNS = ("house_id", "dataset", "env", "viewpoints", "renderer", "classifier", "oracle_accuracy",
                   "aggregator", "postprocess", "segmenter", "label", "status", "error", "iou", "precision",
                   "recall", "accuracy", "n_pred_segments", "n_gt_segments", "n_views", "n_refused",
                   "view_accuracy")

#: bump to invalidate every cache entry after a change in cached outputs' meaning.
CACHE_VERSION = 1


def _plain(node: Any) -> Any:
    return OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else node


def stage_keys(cfg: DictConfig) -> dict[str, str]:
    """Cache keys of the render, classify and score stages for this config."""
    env = {k: v for k, v in (_plain(cfg.env) or {}).items() if k not in SELECTION_KEYS}
    salt = (CACHE_VERSION, cfg.run.get("cache_salt", ""))
    render = config_key("render", salt, env, _plain(cfg.get("viewpoints")), _plain(cfg.get("renderer")))
    classify = config_key("classify", render, _plain(cfg.get("classifier")))
    if cfg.get("segmenter") is not None:
        score = config_key("segment", salt, env, _plain(cfg.segmenter), _plain(cfg.metrics))
    else:
        score = config_key("score", classify, _plain(cfg.get("aggregator")), _plain(cfg.get("postprocess")),
                           _plain(cfg.metrics))
    return {"render": render, "classify": classify, "score": score}


def select_houses(all_ids: list[str], houses: Any, limit: Any) -> list[str]:
    """``run.houses`` (list of ids, or None for all) then ``run.limit`` (first N)."""
    ids = list(all_ids)
    if houses:
        wanted = [str(h) for h in houses]
        missing = [h for h in wanted if h not in set(ids)]
        if missing:
            raise ValueError(f"run.houses: unknown house id(s) {missing[:5]}; the environment has {len(ids)} houses, "
                             f"e.g. {ids[:3]}")
        ids = wanted
    if limit is not None:
        ids = ids[: int(limit)]
    return ids


def _choices() -> dict[str, str]:
    try:
        ch = HydraConfig.get().runtime.choices
    except ValueError:
        return {}
    return {k: (str(v) if v is not None else "") for k, v in ch.items() if not k.startswith("hydra")}


def build_pipeline(cfg: DictConfig, choices: dict[str, str] | None = None) -> Pipeline:
    """Instantiate every configured stage and the cache keys."""
    choices = choices if choices is not None else _choices()
    env = instantiate(cfg.env)
    seg = cfg.get("segmenter")
    names = {"env": choices.get("env", getattr(env, "name", "env"))}
    if seg is not None:
        names["segmenter"] = choices.get("segmenter", str(seg.get("_target_", "")).rsplit(".", 1)[-1])
        for k in ("viewpoints", "renderer", "classifier", "aggregator", "postprocess"):
            names[k] = ""
    else:
        for k in ("viewpoints", "renderer", "classifier", "aggregator", "postprocess"):
            names[k] = choices.get(k, str(cfg[k].get("_target_", "")).rsplit(".", 1)[-1] if cfg.get(k) else "none")
        names["segmenter"] = ""
    extra = {}
    if seg is None and cfg.classifier.get("accuracy") is not None:
        extra["oracle_accuracy"] = float(cfg.classifier.accuracy)
    extra["label"] = str(cfg.run.get("label") or "")
    metric_params = instantiate(cfg.metrics)
    extra["metric_params"] = describe(metric_params)
    kw: dict[str, Any] = {}
    if seg is not None:
        kw["segmenter"] = instantiate(seg)
    else:
        for k in ("viewpoints", "renderer", "classifier", "aggregator"):
            kw[k] = instantiate(cfg[k])
        kw["postprocess"] = instantiate(cfg.postprocess) if cfg.get("postprocess") else None
    return Pipeline(
        env=env, cache_dir=Path(cfg.run.cache_dir), keys=stage_keys(cfg), names=names,
        metric_params=metric_params, force=expand_force(cfg.run.get("force")),
        save_maps=bool(cfg.run.get("save_maps", True)), extra=extra, **kw,
    )


def run(cfg: DictConfig, out_dir: Path, choices: dict[str, str] | None = None) -> pd.DataFrame:
    """Run one configuration over its houses; write metrics.csv, summary.json, resolved_config.yaml."""
    t0 = time.perf_counter()
    out_dir.mkdir(parents=True, exist_ok=True)
    body = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
    atomic_write_text(Job(out_dir).config_path, OmegaConf.to_yaml(body, resolve=True))
    pipe = build_pipeline(cfg, choices)
    ids = select_houses(pipe.env.house_ids(), cfg.run.get("houses"), cfg.run.get("limit"))
    if pipe.classifier is not None and hasattr(pipe.classifier, "setup"):
        pipe.classifier.setup(ids)
    clf_cfg = cfg.get("classifier") if cfg.get("segmenter") is None else None
    acc = clf_cfg.get("accuracy") if clf_cfg is not None else None
    # a bar only on a terminal with no other job beside it; else the finished-job line below
    progress = house_progress(job_label(pipe.names, None if acc is None else float(acc)),
                              bool(cfg.run.get("progress", True)))
    rows = pipe.run(ids, progress)
    df = pd.DataFrame(rows)
    if "traceback" in df:
        df = df.drop(columns=["traceback"])
    lead = [c for c in LEADING_COLUMNS if c in df]
    df = df[lead + sorted(c for c in df.columns if c not in lead)]
    atomic_write_text(Job(out_dir).metrics_path, df.to_csv(index=False))
    failed = [r for r in rows if r.get("status") != "ok"]
    reasons = Counter(r.get("error", "").split(":")[0] for r in failed)
    summary = {
        "n_houses": len(rows), "n_ok": len(rows) - len(failed), "n_failed": len(failed),
        "failure_reasons": dict(reasons),
        "failed": [{"house_id": r["house_id"], "error": r.get("error", "")} for r in failed],
        "wall_time_s": round(time.perf_counter() - t0, 3), "keys": pipe.keys, "names": pipe.names,
    }
    ok = df[df["status"] == "ok"] if "status" in df else df
    for m in ("iou", "precision", "recall", "accuracy"):
        if m in ok and len(ok):
            summary[f"mean_{m}"] = float(ok[m].mean())
    atomic_write_json(Job(out_dir).summary_path, summary)
    log.info("%s: %d houses, %d ok, %d failed%s; mean IoU %.4f; %.1f s", out_dir, len(rows), summary["n_ok"],
             len(failed), (" (" + ", ".join(f"{k}: {v}" for k, v in reasons.items()) + ")") if failed else "",
             summary.get("mean_iou", float("nan")), summary["wall_time_s"])
    return df


__all__ = ["run", "build_pipeline", "stage_keys", "select_houses", "CONF_DIR"]
