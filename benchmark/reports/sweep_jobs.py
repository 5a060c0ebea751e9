"""Which jobs of a sweep did not finish: so that no table reads part of a sweep silently.

A multirun writes ``multirun.yaml`` into its sweep folder (Hydra): the sweeper's ``params``,
its extra ``grids`` (``hydra_plugins/roomseg_sweep``) and the command line's overrides. From it
:func:`expected_jobs` lists every job the sweep was asked to run (the overrides of each, as
Hydra's basic sweeper expands them, each grid after ``params``, a job listed twice once), and
:func:`missing_jobs` those without a finished job folder (``.hydra/overrides.yaml`` naming the
same overrides, beside ``metrics.csv``, ``summary.json`` and ``resolved_config.yaml``): a job
never started, stopped, or whose files were removed. :func:`partial_sweep_lines` says it in one
line per sweep. A folder without ``multirun.yaml`` (a single run, a published copy) is not
checked here.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from benchmark.harness.store import Job

MULTIRUN = "multirun.yaml"


def _expand(overrides: Sequence[str]) -> list[tuple[str, ...]]:
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    from hydra.core.override_parser.overrides_parser import OverridesParser

    parsed = OverridesParser.create().parse_overrides(list(overrides))
    return [tuple(sorted(job)) for job in BasicSweeper.split_arguments(parsed, None)[0]]


def expected_jobs(sweep_dir: str | Path) -> list[tuple[str, ...]] | None:
    """The overrides of every job the sweep in ``sweep_dir`` was asked to run (each sorted), or
    None when the folder has no ``multirun.yaml``.

    Raises:
        ValueError: an unreadable ``multirun.yaml`` (the message names it)."""
    from omegaconf import OmegaConf

    path = Path(sweep_dir) / MULTIRUN
    if not path.exists():
        return None
    try:
        cfg = OmegaConf.load(path)
        hydra = cfg.hydra
        task = [str(x) for x in hydra.overrides.task]
        sweeper = hydra.sweeper
        params = {str(k): str(v) for k, v in (sweeper.get("params") or {}).items()}
        grids = [{str(k): str(v) for k, v in g.items()} for g in (sweeper.get("grids") or [])]
    except Exception as e:  # noqa: BLE001 - any YAML or structure error is a malformed file
        raise ValueError(f"{path}: unreadable sweep description ({type(e).__name__}: {str(e).strip()[:120]})") from None
    jobs: dict[tuple[str, ...], None] = {}
    for grid in [params, *grids]:
        keys = {o.split("=", 1)[0].lstrip("+~") for o in task}
        base = [f"{k}={v}" for k, v in grid.items() if k not in keys]  # the command line wins over a grid
        for job in _expand(base + task):
            jobs.setdefault(job, None)
    return list(jobs)


def _finished(sweep_dir: Path) -> set[tuple[str, ...]]:
    """The overrides of every finished job in the sweep folder (each sorted). Hydra writes a job's
    ``overrides.yaml`` as a YAML list of ``key=value`` strings: read by PyYAML's safe loader (libyaml's
    where PyYAML has it: a thirtieth of ``OmegaConf.load``'s time, the same strings)."""
    import yaml

    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    out = set()
    for ov in sweep_dir.glob("*/.hydra/overrides.yaml"):
        job = Job(ov.parent.parent)
        if not job.is_finished():
            continue
        try:
            items = yaml.load(ov.read_text(encoding="utf-8"), Loader=loader)
        except Exception:  # noqa: BLE001 - an unreadable overrides file: the job counts as missing
            continue
        if isinstance(items, list):  # anything else is no overrides file Hydra wrote: missing too
            out.add(tuple(sorted(str(x) for x in items)))
    return out


def missing_jobs(sweep_dir: str | Path) -> tuple[int, list[str]] | None:
    """(jobs expected, the unfinished ones in words: each job's overrides that not every job
    shares, e.g. ``corruption=scan_3, segmenter=voronoi``), or None without ``multirun.yaml``."""
    expected = expected_jobs(sweep_dir)
    if expected is None:
        return None
    done = _finished(Path(sweep_dir))
    common = set.intersection(*(set(j) for j in expected)) if expected else set()
    missing = [", ".join(o for o in job if o not in common) or ", ".join(job) for job in expected if job not in done]
    return len(expected), missing


def partial_sweep_lines(paths: Sequence[str | Path], limit: int = 4) -> list[str]:
    """One line per sweep at or under ``paths`` whose jobs did not all finish, e.g. ``sweep
    R/runs/robustness: 8 of 12 jobs finished; missing: corruption=scan_3, segmenter=voronoi; ...
    (their rows are in no table)``."""
    sweeps: dict[Path, None] = {}
    for p in map(Path, paths):
        p = p.parent if p.is_file() else p
        for cand in (p, p.parent):
            if (cand / MULTIRUN).exists():
                sweeps.setdefault(cand.resolve(), None)
        if p.is_dir():
            for m in sorted(p.rglob(MULTIRUN)):
                sweeps.setdefault(m.parent.resolve(), None)
    out = []
    for sweep in sweeps:
        found = missing_jobs(sweep)
        if not found or not found[1]:
            continue
        n, missing = found
        shown = "; ".join(missing[:limit]) + (f"; and {len(missing) - limit} more" if len(missing) > limit else "")
        out.append(f"sweep {sweep}: {n - len(missing)} of {n} jobs finished; missing: {shown} "
                   f"(their rows are in no table: rerun the sweep to finish them)")
    return out


__all__ = ["MULTIRUN", "expected_jobs", "missing_jobs", "partial_sweep_lines"]
