"""Per-job progress of the runner: a bar on a terminal when the job runs alone, nothing otherwise.

Several joblib workers share one stderr; their carriage-return bars overwrite each other on
a terminal and pile up into one long line in a log file. So a job draws a tqdm bar (one
line, left on screen when done, named in words) only when stderr is a terminal and no
other job runs beside it; otherwise it draws nothing while it runs, and the runner's one
line per finished job (and the sweep's summary at the end) is what is printed. A job whose
houses run on a pool of processes (``run.workers``) is still one job: the driver draws its
bar, advanced as houses finish in any worker.

A sweep (a Hydra multirun) shows one progress line for the whole of it instead
(:class:`SweepProgress`): jobs done of the total, houses per second and the time left,
redrawn in place on a terminal and written at every tenth of the jobs otherwise; the jobs'
own lines go to their log files.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable, Mapping
from typing import IO, Any

#: short words for stage options in the progress label.
_WORDS = {"graph_knn": "graph KNN", "vision_cone": "vision cone", "euclidean_knn": "Euclidean KNN",
          "default": "post", "none": "raw"}


def job_label(names: Mapping[str, str], oracle_accuracy: float | None = None, width: int = 48) -> str:
    """A job named in words, e.g. ``synthetic · oracle 80% · vision cone · post`` (at most
    ``width`` characters; the classifier's accuracy when it is the oracle's)."""
    if names.get("segmenter"):
        parts = [names.get("env", ""), names["segmenter"]]
    else:
        clf = names.get("classifier", "")
        if oracle_accuracy is not None:
            clf += f" {oracle_accuracy:.0%}"
        parts = [names.get("env", ""), clf, _WORDS.get(names.get("aggregator", ""), names.get("aggregator", "")),
                 _WORDS.get(names.get("postprocess", ""), names.get("postprocess", ""))]
    text = " · ".join(p for p in parts if p)
    return text if len(text) <= width else text[: width - 1] + "…"


def parallel_jobs() -> int:
    """How many jobs may run at once beside this one: the launcher's ``n_jobs`` in a Hydra
    multirun, 1 in a single run or outside Hydra."""
    try:
        from hydra.core.hydra_config import HydraConfig
        from hydra.types import RunMode

        hc = HydraConfig.get()
    except (ImportError, ValueError):
        return 1
    if hc.mode != RunMode.MULTIRUN:
        return 1
    n = hc.launcher.get("n_jobs", 1) if hc.get("launcher") is not None else 1
    try:
        return max(int(n), 1)
    except (TypeError, ValueError):
        return 1


def house_progress(label: str, enabled: bool = True, stream: IO[str] | None = None,
                   workers: int | None = None) -> Callable[..., Iterable[Any]] | None:
    """A wrapper that draws a bar over a job's houses, or None where a bar would garble output.

    Args:
        label: the job in words (:func:`job_label`).
        enabled: ``run.progress``.
        stream: where the bar goes (stderr).
        workers: jobs that may run at once (:func:`parallel_jobs` when None).

    Returns:
        ``wrap(iterable, total=None)``, a ``tqdm`` bar over the iterable (the houses, or the
        stream of finished houses of a pool: ``total`` gives its length), when enabled,
        ``stream`` is a terminal and ``workers`` is 1; otherwise None (no bar: the
        finished-job line is the job's one line).
    """
    stream = sys.stderr if stream is None else stream
    workers = parallel_jobs() if workers is None else workers
    isatty = getattr(stream, "isatty", None)
    if not enabled or workers > 1 or not (callable(isatty) and isatty()):
        return None
    from tqdm import tqdm

    def wrap(it: Iterable[Any], total: int | None = None) -> Iterable[Any]:
        return tqdm(it, desc=label, unit="house", file=stream, leave=True, dynamic_ncols=True, total=total)

    return wrap


__all__ = ["house_progress", "job_label", "parallel_jobs"]

