"""The benchmark runner: sweeps, caches, resume, failures, resolved configs, tables."""

from __future__ import annotations

import gzip
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hydra import compose, initialize_config_dir

from benchmark.harness.pipeline import expand_force
from benchmark.harness.runner import CONF_DIR, run, select_houses

ROOT = Path(__file__).resolve().parents[1]
FAST = ["viewpoints.spacing=1.0", "env.resolution=0.1", "env.start=0"]


def _houses_file(tmp_path: Path, procthor_file: Path, n: int = 3, bad_at: int | None = None) -> Path:
    """A small house file cut from the shared houses, optionally with one malformed house."""
    lines = []
    with gzip.open(procthor_file, "rt") as f:
        for i, line in enumerate(f):
            if i >= n:
                break
            lines.append(line.strip())
    if bad_at is not None:
        h = json.loads(lines[bad_at])
        h["rooms"][0]["roomType"] = "Garage"
        lines[bad_at] = json.dumps(h)
    path = tmp_path / "houses.jsonl"
    path.write_text("\n".join(lines) + "\n")
    return path


def _compose(tmp_path: Path, houses: Path, *overrides: str):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=[
            "env=procthor_shared", f"env.path={houses}", "classifier=oracle", "classifier.accuracy=0.8",
            f"run.results_dir={tmp_path / 'results'}", "run.progress=false", *FAST, *overrides,
        ], return_hydra_config=True)
    choices = {k: str(v) for k, v in cfg.hydra.runtime.choices.items() if not k.startswith("hydra")}
    return cfg, choices


def _snapshot(cache: Path) -> dict[str, float]:
    return {str(p): p.stat().st_mtime_ns for p in cache.rglob("*") if p.is_file() and not p.name.endswith(".lock")}


@pytest.mark.slow
def test_grid_writes_one_row_per_house_and_config_and_rerun_does_no_work(tmp_path, procthor_file):
    houses = _houses_file(tmp_path, procthor_file, n=2)
    rows = []
    for agg in ("graph_knn", "vision_cone"):
        for post in ("none", "default"):
            cfg, ch = _compose(tmp_path, houses, f"aggregator={agg}", f"postprocess={post}")
            rows.append(run(cfg, tmp_path / "out" / f"{agg}-{post}", ch))
    df = pd.concat(rows)
    assert len(df) == 8 and (df["status"] == "ok").all()
    assert df.groupby(["house_id", "aggregator", "postprocess"]).size().max() == 1
    # render and classify happened once per house: one render key, one classify key
    cache = tmp_path / "results" / "cache"
    assert len(list((cache / "render").iterdir())) == 1
    assert len(list((cache / "classify").iterdir())) == 1
    assert len(list((cache / "scores").iterdir())) == 4
    before = _snapshot(cache)
    cfg, ch = _compose(tmp_path, houses, "aggregator=vision_cone", "postprocess=default")
    again = run(cfg, tmp_path / "out" / "again", ch)
    assert _snapshot(cache) == before  # nothing recomputed, nothing rewritten
    pd.testing.assert_frame_equal(again.reset_index(drop=True),
                                  rows[3].reset_index(drop=True))
    # the resolved config is saved beside the results, with interpolations resolved
    text = (tmp_path / "out" / "again" / "resolved_config.yaml").read_text()
    assert "${" not in text and "vision_cone" in text.lower() or "VisionCone" in text
    from omegaconf import OmegaConf

    assert text == OmegaConf.to_yaml(OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"]), resolve=True)


def test_force_redoes_the_named_stage_and_after(tmp_path, procthor_file):
    houses = _houses_file(tmp_path, procthor_file, n=1)
    cfg, ch = _compose(tmp_path, houses)
    run(cfg, tmp_path / "o1", ch)
    cache = tmp_path / "results" / "cache"
    before = _snapshot(cache)
    cfg, ch = _compose(tmp_path, houses, "run.force=[classify]")
    run(cfg, tmp_path / "o2", ch)
    after = _snapshot(cache)
    changed = {Path(p).parts[-3] for p in before if after.get(p) != before[p]}
    assert changed == {"classify", "aggregate", "scores", "maps"}
    cfg, ch = _compose(tmp_path, houses, "run.force=[score]")
    run(cfg, tmp_path / "o3", ch)
    again = _snapshot(cache)
    assert {Path(p).parts[-3] for p in after if again.get(p) != after[p]} == {"scores", "maps"}
    assert expand_force(["render"]) == {"render", "map", "classify", "aggregate", "score"}
    assert expand_force(["map"]) == {"map", "classify", "aggregate", "score"}
    assert expand_force(["aggregate"]) == {"aggregate", "score"}
    with pytest.raises(ValueError, match="run.force"):
        expand_force(["paint"])


def test_malformed_house_fails_alone_with_its_reason(tmp_path, procthor_file):
    houses = _houses_file(tmp_path, procthor_file, n=3, bad_at=1)
    cfg, ch = _compose(tmp_path, houses)
    df = run(cfg, tmp_path / "out", ch)
    assert df["status"].tolist() == ["ok", "failed", "ok"]
    err = df.loc[1, "error"]
    assert "houses-00001" in err and "roomType" in err and "Garage" in err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["n_failed"] == 1 and summary["n_ok"] == 2
    assert summary["failed"][0]["house_id"] == "houses-00001"


def test_select_houses_errors():
    assert select_houses(["a", "b", "c"], None, 2) == ["a", "b"]
    assert select_houses(["a", "b", "c"], ["c"], None) == ["c"]
    with pytest.raises(ValueError, match="unknown house id"):
        select_houses(["a"], ["zz"], None)


@pytest.mark.slow
def test_killed_multirun_resumes_without_duplicates_or_losses(tmp_path, procthor_file):
    """A real `-m` multirun from the shell, killed midway, then rerun to completion."""
    houses = _houses_file(tmp_path, procthor_file, n=4)
    res = tmp_path / "results"
    cmd = [sys.executable, "-m", "benchmark.commands.bench", "-m", "env=procthor_shared", f"env.path={houses}",
           "classifier=oracle", "aggregator=graph_knn,euclidean_knn", "postprocess=none",
           f"run.results_dir={res}", "run.name=kill", "run.progress=false", "hydra/launcher=basic", *FAST]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True)
    deadline = time.time() + 240
    while time.time() < deadline and proc.poll() is None:
        if len(list(res.glob("cache/scores/*/*.json"))) >= 2:
            break
        time.sleep(0.05)
    killed = proc.poll() is None
    if killed:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    n_done = len(list(res.glob("cache/scores/*/*.json")))
    assert killed and n_done < 8  # it really stopped midway
    out = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    csvs = sorted((res / "runs" / "kill").rglob("metrics.csv"))
    assert len(csvs) == 2
    df = pd.concat(pd.read_csv(c) for c in csvs)
    assert len(df) == 8 and df.groupby(["house_id", "aggregator"]).size().eq(1).all()
    assert (df["status"] == "ok").all()
    assert all((c.parent / "resolved_config.yaml").exists() for c in csvs)


def test_tables_match_hand_computed_means(tmp_path):
    from benchmark.reports.tables import render

    rows = pd.DataFrame({
        "house_id": ["h1", "h2", "h1", "h2", "h1", "h2"],
        "dataset": ["synthetic"] * 6,
        "classifier": ["oracle"] * 6,
        "aggregator": ["graph_knn", "graph_knn", "vision_cone", "vision_cone", "vision_cone", "vision_cone"],
        "postprocess": ["default", "default", "default", "default", "none", "none"],
        "segmenter": [""] * 6,
        "iou": [0.5, 0.7, 0.2, 0.4, 0.1, np.nan],
        "accuracy": [0.6, 0.8, 0.3, 0.5, 0.2, np.nan],
        "status": ["ok", "ok", "ok", "ok", "ok", "failed"],
        "error": ["", "", "", "", "", "HouseError: bad"],
    })
    run_dir = tmp_path / "runs" / "x"
    run_dir.mkdir(parents=True)
    rows.to_csv(run_dir / "metrics.csv", index=False)
    text = render([tmp_path / "runs"], ["table4", "table3"], tmp_path / "tables")
    t4 = pd.read_csv(tmp_path / "tables" / "table4.csv")
    knn = t4[t4["aggregator"] == "graph_knn"].iloc[0]
    assert knn["iou_mean"] == pytest.approx(0.6) and knn["iou_std"] == pytest.approx(np.std([0.5, 0.7], ddof=1))
    assert knn["accuracy_mean"] == pytest.approx(0.7) and knn["n"] == 2
    cone = t4[t4["aggregator"] == "vision_cone"].iloc[0]
    assert cone["iou_mean"] == pytest.approx(0.3)
    t3 = pd.read_csv(tmp_path / "tables" / "table3.csv")
    none = t3[t3["postprocess"] == "none"].iloc[0]
    assert none["iou_mean"] == pytest.approx(0.1) and none["n"] == 1 and none["n_failed"] == 1
    dflt = t3[t3["postprocess"] == "default"].iloc[0]
    assert dflt["iou_mean"] == pytest.approx(np.mean([0.5, 0.7, 0.2, 0.4]))
    assert "60.00 [50.00, 70.00]" in text  # graph_knn IoU in percent: mean [95 % interval of two houses]
    assert knn["iou_lo"] == pytest.approx(0.5) and knn["iou_hi"] == pytest.approx(0.7)
    assert (tmp_path / "tables" / "table4.tex").read_text().count("\\\\") >= 2
    assert "1 of 6 rows failed: HouseError x1" in text


def test_postprocessing_variants_share_one_aggregation(tmp_path, procthor_file):
    """Jobs that differ only in post-processing aggregate once: the second reads the raw map
    the first cached, and its raw map equals the first job's."""
    from benchmark.harness.cache import load_npz
    from benchmark.harness.store import find_jobs

    houses = _houses_file(tmp_path, procthor_file, n=1)
    cfg, ch = _compose(tmp_path, houses, "postprocess=none")
    run(cfg, tmp_path / "none", ch)
    agg = sorted((tmp_path / "results" / "cache" / "aggregate").rglob("*.npz"))
    assert len(agg) == 1
    stamp = agg[0].stat().st_mtime_ns
    cfg, ch = _compose(tmp_path, houses, "postprocess=default")
    df = run(cfg, tmp_path / "default", ch)
    assert sorted((tmp_path / "results" / "cache" / "aggregate").rglob("*.npz")) == agg
    timings = pd.read_csv(tmp_path / "default" / "timings.csv")
    assert agg[0].stat().st_mtime_ns == stamp  # loaded, not recomputed
    assert "t_aggregate" not in timings and "t_postprocess" in timings and not timings["cached"].any()
    raws = [load_npz(j.maps_path(df["house_id"][0]))["raw"] for j in find_jobs([tmp_path / "none", tmp_path / "default"])]
    assert np.array_equal(raws[0], raws[1])


def test_without_cached_aggregates_the_rows_are_the_same_and_no_entry_is_written(tmp_path, procthor_file):
    """run.cache_aggregates=false (the robustness sweep's): no aggregated label map is written to
    the cache, nor read; the rows, the raw maps and the job's identity are those of the job that
    keeps them (the setting changes no row)."""
    from benchmark.harness.cache import load_npz
    from benchmark.harness.store import Job

    houses = _houses_file(tmp_path, procthor_file, n=2)
    cfg, ch = _compose(tmp_path, houses, "run.cache_aggregates=false", "run.cache_salt=off")
    off = run(cfg, tmp_path / "off", ch)
    assert not (tmp_path / "results" / "cache" / "aggregate").exists()
    assert "t_aggregate" in pd.read_csv(tmp_path / "off" / "timings.csv")
    cfg, ch = _compose(tmp_path, houses, "run.cache_salt=on")
    on = run(cfg, tmp_path / "on", ch)
    assert len(list((tmp_path / "results" / "cache" / "aggregate").rglob("*.npz"))) == 2
    cols = [c for c in on.columns if not c.endswith("_key")]  # (the cache keys hold the salt)
    pd.testing.assert_frame_equal(off[cols].reset_index(drop=True), on[cols].reset_index(drop=True))
    for hid in on["house_id"]:
        assert np.array_equal(load_npz(Job(tmp_path / "off").maps_path(hid))["raw"],
                              load_npz(Job(tmp_path / "on").maps_path(hid))["raw"])
    assert Job(tmp_path / "off").identity()["key"] == Job(tmp_path / "on").identity()["key"]
