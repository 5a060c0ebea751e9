"""Trust in rows and cache entries (issue 61, items 4, 8 and part of 11): every reader of
``metrics.csv`` rows goes through one loader with the checks ``tables`` applies (a file holding
a house twice for one configuration is refused by ``report`` and ``figures`` too, not averaged);
a cache entry belongs to its full key (``make bench`` and ``make robustness`` into one results
folder never evict each other's score entries); a robustness summary whose sweep records are
gone does not average a family over the severities left as if they were all."""

from __future__ import annotations

import logging
from pathlib import Path

import pandas as pd

from benchmark.config import compose_job
from benchmark.harness.runner import run

ROOT = Path(__file__).resolve().parents[1]
FAST = ["env.resolution=0.1", "classifier=oracle", "run.limit=1", "viewpoints.spacing=1.0", "run.progress=false",
        "aggregator=graph_knn", "postprocess=default"]
ROW = ["house_id", "status", "iou", "precision", "recall", "accuracy", "matched_iou", "n_views"]


# ------------------------------------------------------------------ item 8: a cache entry belongs to its full key
def _score_entries(results: Path) -> dict[Path, int]:
    return {p: p.stat().st_mtime_ns for p in (results / "cache" / "scores").rglob("*.json")}


def test_bench_and_robustness_settings_into_one_results_folder_keep_their_own_score_entries(tmp_path, caplog):
    """The issue's pair: ``make bench`` (env=synthetic, maps kept) and ``make robustness``
    (env=synthetic_robust: the same houses; run.save_maps=false; its clean condition has the
    bench's stages) into one results_dir, and a third with the bench's env but no maps. Each
    evicted the other's score entry ("env is 'synthetic', expected 'synthetic_robust'", "the
    entry has no maps file"); now each has its own, and a second round reads them all back with
    no warning, computing nothing."""
    results = tmp_path / "R"
    settings = {"bench": ["env=synthetic"],
                "robustness": ["env=synthetic_robust", "corruption=clean", "run.save_maps=false"],
                "no maps": ["env=synthetic", "run.save_maps=false"]}
    first, keys = {}, {}
    with caplog.at_level(logging.WARNING, logger="roomseg-bench"):
        for name, over in settings.items():
            cfg, ch = compose_job([*FAST, f"run.results_dir={results}", *over])
            first[name] = run(cfg, tmp_path / name, ch)
            keys[name] = first[name]["score_key"].iloc[0]
        assert not [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
        entries = _score_entries(results)
        assert len(set(keys.values())) == 3 and len(entries) == 3  # one entry per full key
        for name, over in settings.items():  # the second round: everything from the cache
            cfg, ch = compose_job([*FAST, f"run.results_dir={results}", *over])
            again = run(cfg, tmp_path / name, ch)
            pd.testing.assert_frame_equal(again[ROW], first[name][ROW])
            assert again["env"].iloc[0] == first[name]["env"].iloc[0] and again["score_key"].iloc[0] == keys[name]
    warned = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert warned == []  # no "bad cache entry" for a normal second run
    assert _score_entries(results) == entries  # none rewritten
    assert first["bench"]["env"].iloc[0] == "synthetic" and first["robustness"]["env"].iloc[0] == "synthetic_robust"
    # the maps the bench keeps are vouched for by its own entry; the others keep none
    maps = sorted((results / "cache" / "maps").rglob("*.npz"))
    assert [p.parent.name for p in maps] == [keys["bench"]]
