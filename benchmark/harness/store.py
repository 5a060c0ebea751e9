"""The run store: the one module that knows where runs, jobs, rows, saved maps and cache
entries live. The runner, tables, figures, perf and the post-processing timing all ask it;
nothing else joins these paths.

Layout (``results_dir`` and ``cache_dir`` come from ``run.results_dir`` / ``run.cache_dir``;
the cache may live anywhere)::

    <results_dir>/runs/<run name>/[<job subdir>/]   a job (one configuration):
        metrics.csv            one row per house
        summary.json           counts, failures, wall time, cache keys, stage names
        resolved_config.yaml   the full config, every interpolation resolved
    <cache_dir>/render/<render key>/<house>/        observations (envs.render.cache layout)
    <cache_dir>/classify/<classify key>/<house>.npz proba (N, C), poses (N, 3)
    <cache_dir>/scores/<score key>/<house>.json     the house's metrics row
    <cache_dir>/maps/<score key>/<house>.npz        raw / post-processed label maps, poses
                                                    (segmenters: instances)
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: the files every finished job folder holds.
METRICS, SUMMARY, CONFIG = "metrics.csv", "summary.json", "resolved_config.yaml"


def safe_name(house_id: str) -> str:
    """A house id made safe as a file name (letters, digits, ``-_.``; anything else -> ``_``)."""
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in str(house_id))


@dataclass(frozen=True)
class CacheStore:
    """Where the stage caches live under ``root`` (``run.cache_dir``)."""

    root: Path

    def render_dir(self, key: str, house_id: str) -> Path:
        return self.root / "render" / key / safe_name(house_id)

    def classify_path(self, key: str, house_id: str) -> Path:
        return self.root / "classify" / key / f"{safe_name(house_id)}.npz"

    def score_path(self, key: str, house_id: str) -> Path:
        return self.root / "scores" / key / f"{safe_name(house_id)}.json"

    def maps_path(self, key: str, house_id: str) -> Path:
        return self.root / "maps" / key / f"{safe_name(house_id)}.npz"

    def model_path(self, kind: str, key: str, suffix: str = ".npz") -> Path:
        """A fitted model (e.g. the objects classifier) cached by the content of its training set."""
        return self.root / "models" / kind / f"{key}{suffix}"


@dataclass(frozen=True)
class Job:
    """A finished (or running) job folder and what it says about itself."""

    dir: Path

    @property
    def metrics_path(self) -> Path:
        return self.dir / METRICS

    @property
    def summary_path(self) -> Path:
        return self.dir / SUMMARY

    @property
    def config_path(self) -> Path:
        return self.dir / CONFIG

    def is_finished(self) -> bool:
        return self.metrics_path.exists() and self.summary_path.exists() and self.config_path.exists()

    def config(self):
        """The job's resolved config (an OmegaConf DictConfig)."""
        from omegaconf import OmegaConf

        return OmegaConf.load(self.config_path)

    def summary(self) -> dict[str, Any]:
        import json

        with open(self.summary_path, encoding="utf-8") as f:
            return json.load(f)

    def cache(self) -> CacheStore:
        """The cache this job wrote to (its ``run.cache_dir``, wherever that is)."""
        return CacheStore(Path(str(self.config().run.cache_dir)))

    def maps_path(self, house_id: str) -> Path:
        """The saved label maps of one house of this job (may not exist: ``run.save_maps``)."""
        return self.cache().maps_path(self.summary()["keys"]["score"], house_id)


def job_dir_for(results_dir: str | Path, run_name: str, subdir: str | None = None) -> Path:
    """The folder of a run (``subdir`` None) or of one job of a sweep."""
    base = Path(results_dir) / "runs" / run_name
    return base / subdir if subdir else base


def find_jobs(paths: Sequence[str | Path], finished_only: bool = True) -> list[Job]:
    """Every job folder at or under ``paths`` (a folder holding ``metrics.csv``), sorted.

    Raises:
        FileNotFoundError: a path that does not exist, or no job under any of them.
    """
    out: list[Job] = []
    for p in map(Path, paths):
        if p.is_file() and p.name == METRICS:
            out.append(Job(p.parent))
        elif p.is_dir():
            out.extend(Job(m.parent) for m in sorted(p.rglob(METRICS)))
        else:
            raise FileNotFoundError(f"no run folder or {METRICS} at {p}")
    if finished_only:
        out = [j for j in out if j.is_finished()]
    if not out:
        raise FileNotFoundError(f"no finished job ({METRICS} + {SUMMARY} + {CONFIG}) under {[str(p) for p in paths]}")
    return out


def iter_metric_files(paths: Sequence[str | Path]) -> Iterator[Path]:
    """The ``metrics.csv`` of every job under ``paths`` (a path may be a CSV file itself)."""
    for p in map(Path, paths):
        if p.is_file():
            yield p
        elif p.is_dir():
            yield from sorted(p.rglob(METRICS))
        else:
            raise FileNotFoundError(f"no run folder or metrics file at {p}")


__all__ = ["CacheStore", "Job", "find_jobs", "iter_metric_files", "job_dir_for", "safe_name",
           "METRICS", "SUMMARY", "CONFIG"]
