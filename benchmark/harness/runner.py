"""The runner behind ``roomseg-bench`` (:mod:`benchmark.commands.bench`).

Checks the config (:mod:`benchmark.harness.checks`), builds a
:class:`benchmark.harness.pipeline.Pipeline` whose stages are instantiated from ``conf/`` with
``_target_`` only when a house needs them, claims the job's folder (a folder holding another
run's results is never written into: :func:`benchmark.harness.store.claim_job_dir`), runs the
selected houses and writes ``metrics.csv`` (one row per house), ``timings.csv`` (per house: the
stages' times, wall time, worker, and whether the row came from the cache), ``summary.json``
(counts, failures and why, wall time, keys, per-house content hashes) and ``resolved_config.yaml``.

The houses run on an executor (:mod:`benchmark.harness.executor`): in this process
(``run.workers=1``), on a pool of ``run.workers`` local processes (default: the cores
available) that every job of a multirun shares, or as Ray tasks (``run.executor=ray``). Rows
come back in house order, so ``metrics.csv`` is the same bytes whatever the executor.
Examples::

    roomseg-bench                                   # defaults from conf/config.yaml
    roomseg-bench aggregator=vision_cone run.limit=5
    roomseg-bench -m aggregator=graph_knn,vision_cone postprocess=none,default
    roomseg-bench experiment=table4                 # a paper table's sweep
"""

from __future__ import annotations

import logging
import os
import time
from collections import Counter
from collections.abc import Mapping, Sequence
from datetime import datetime, timezone
from functools import partial
from pathlib import Path
from typing import Any

import pandas as pd
from hydra.core.hydra_config import HydraConfig
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from benchmark.config import ROBOT_STAGES, resolved_body, robot_settings, shapes_map
from benchmark.harness.cache import atomic_write_json, atomic_write_text, config_inputs, config_key
from benchmark.harness.checks import ConfigError, check_config, check_writable
from benchmark.harness.executor import (
    CONNECT_TIMEOUT_S,
    Executor,
    HouseResult,
    JobSpec,
    RayExecutor,
    SerialExecutor,
    close_pool,
    local_pool,
)
from benchmark.harness.pipeline import (
    MethodPipeline,
    Pipeline,
    SegmenterPipeline,
    StageError,
    expand_force,
    scene_cache_limit,
)
from benchmark.harness.processes import available_cores, worker_cap
from benchmark.harness.progress import house_progress, job_label, parallel_jobs
from benchmark.harness.store import NON_ROW_KEYS, SELECTION_KEYS, Job, claim_job_dir, flat_settings
from benchmark.harness.sweep import current_sweep
from benchmark.harness.typed import check_typed
from benchmark.metrics import describe
from benchmark.paths import CONF_DIR

log = logging.getLogger("roomseg-bench")


#: first columns of metrics.csv, in this order; the rest follow alphabetically.
LEADING_COLUMNS = ("house_id", "dataset", "env", "viewpoints", "renderer", "classifier", "oracle_accuracy",
                   "aggregator", "postprocess", "segmenter", "label", "corruption", "severity", "status", "error",
                   "iou", "precision", "recall", "accuracy", "n_pred_segments", "n_gt_segments", "n_views",
                   "n_refused", "view_accuracy")

#: bump to invalidate every cache entry after a change in cached outputs' meaning (2: ProcTHOR's
#: ``empty`` walls no longer drawn, so scenes changed with no change in any config; 3: the kidnapped
#: robot's relocalising closures join the online solve without the robust kernel, so the online
#: view poses of lost and kidnap levels changed; 4: a relocalising closure that the closure search
#: proposes again is not entered twice, and the online solve takes a relocalisation's closures at
#: the node that confirmed it, so estimates after a tracking loss changed).
CACHE_VERSION = 4


def _plain(node: Any) -> Any:
    return OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else node


def stage_keys(cfg: DictConfig, names: Mapping[str, str], dataset: str) -> dict[str, str]:
    """Cache keys of the render, map, classify, aggregate and score stages for this config.

    A score entry is the row as this configuration writes it (its stage ``names``, ``env``
    included, and its ``dataset``) and, with ``run.save_maps``, vouches for the saved label maps:
    its key follows all three, so that two environments over the same houses (``env=synthetic``
    and ``env=synthetic_robust``) or two save settings never share an entry (each would take the
    other's for a bad one and recompute it)."""
    env = {k: v for k, v in (_plain(cfg.env) or {}).items() if k not in SELECTION_KEYS}
    row = {"names": dict(names), "dataset": str(dataset), "save_maps": bool(cfg.run.get("save_maps", True))}
    salt = (CACHE_VERSION, cfg.run.get("cache_salt", ""))
    robot = robot_settings(cfg)
    render = config_key("render", salt, env, _plain(cfg.get("viewpoints")), _plain(cfg.get("renderer")))
    classify = config_key("classify", render, _plain(cfg.get("classifier")))
    keys = {"render": render, "classify": classify}
    if "mapping" in robot:  # the robot's map: the house, the views it drove through, the mapping
        # views_at only chooses the views' poses from the one estimate: the estimate and the map
        # it places the scans at are the same either way, so views_final_1 shares slam_3's
        slam = [{"pose_error": {k: v for k, v in robot["pose_error"].items() if k != "views_at"}}] \
            if shapes_map(robot) else []
        keys["map"] = config_key("map", salt, env, _plain(cfg.get("viewpoints")), robot["mapping"], *slam)
    if cfg.get("segmenter") is not None:
        parts = [{"mapping": keys["map"]}] if "mapping" in robot else []
        keys["score"] = config_key("segment", salt, env, _plain(cfg.segmenter), _plain(cfg.metrics), *parts, row)
        return keys
    keys["aggregate"] = config_key("aggregate", classify, _plain(cfg.get("aggregator")), *([robot] if robot else []))
    keys["score"] = config_key("score", keys["aggregate"], _plain(cfg.get("postprocess")), _plain(cfg.metrics), row)
    return keys


def select_houses(all_ids: list[str], houses: Any, limit: Any) -> list[str]:
    """``run.houses`` (list of ids, or None for all) then ``run.limit`` (first N).

    Raises:
        ConfigError: an unknown or repeated id in ``run.houses``, or no house selected."""
    ids = list(all_ids)
    if houses:
        wanted = [str(h) for h in houses]
        missing = [h for h in wanted if h not in set(ids)]
        if missing:
            raise ConfigError(f"run.houses: unknown house id(s) {missing[:5]}; the environment has {len(ids)} "
                              f"houses, e.g. {ids[:3]}")
        repeated = sorted({h for h in wanted if wanted.count(h) > 1})
        if repeated:
            raise ConfigError(f"run.houses: house id(s) {repeated[:5]} listed more than once")
        ids = wanted
    if limit is not None:
        ids = ids[: int(limit)]
    if not ids:
        raise ConfigError(f"no house selected: the environment has {len(all_ids)} houses"
                          + (f", run.limit={limit!r}" if limit is not None else "") + "; expected at least one")
    return ids


def _choices() -> dict[str, str]:
    try:
        ch = HydraConfig.get().runtime.choices
    except ValueError:
        return {}
    return {k: (str(v) if v is not None else "") for k, v in ch.items() if not k.startswith("hydra")}


def _env_classes(env: Any, cfg: DictConfig) -> tuple[str, ...]:
    """The environment's ordered class names (its ``classes``, else ``env.classes``/``classes``)."""
    for source in (getattr(env, "classes", None), getattr(env, "raster", {}).get("classes"),
                   cfg.env.get("classes"), cfg.get("classes")):
        if source:
            return tuple(str(c) for c in source)
    return ()


#: the last job this process ran: ``houses`` scored, its folder ``dir`` and ``moved`` (the line
#: saying why it wrote beside its folder, or ""); a sweep's launcher reads it after each job.
LAST_RUN: dict[str, Any] = {}

#: environments built in this process, by resolved config and input-file fingerprints: the
#: jobs of a sweep that a worker runs one after another share one (a house file is read once).
_ENVS: dict[str, Any] = {}


def _environment(node: DictConfig) -> tuple[Any, str]:
    """``instantiate(cfg.env)``, reused across jobs of this process while its config and the
    files it names (house file, annotation folder) are unchanged. Returns (env, its key)."""
    plain = _plain(node)
    key = config_key(plain, config_inputs(plain, where="env"))
    if key not in _ENVS:
        if len(_ENVS) >= 4:
            _ENVS.pop(next(iter(_ENVS)))
        try:
            _ENVS[key] = instantiate(node)
        except Exception as e:  # a dataset that is absent: one line with the command that fetches it
            from benchmark.harness.hints import missing_data

            hint = missing_data(e)
            if hint is None:
                raise
            raise ConfigError(f"env: {hint}") from None
    return _ENVS[key], key


def _builder(node: Any):
    return (lambda: instantiate(node)) if node is not None else None


def build_pipeline(cfg: DictConfig, choices: dict[str, str] | None = None) -> Pipeline:
    """The pipeline of one configuration: the environment (instantiated now), the other stages
    as factories (instantiated when a house first needs them), the cache keys and names.

    Returns:
        A :class:`MethodPipeline`, or a :class:`SegmenterPipeline` when ``segmenter`` is set.
    """
    choices = choices if choices is not None else _choices()
    env, env_key = _environment(cfg.env)
    seg = cfg.get("segmenter")
    names = {"env": choices.get("env", getattr(env, "name", "env"))}
    method_stages = ("viewpoints", "renderer", "classifier", "aggregator", "postprocess")
    if seg is not None:
        names["segmenter"] = choices.get("segmenter", str(seg.get("_target_", "")).rsplit(".", 1)[-1])
        for k in method_stages:
            names[k] = ""
    else:
        for k in method_stages:
            names[k] = choices.get(k, str(cfg[k].get("_target_", "")).rsplit(".", 1)[-1] if cfg.get(k) else "none")
        names["segmenter"] = ""
    extra = {}
    if seg is None and cfg.classifier.get("accuracy") is not None:
        extra["oracle_accuracy"] = float(cfg.classifier.accuracy)
    extra["label"] = str(cfg.run.get("label") or "")
    metric_params = instantiate(cfg.metrics)
    extra["metric_params"] = describe(metric_params)
    robot_cfg = cfg.get("robot") or {}
    extra["corruption"] = str(robot_cfg.get("corruption", "clean"))
    extra["severity"] = int(robot_cfg.get("severity", 0))
    robot = robot_settings(cfg)
    groups: tuple[str, ...] = ("segmenter",) if seg is not None else method_stages
    if seg is not None and "mapping" in robot:  # the robot's map is built along its views
        groups = (*groups, "viewpoints")
        names["viewpoints"] = choices.get("viewpoints", "")
    robot_groups = tuple(g for g in ROBOT_STAGES if g in robot and (
        seg is None or g == "mapping" or (g == "pose_error" and "mapping" in robot and shapes_map(robot))))
    common = dict(
        env=env, cache_dir=Path(cfg.run.cache_dir), keys=stage_keys(cfg, names, getattr(env, "name", "env")), names=names,
        metric_params=metric_params, force=expand_force(cfg.run.get("force")),
        save_maps=bool(cfg.run.get("save_maps", True)), cache_aggregates=bool(cfg.run.get("cache_aggregates", True)),
        extra=extra,
        builders={k: _builder(cfg.get(k)) for k in (*groups, *robot_groups)},
        inputs={k: _plain(cfg.get(k)) for k in (*groups, *robot_groups, "metrics")},
        cache_failures=bool(cfg.run.get("cache_failures", False)), env_key=env_key,
    )
    if seg is not None:
        return SegmenterPipeline(**common)
    return MethodPipeline(**common, classes=_env_classes(env, cfg) or None)


def pipeline_from_plain(plain: dict[str, Any], choices: dict[str, str], eval_ids: Sequence[str],
                        keys: dict[str, str] | None = None) -> Pipeline:
    """A job's pipeline built in a worker process from the job's resolved plain config (no
    ``hydra`` node) and chosen options, as the driver built its own.

    Args:
        plain: ``OmegaConf.to_container(cfg without hydra, resolve=True)``.
        choices: {group: chosen option} (the stage names in every row).
        eval_ids: the job's houses (a classifier's ``setup`` refuses training houses).
        keys: the driver's cache keys: the worker's must be equal.

    Raises:
        StageError: the worker's cache keys differ from the driver's.
    """
    pipe = build_pipeline(OmegaConf.create(plain), choices)
    pipe.eval_ids = tuple(eval_ids)
    if keys is not None and pipe.keys != keys:
        raise StageError(f"a worker built other cache keys than the driver ({pipe.keys} vs {keys}): "
                         f"the resolved config does not rebuild the same job")
    return pipe


#: the lines said about capping ``run.workers`` in this process (:func:`choose_executor`).
_CAP_NOTES: set[str] = set()


def choose_executor(cfg: DictConfig, pipe: Pipeline, n_houses: int) -> Executor:
    """The executor of a job's ``n_houses`` houses (see the module docstring): Ray for
    ``run.executor=ray``; else this process when one worker would do (``run.workers=1``, one
    house, or a launcher that already runs several jobs side by side, each in its own
    process); else this process's pool of ``run.workers`` processes (default: the cores
    available)."""
    ray_cfg = cfg.run.get("ray") or {}
    if cfg.run.get("executor", "local") == "ray":
        address = ray_cfg.get("address")  # a cluster's CPUs are its own; a local instance gets the capped count
        workers = (cfg.run.get("workers") or available_cores()) if address else _workers(cfg, n_houses)
        return RayExecutor(address, workers, ray_cfg.get("connect_timeout") or CONNECT_TIMEOUT_S)
    if parallel_jobs() > 1:  # the launcher's n_jobs workers are the sweep's processes already
        return SerialExecutor(pipe)
    workers = _workers(cfg, n_houses)
    return SerialExecutor(pipe) if workers <= 1 else local_pool(workers)


def _workers(cfg: DictConfig, n_houses: int) -> int:
    """``run.workers`` (None: the cores), at most ``n_houses`` and at most what this machine
    holds (:func:`benchmark.harness.processes.worker_cap`; one warning line, once per process,
    when that cap binds)."""
    requested = cfg.run.get("workers")
    cap, note = worker_cap(requested)
    want = max(min(int(requested) if requested is not None else available_cores(), n_houses), 1)
    if note and want > cap and note not in _CAP_NOTES:
        _CAP_NOTES.add(note)
        log.warning(note)
    return min(want, cap)


def _in_multirun() -> bool:
    try:
        from hydra.types import RunMode

        return HydraConfig.get().mode == RunMode.MULTIRUN
    except (ImportError, ValueError):
        return False


def job_identity(cfg: DictConfig, ids: list[str], plain: dict[str, Any] | None = None,
                 from_data_root: bool = True) -> tuple[str, dict[str, Any]]:
    """A job's identity: a key over every setting that changes its rows (the resolved config
    without :data:`NON_ROW_KEYS`, house selection and input paths included) and the selected
    house ids. Editing a house's content keeps the identity (the rerun updates the job). Paths
    under the shared-data root (``paths.data_dir``) count from that root, so the same job has
    the same key on every checkout, wherever its ``ROOMSEG_SHARED_DATA`` points
    (``from_data_root=False``: the key of earlier versions, over the paths as resolved, which a
    job folder written by them holds).

    Returns:
        (key, settings): ``settings`` flat {dotted key: value} for "what differs" messages.
    """
    if plain is None:
        plain = resolved_body(cfg)
    settings = {k: v for k, v in flat_settings(plain).items() if k not in NON_ROW_KEYS}
    root = str((plain.get("paths") or {}).get("data_dir") or "")
    if root and from_data_root:  # where the shared data sits is the machine's, not the job's: the same job on any checkout
        settings = {k: ("${paths.data_dir}" + v[len(root):] if isinstance(v, str) and (v == root or v.startswith(
            root.rstrip("/") + "/")) else v) for k, v in settings.items()}
    settings["houses"] = f"{len(ids)} houses: {ids[0]} .. {ids[-1]} ({config_key(ids)})"
    return config_key("job", settings, ids), settings


def resolved_yaml(plain: dict[str, Any]) -> str:
    """``OmegaConf.to_yaml(body, resolve=True)`` of a config body whose resolved container is
    ``plain`` (``OmegaConf.to_container(body, resolve=True)``; the configs hold no enums), written
    from that container instead of resolving the config again (:func:`benchmark.config.yaml_text`)."""
    from benchmark.config import yaml_text

    return yaml_text(plain)


def run(cfg: DictConfig, out_dir: Path, choices: dict[str, str] | None = None) -> pd.DataFrame:
    """Run one configuration over its houses; write metrics.csv, timings.csv, summary.json and
    resolved_config.yaml.

    Returns:
        The rows (one per house, as in ``metrics.csv``: no ``t_*`` timings, which go to
        ``timings.csv``); ``df.attrs["job_dir"]`` is the folder written (``out_dir``, or its
        ``~<key>`` sibling when ``out_dir`` holds another run's results) and
        ``df.attrs["n_failed"]`` the failed houses.

    Raises:
        ConfigError: a bad setting, an unwritable folder, or no house selected (before any work).
        StageError: a stage that cannot be built or does not fit the environment.
        WorkerDied: a worker process died (the houses scored before are cached).
    """
    t0 = time.perf_counter()
    LAST_RUN.clear()  # this run's folder once claimed (an error before that belongs to out_dir)
    plain = resolved_body(cfg)
    check_config(plain)
    check_typed(plain)
    try:
        scene_cache_limit()
    except ValueError as e:
        raise ConfigError(str(e)) from None
    check_writable(cfg.run.results_dir, "run.results_dir")
    check_writable(cfg.run.cache_dir, "run.cache_dir")
    choices = choices if choices is not None else _choices()
    pipe = build_pipeline(cfg, choices)
    ids = select_houses(pipe.env.house_ids(), cfg.run.get("houses"), cfg.run.get("limit"))
    pipe.eval_ids = tuple(ids)
    key, settings = job_identity(cfg, ids, plain)
    earlier = job_identity(cfg, ids, plain, from_data_root=False)[0]
    executor = choose_executor(cfg, pipe, len(ids))
    if hasattr(executor, "connect"):  # a cluster that cannot be reached: one line, before anything is written
        executor.connect()
    try:
        out_dir, note = claim_job_dir(out_dir, key, settings, aliases=(earlier,))
    except OSError as e:
        raise ConfigError(f"cannot write the job folder {getattr(e, 'filename', None) or out_dir} "
                          f"({e.strerror or e})") from None
    LAST_RUN.clear()
    LAST_RUN.update(houses=0, dir=str(out_dir), moved=note)
    if note:  # a sweep's launcher says it once for all its jobs (this job's log file keeps it)
        log.log(logging.INFO if _in_multirun() else logging.WARNING, note)
    job = Job(out_dir)
    atomic_write_text(job.config_path, resolved_yaml(plain))
    clf_cfg = cfg.get("classifier") if cfg.get("segmenter") is None else None
    acc = clf_cfg.get("accuracy") if clf_cfg is not None else None
    # a bar only on a terminal with no other job beside it; else the finished-job line below
    progress = house_progress(job_label(pipe.names, None if acc is None else float(acc)),
                              bool(cfg.run.get("progress", True)))
    spec = JobSpec(key=config_key("worker", plain, choices, ids),
                   build=partial(pipeline_from_plain, plain, choices, tuple(ids), pipe.keys), cwd=os.getcwd())
    try:
        results = executor.map(spec, ids, progress, where=str(out_dir))
    finally:
        if not _in_multirun():  # a multirun's jobs share the pool; a single run ends with it
            close_pool()
    rows = [r.row for r in results]
    df, timings = split_timings(rows, results)
    atomic_write_text(job.timings_path, timings.to_csv(index=False))
    atomic_write_text(job.metrics_path, df.to_csv(index=False))
    failed = [r for r in rows if r.get("status") != "ok"]
    reasons = Counter(r.get("error", "").split(":")[0] for r in failed)
    built = list(dict.fromkeys(stage for r in results for stage in r.built))
    summary = {
        "n_houses": len(rows), "n_ok": len(rows) - len(failed), "n_failed": len(failed),
        "failure_reasons": dict(reasons),
        "failed": [{"house_id": r["house_id"], "error": r.get("error", "")} for r in failed],
        "wall_time_s": round(time.perf_counter() - t0, 3), "keys": pipe.keys, "names": pipe.names,
        "job_key": key, "stages_built": built, "contents": {h: r.content for h, r in zip(ids, results)},
        "executor": executor.name, "workers": int(getattr(executor, "workers", 1) or 1),
        "n_cached": sum(r.cached for r in results),
        # newest job wins where two jobs hold the same configuration and house (reports/tables.py)
        "finished_at": datetime.now(timezone.utc).isoformat(),
        "sweep_id": current_sweep() if _in_multirun() else None,  # the multirun that ran this job
    }
    ok = df[df["status"] == "ok"] if "status" in df else df
    for m in ("iou", "precision", "recall", "accuracy"):
        if m in ok and len(ok):
            summary[f"mean_{m}"] = float(ok[m].mean())
    atomic_write_json(job.summary_path, summary)
    log.info("%s: %s", out_dir, finished_line(summary, failed, reasons))
    df.attrs["job_dir"] = str(out_dir)
    df.attrs["n_failed"] = len(failed)
    LAST_RUN["houses"] = len(rows)
    return df


def finished_line(summary: dict[str, Any], failed: Sequence[dict[str, Any]], reasons: Counter) -> str:
    """The line a finished job logs: houses, ok, failed (by reason, and the first failure's own
    line, which names the file a missing input is), the mean IoU in percent (as every table
    prints it; none when no house succeeded) and the wall time."""
    n = summary["n_houses"]
    text = f"{n} house{'' if n == 1 else 's'}, {summary['n_ok']} ok, {len(failed)} failed"
    if failed:
        first = failed[0]
        why = " ".join(str(first.get("error") or "no reason recorded").split())
        text += f" ({', '.join(f'{k}: {v}' for k, v in reasons.items())}; first {first.get('house_id')}: {why})"
    iou = summary.get("mean_iou")
    text += f"; mean IoU {100 * iou:.2f} %" if iou is not None and iou == iou else "; no mean IoU (no house succeeded)"
    return f"{text}; {summary['wall_time_s']:.1f} s"


def split_timings(rows: list[dict[str, Any]], results: Sequence[HouseResult]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The rows as ``metrics.csv`` holds them (leading columns first, the rest alphabetical;
    no traceback and no ``t_*`` timings, which differ from run to run) and ``timings.csv``:
    per house (same order) ``house_id``, ``cached`` (row served from the cache: its ``t_*``
    are those of the run that computed it), ``house_s`` (wall seconds in its worker, this
    run), ``worker`` (``host:pid``) and each ``t_*`` stage time in seconds."""
    df = pd.DataFrame(rows)
    timing_cols = sorted(c for c in df.columns if c.startswith("t_"))
    timings = pd.DataFrame({"house_id": [r.get("house_id") for r in rows],
                            "cached": [bool(r.cached) for r in results],
                            "house_s": [round(r.seconds, 6) for r in results],
                            "worker": [r.worker for r in results]})
    for c in timing_cols:
        timings[c] = df[c].to_numpy()
    df = df.drop(columns=[c for c in ("traceback", *timing_cols) if c in df])
    lead = [c for c in LEADING_COLUMNS if c in df]
    return df[lead + sorted(c for c in df.columns if c not in lead)], timings


__all__ = ["run", "build_pipeline", "pipeline_from_plain", "choose_executor", "split_timings", "stage_keys", "select_houses", "job_identity", "CONF_DIR", "ConfigError"]
