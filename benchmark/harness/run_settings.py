"""The ``run:`` node of ``conf/config.yaml``, typed: what the harness itself reads.

``run`` is not a ``_target_`` node (no stage class takes it as keyword arguments), so the
frozen dataclass :class:`RunSettings` is its schema: one field per key of the node, in the
node's order, each with its type and, where a type cannot say it, a range marker of
:mod:`envs.ranges` in ``Annotated[...]`` (``limit: Annotated[int | None, Integer(1)]``). The
check (:func:`benchmark.harness.checks.check_config`, and the command line before a sweep:
:func:`benchmark.harness.checks.check_run_overrides`) reads them with the machinery that
checks the stages (:func:`benchmark.harness.typed.check_fields`); a key the dataclass does not
have is refused, listing its fields (tests/test_run_settings.py checks that they are the keys
of ``conf/config.yaml``'s ``run:`` node, in order, and that the defaults are the same).

Standard library and :mod:`envs.ranges` only: importing this module costs nothing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated, Any

from envs.ranges import Integer, NonEmpty, OneOf, Range, Seconds, Text

#: Stages that ``run.force`` can name, in pipeline order; forcing one forces those after it
#: (:func:`benchmark.harness.pipeline.expand_force`, which takes them from here).
STAGES = ("render", "map", "classify", "aggregate", "score")


class RayAddress(Range):
    """Where Ray runs: ``auto`` (the cluster this machine joined with ``ray start``),
    ``host:port`` of a cluster's head, or ``ray://host:port`` (Ray Client); a port is digits."""

    what = "auto, host:port or ray://host:port"

    def __call__(self, value: Any) -> bool:
        if not isinstance(value, str):
            return False
        if value == "auto":
            return True
        host, colon, port = value.removeprefix("ray://").rpartition(":")
        return bool(colon and host and port.isdigit())


#: the longest ``run.name`` (a folder name; a sweep's job folders and ``~<key>`` siblings add to it).
MAX_RUN_NAME = 120


class RunName(Text):
    """``run.name``: one folder name under ``<results_dir>/runs`` (a string, or a number read as
    text): not empty, no ``/`` or ``\\``, not starting with a dot (``.`` and ``..`` would name the
    runs folder or the results root, ``../x`` a folder outside it), no control characters, at
    most :data:`MAX_RUN_NAME` characters. A sweep's job folders under it follow their own rule
    (``benchmark.config.job_dirname``)."""

    what = (f"one folder name (a string or a number; no / or \\, not starting with a dot, at most "
            f"{MAX_RUN_NAME} characters)")

    def __call__(self, value: Any) -> bool:
        if not super().__call__(value):
            return False
        name = str(value)
        return (0 < len(name) <= MAX_RUN_NAME and not name.startswith(".") and "/" not in name
                and "\\" not in name and name.isprintable())


class StageNames(Range):
    """``run.force``: a list of stage names (or one name), ``all`` for every stage.

    Args:
        stages: the names, in pipeline order (default :data:`STAGES`).
    """

    def __init__(self, stages: tuple[str, ...] = STAGES) -> None:
        self.stages = tuple(stages)
        self.what = f"a list of stage names from {list(self.stages)} or 'all'"

    def _items(self, value: Any) -> list[Any] | None:
        items = [value] if isinstance(value, str) else value
        return list(items) if isinstance(items, list | tuple) else None

    def __call__(self, value: Any) -> bool:
        items = self._items(value)
        return items is not None and all(isinstance(f, str) and f in (*self.stages, "all") for f in items)

    def explain(self, value: Any, nullable: bool = False) -> str:
        """Names the unknown stages when every item is a string: ``unknown stage(s) ['bogus']``."""
        items = self._items(value)
        if items is not None and all(isinstance(f, str) for f in items):
            unknown = [f for f in items if f not in (*self.stages, "all")]
            return f"unknown stage(s) {unknown}; expected names from {list(self.stages)} or 'all'"
        return super().explain(value, nullable)


@dataclass(frozen=True)
class RaySettings:
    """``run.ray``: where the houses run when ``run.executor=ray``.

    Attributes:
        address: a cluster (:class:`RayAddress`), or None for a local Ray instance with
            ``run.workers`` CPUs.
        connect_timeout: seconds to reach the cluster at ``address`` before one line
            "cannot connect".
    """

    address: Annotated[str | None, RayAddress()] = None
    connect_timeout: Annotated[float, Seconds()] = 30


@dataclass(frozen=True)
class RunSettings:
    """``run``: how the harness runs a job (not what it computes: no key here but ``houses``,
    ``limit`` and ``label`` reaches a row, and none reaches a cache key but ``cache_salt``).

    Attributes:
        name: the run's folder, ``<results_dir>/runs/<name>``: one folder name (:class:`RunName`).
        label: free text copied into every row.
        houses: house ids to run (each a string or an integer), or None for all houses.
        limit: the first N houses only (after ``houses``), or None for all.
        force: stages to redo even if cached (:class:`StageNames`); None or [] for none.
        progress: draw a progress bar.
        save_maps: keep the raw and post-processed label maps (for figures).
        cache_aggregates: keep each house's aggregated label map in the stage cache, for the jobs
            that differ from this one only in post-processing or metrics (they read it instead of
            aggregating again); false: none is written (a sweep with no two such jobs).
        results_dir: the folder of runs, rows and caches (a path).
        cache_dir: the stage caches (a path; default ``<results_dir>/cache``).
        cache_salt: text in every cache key; change it to start a fresh cache.
        allow_failures: exit 0 even when some houses failed.
        cache_failures: serve a house's logged failure instead of retrying it.
        workers: processes that run a job's houses, or None for the cores available.
        executor: ``local`` (``workers`` processes of this machine) or ``ray``.
        ray: :class:`RaySettings`.
    """

    name: Annotated[str | int | float, RunName()] = "default"
    label: Annotated[str | int | float, Text()] = ""
    houses: Annotated[list[str | int] | None, NonEmpty("house ids")] = None
    limit: Annotated[int | None, Integer(1)] = None
    force: Annotated[list[str] | str | None, StageNames()] = field(default_factory=list)
    progress: bool = True
    save_maps: bool = True
    cache_aggregates: bool = True
    results_dir: str = "results"
    cache_dir: str = "results/cache"
    cache_salt: Annotated[str | int | float, Text()] = ""
    allow_failures: bool = False
    cache_failures: bool = False
    workers: Annotated[int | None, Integer(1)] = None
    executor: Annotated[str, OneOf("local", "ray")] = "local"
    ray: RaySettings = field(default_factory=RaySettings)


__all__ = ["MAX_RUN_NAME", "STAGES", "RayAddress", "RaySettings", "RunName", "RunSettings", "StageNames"]
