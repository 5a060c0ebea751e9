"""The run store: the one module that knows where runs, jobs, rows, saved maps and cache
entries live. The runner, tables, figures, perf and the post-processing timing all ask it;
nothing else joins these paths.

Layout (``results_dir`` and ``cache_dir`` come from ``run.results_dir`` / ``run.cache_dir``;
the cache may live anywhere)::

    <results_dir>/runs/<run name>/[<job subdir>/]   a job (one configuration):
        job.json               the job's identity: a key over every choice that changes its
                               rows (config, house selection, input content); a folder
                               holding another identity is never written into
        metrics.csv            one row per house
        timings.csv            per house: stage times (t_*, seconds), wall time, worker, and
                               whether the row was served from the cache
        summary.json           counts, failures, wall time, cache keys, stage names, and
                               per house the content hash of its cache entries
        resolved_config.yaml   the full config, every interpolation resolved
    <results_dir>/runs/<run name>/sweep_summary.{md,csv}   a multirun's jobs (callback)
    <results_dir>/runs/<run name>/last_sweep.json   the job folders the last multirun into
                                                    this folder ran, and when (tables and the
                                                    report read them alone with --last-sweep)
    <cache_dir>/render/<render key>/<entry>/        observations (envs.render.cache layout)
    <cache_dir>/classify/<classify key>/<entry>.npz proba (N, C), poses (N, 3), n_refused
    <cache_dir>/aggregate/<aggregate key>/<entry>.npz raw label map (shared by post-processing variants)
    <cache_dir>/scores/<score key>/<entry>.json     the house's metrics row (successes only)
    <cache_dir>/failures/<score key>/<entry>.json   the house's last failure (a log, not a result)
    <cache_dir>/maps/<score key>/<entry>.npz        raw / post-processed label maps, poses
                                                    (segmenters: instances)
    <cache_dir>/robot_maps/<map key>/<entry>.npz    the map the robot built (mapping=scan): free cells
    <cache_dir>/slam/<map key>/<entry>.npz          the one pose estimate a SLAM robot's map is built
                                                    at (pose_error=odometry with a mapping)
    <cache_dir>/coverage/<render key>/<entry>.json  the share of the house the views saw
    <cache_dir>/models/<kind>/<key>.npz             fitted models (objects classifier)

``<entry>`` is ``<house id made safe>@<content>``: ``content`` is a hash of the house's JSON and
of the input files the stages up to that one read (:mod:`benchmark.harness.cache`), so an
edited house or input file gets new entries and nothing stale is served.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

#: the files every finished job folder holds.
METRICS, SUMMARY, CONFIG = "metrics.csv", "summary.json", "resolved_config.yaml"
#: the mappings of a runner job's ``summary.json`` that reports read (:meth:`Job.summary`).
RUN_SUMMARY_MAPPINGS = ("names", "keys", "contents")
#: per-house timings beside metrics.csv (they differ from run to run; the rows do not).
TIMINGS = "timings.csv"
#: the job's identity (written first, when the runner claims the folder).
IDENTITY = "job.json"
#: what a multirun's summary callback writes into the sweep folder.
SWEEP_SUMMARY = "sweep_summary"
#: the job folders of the last multirun into a sweep folder (written at its end).
LAST_SWEEP = "last_sweep.json"


#: the longest file name part made from an id (file systems allow 255 bytes per name; an
#: entry adds ``@<content>`` and a suffix, a temporary file a prefix and a suffix).
MAX_NAME = 64


def safe_name(house_id: str) -> str:
    """An id (house, run, ...) made safe and bounded as a file name.

    An id of at most :data:`MAX_NAME` ASCII letters, digits and ``-_.`` (not starting with a
    dot) is used as it is. Any other id keeps a readable part (its first 40 characters, others
    replaced by ``_``) followed by ``~`` and 12 hex digits of its SHA-1, so that two ids never
    share a name (``a b`` and ``a_b``) and no name is longer than :data:`MAX_NAME`.
    """
    text = str(house_id)
    plain = "".join(ch if (ch.isascii() and ch.isalnum()) or ch in "-_." else "_" for ch in text)
    if plain == text and 0 < len(text) <= MAX_NAME and not text.startswith("."):
        return text
    import hashlib

    digest = hashlib.sha1(text.encode("utf-8", "surrogatepass")).hexdigest()[:12]
    return f"{plain.lstrip('.')[:40]}~{digest}"


def entry_name(house_id: str, content: str) -> str:
    """The cache entry name of one house: ``<safe id>@<first 12 hex digits of content>``."""
    if not content:
        raise ValueError(f"cache entry of house {house_id!r}: empty content hash")
    return f"{safe_name(house_id)}@{content[:12]}"


@dataclass(frozen=True)
class CacheStore:
    """Where the stage caches live under ``root`` (``run.cache_dir``). ``key`` is a stage's
    config key, ``content`` the house's content hash for that stage (see the module doc)."""

    root: Path

    #: kind of entry -> (folder, suffix, the stage whose config key and content name it):
    #: render (a folder of views), classify, aggregate (raw label map), score (the row), failure
    #: (a house's last failure, kept as a log; not served as a result by default), maps (saved
    #: label maps), robot_map (the map the robot built: its free cells), slam (the robot's one
    #: pose estimate, keyed like the map it shapes: every method of a condition shares it),
    #: coverage (how much of a house a render's views saw, keyed like the render).
    KINDS = {"render": ("render", "", "render"), "classify": ("classify", ".npz", "classify"),
             "aggregate": ("aggregate", ".npz", "aggregate"), "score": ("scores", ".json", "score"),
             "failure": ("failures", ".json", "score"), "maps": ("maps", ".npz", "score"),
             "robot_map": ("robot_maps", ".npz", "map"), "slam": ("slam", ".npz", "map"),
             "coverage": ("coverage", ".json", "render")}

    def entry(self, kind: str, keys: Mapping[str, str], contents: Mapping[str, str], house_id: str) -> Path:
        """Where one house's entry of ``kind`` (:data:`KINDS`) lives for a configuration.

        Args:
            keys: stage -> config key (``runner.stage_keys``).
            contents: stage -> the house's content hash at that stage.
        """
        folder, suffix, stage = self.KINDS[kind]
        return self.root / folder / keys[stage] / f"{entry_name(house_id, contents[stage])}{suffix}"

    def model_path(self, kind: str, key: str, suffix: str = ".npz") -> Path:
        """A fitted model (e.g. the objects classifier) cached by the content of its training set."""
        return self.root / "models" / kind / f"{key}{suffix}"


#: env config keys that select houses rather than change them (left out of cache keys, and
#: of the configuration tables compare).
SELECTION_KEYS = ("start", "stop", "n_houses", "seed_start", "name", "houses")
#: run settings that change nothing in the rows (left out of a job's identity, see
#: :func:`benchmark.harness.runner.job_identity`, and of the configuration tables compare).
NON_ROW_KEYS = ("run.force", "run.progress", "run.results_dir", "run.cache_dir", "run.save_maps",
                "run.cache_aggregates", "run.cache_salt",
                "run.allow_failures", "run.cache_failures", "run.name", "run.workers", "run.executor",
                "run.ray.address", "run.ray.connect_timeout")


def flat_settings(plain: dict[str, Any]) -> dict[str, Any]:
    """A plain (resolved) config as ``{dotted key: value}``; lists and scalars are values."""
    flat: dict[str, Any] = {}

    def walk(v: Any, key: str) -> None:
        if isinstance(v, dict):
            for k, x in v.items():
                walk(x, f"{key}.{k}" if key else str(k))
        else:
            flat[key] = v

    walk(plain, "")
    return flat


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
    def timings_path(self) -> Path:
        return self.dir / TIMINGS

    @property
    def config_path(self) -> Path:
        return self.dir / CONFIG

    def is_finished(self) -> bool:
        return self.metrics_path.exists() and self.summary_path.exists() and self.config_path.exists()

    def config(self):
        """The job's resolved config (a read-only OmegaConf DictConfig, read once per file
        version: reports ask for it many times).

        Raises:
            ValueError: one line naming the file: it does not parse, or is not a mapping with
                a ``run`` section (empty, a list, another file's text)."""
        st = self.config_path.stat()
        return _load_config(str(self.config_path), st.st_mtime_ns, st.st_size)

    def summary(self, require: Sequence[str] = ()) -> dict[str, Any]:
        """The job's ``summary.json``; ``require``: keys that must hold mappings (the runner's
        ``names``, ``keys``, ``contents``: :data:`RUN_SUMMARY_MAPPINGS`).

        Raises:
            ValueError: one line naming the file: it does not parse, is not a JSON object, or
                one of ``names``, ``keys``, ``contents`` (required or present) is not a mapping."""
        import json

        try:
            with open(self.summary_path, encoding="utf-8") as f:
                out = json.load(f)
        except (ValueError, UnicodeDecodeError) as e:
            raise ValueError(f"{self.summary_path}: malformed JSON ({' '.join(str(e).split())[:120]})") from None
        if not isinstance(out, dict):
            raise ValueError(f"{self.summary_path}: expected a JSON object, got {type(out).__name__}")
        bad = [k for k in dict.fromkeys((*require, *RUN_SUMMARY_MAPPINGS))
               if (k in require or k in out) and not isinstance(out.get(k), dict)]
        if bad:
            raise ValueError(f"{self.summary_path}: malformed summary (expected {', '.join(bad)} as mappings)")
        return out

    def cache(self) -> CacheStore:
        """The cache this job wrote to (its ``run.cache_dir``, wherever that is)."""
        return CacheStore(Path(str(self.config().run.cache_dir)))

    def house_ids(self) -> list[str]:
        """The houses this job ran, in its order."""
        return list(self.summary().get("contents", {}))

    def maps_path(self, house_id: str) -> Path:
        """The saved label maps of one house of this job (may not exist: ``run.save_maps``).

        Raises:
            KeyError: the job did not run that house (the message names job and house)."""
        summary = self.summary(RUN_SUMMARY_MAPPINGS)
        contents = summary.get("contents", {})
        if house_id not in contents:
            raise KeyError(f"{self.summary_path}: no house {house_id!r} in this job "
                           f"({len(contents)} houses, e.g. {list(contents)[:3]})")
        return self.cache().entry("maps", summary["keys"], {"score": contents[house_id]}, house_id)

    @property
    def identity_path(self) -> Path:
        return self.dir / IDENTITY

    def identity(self) -> dict[str, Any] | None:
        """The job's ``job.json`` (None when absent or unreadable)."""
        import json

        try:
            with open(self.identity_path, encoding="utf-8") as f:
                out = json.load(f)
        except (OSError, ValueError):
            return None
        return out if isinstance(out, dict) and "key" in out else None

    def settings(self) -> dict[str, Any] | None:
        """What this job's rows depend on, flat ``{dotted key: value}``: the ``settings`` of its
        ``job.json`` (the runner's identity: the resolved config without the settings that change
        no row, and a ``houses`` summary), else its resolved config flattened the same way (a job
        of an older layout); None when it has neither."""
        ident = self.identity()
        if ident is not None and isinstance(ident.get("settings"), dict):
            return dict(ident["settings"])
        if not self.config_path.exists():
            return None
        from omegaconf import OmegaConf

        try:
            plain = OmegaConf.to_container(self.config(), resolve=True)
        except Exception as e:  # noqa: BLE001 - any YAML or interpolation error is a malformed file
            raise ValueError(f"{self.config_path}: unreadable config ({type(e).__name__}: {str(e).strip()[:120]})") from None
        if not isinstance(plain, dict):
            raise ValueError(f"{self.config_path}: expected a mapping, got {type(plain).__name__}")
        return {k: v for k, v in flat_settings(plain).items() if k not in NON_ROW_KEYS}

    def finished_at(self) -> float:
        """When the job finished, POSIX seconds: ``finished_at`` of its ``summary.json`` (ISO
        8601, written by the runner), else the modification time of its summary, else of its
        ``metrics.csv``."""
        from datetime import datetime

        try:
            stamp = self.summary().get("finished_at")
            if isinstance(stamp, str):
                return datetime.fromisoformat(stamp).timestamp()
        except (OSError, ValueError, AttributeError):
            pass
        for p in (self.summary_path, self.metrics_path):
            if p.exists():
                return p.stat().st_mtime
        raise FileNotFoundError(f"no {SUMMARY} or {METRICS} in {self.dir}")

    def run_name(self) -> str:
        """The run this job belongs to: its ``run.name`` (the folder's parent name for jobs
        without a resolved config, e.g. per-map tables of the baselines)."""
        if self.config_path.exists():
            try:
                name = self.config().get("run", {}).get("name")
                if name:
                    return str(name)
            except Exception:  # noqa: BLE001 - an unreadable config falls back to the folder
                pass
        return self.dir.name


def _clip(value: Any, limit: int = 60) -> str:
    """``str(value)`` cut to ``limit`` characters, without a bracket it opens and the cut leaves
    unclosed (``... (3bd9fdf8dd`` -> ``......``), and ``...`` where it was cut."""
    text = str(value)
    if len(text) <= limit:
        return text
    cut = text[:limit]
    for opening, closing in ("()", "[]", "{}"):
        while cut.count(opening) > cut.count(closing):
            cut = cut[: cut.rfind(opening)]
    return cut.rstrip(" ,;:") + "..."


def _differences(old: dict[str, Any], new: dict[str, Any], limit: int = 4) -> str:
    keys = sorted(set(old) | set(new))
    diff = [k for k in keys if old.get(k) != new.get(k)]
    parts = [f"{k}: {_clip(old.get(k, '(unset)'))} -> {_clip(new.get(k, '(unset)'))}" for k in diff[:limit]]
    if len(diff) > limit:
        parts.append(f"and {len(diff) - limit} more")
    return "; ".join(parts) or "the house contents"


def claim_job_dir(out_dir: str | Path, key: str, describe: dict[str, Any],
                  aliases: tuple[str, ...] = ()) -> tuple[Path, str]:
    """The folder a job with identity ``key`` writes into, claimed by writing ``job.json``.

    ``out_dir`` if it is new, empty of results, or already holds this identity; otherwise
    (another run's results are there) the sibling ``<out_dir>~<key[:8]>``, claimed the same
    way. ``describe`` (flat {setting: value}) is recorded so that the message can say what
    differs. ``aliases``: earlier keys of the same identity (a folder that holds one is this
    job's; its ``job.json`` is kept). Concurrent jobs are serialised by a lock beside the folder.

    Returns:
        (folder, note): ``note`` is "" or one line saying why the job moved to a sibling.

    Raises:
        FileExistsError: both folders hold other identities (the message names them).
    """
    import json

    from benchmark.harness.cache import atomic_write_json, locked

    out_dir = Path(out_dir)
    note = ""
    for cand in (out_dir, out_dir.with_name(f"{out_dir.name}~{key[:8]}")):
        with locked(cand.with_name(cand.name + ".claim")):
            job = Job(cand)
            ident = job.identity()
            taken = ident is not None or job.metrics_path.exists() or job.identity_path.exists()
            if ident is not None and ident["key"] in (key, *aliases) or not taken:
                cand.mkdir(parents=True, exist_ok=True)
                if ident is None:
                    atomic_write_json(job.identity_path, {"key": key, "settings": describe})
                return cand, note
            old = (ident or {}).get("settings", {})
            what = _differences(old, describe) if ident is not None else "no job.json (an older layout)"
            note = (f"{cand} holds another run's results (differs in {what}); "
                    f"this job writes to {out_dir.with_name(f'{out_dir.name}~{key[:8]}')} instead")
    raise FileExistsError(f"{out_dir} and its sibling ~{key[:8]} hold other runs' results; "
                          f"choose another run.name ({json.dumps(describe)[:200]})")


#: name prefixes of share columns beyond :data:`benchmark.metrics.METRIC_COLUMNS` (per-class
#: IoUs ``iou_<class>``, ``view_accuracy_seen``, the robot's coverage ``coverage_area`` /
#: ``coverage_rooms``, and families the metrics may grow).
FRACTION_PREFIXES = ("iou_", "matched_", "room_", "ipa_", "pq_", "view_accuracy", "coverage_")
#: name suffixes of share columns (``map_free_iou``, ``label_noise_share``, ``map_missed_share``).
FRACTION_SUFFIXES = ("_iou", "_share")
#: share columns that are settings, not metrics (the oracle classifier's accuracy).
FRACTION_SETTINGS = ("oracle_accuracy",)
#: metrics an ``ok`` row always has (the paper's three, as the runner's cached-row check).
REQUIRED_IN_OK_ROWS = ("iou", "precision", "recall")


def fraction_columns(columns: Sequence[str]) -> list[str]:
    """The columns of a metrics table that are shares in [0, 1]: every metric of
    :data:`benchmark.metrics.METRIC_COLUMNS`, every column named with one of
    :data:`FRACTION_PREFIXES` or :data:`FRACTION_SUFFIXES`, and :data:`FRACTION_SETTINGS`;
    never a count (``count_error``, ``n_*``)."""
    from benchmark.metrics import METRIC_COLUMNS

    out = []
    for c in map(str, columns):
        if c == "count_error" or c.startswith("n_"):
            continue
        if c in METRIC_COLUMNS or c in FRACTION_SETTINGS or c.startswith(FRACTION_PREFIXES) \
                or c.endswith(FRACTION_SUFFIXES):
            out.append(c)
    return out


def _check_fractions(path: Path, df) -> None:
    """Refuse a share outside [0, 1] or a cell that is not a number (one line: file, line,
    house, column, value); missing values (NaN) pass, except :data:`REQUIRED_IN_OK_ROWS` in
    a row whose status is ``ok``. The first bad cell in file order is named."""
    import numpy as np
    import pandas as pd

    cols = fraction_columns(df.columns)
    if not cols or df.empty:
        return
    vals = np.empty((len(df), len(cols)))
    absent = np.empty((len(df), len(cols)), bool)
    for j, c in enumerate(cols):  # column by column (no frame of the share columns is made)
        col = df[c]
        if isinstance(col.dtype, np.dtype) and col.dtype.kind == "f":  # NumPy floats: missing is NaN
            vals[:, j] = col.to_numpy()
            absent[:, j] = np.isnan(vals[:, j])
        else:
            vals[:, j] = (col.to_numpy(float) if pd.api.types.is_numeric_dtype(col)
                          else pd.to_numeric(col, errors="coerce").to_numpy(float))
            absent[:, j] = col.isna().to_numpy()
    ok = df["status"].astype(str).eq("ok").to_numpy() if "status" in df else np.zeros(len(df), bool)
    required = np.array([c in REQUIRED_IN_OK_ROWS for c in cols])
    with np.errstate(invalid="ignore"):
        outside = ~np.isnan(vals) & ((vals < 0.0) | (vals > 1.0))
    text = ~absent & np.isnan(vals)
    missing = ok[:, None] & absent & required[None, :]
    bad = outside | text | missing
    if not bad.any():
        return
    i, j = (int(v) for v in np.argwhere(bad)[0])
    value = df[cols[j]].iloc[i]
    if missing[i, j]:
        what = "missing in a row with status ok"
    elif outside[i, j]:
        what = f"{value} is outside [0, 1]"
    else:
        what = f"{value!s:.40} is not a number"
    house = f" (house {df['house_id'].iloc[i]})" if "house_id" in df else ""
    raise ValueError(f"{path}: line {i + 2}{house}, column {cols[j]!r}: {what}; expected a fraction in [0, 1]")


def read_metrics(path: str | Path):
    """A job's ``metrics.csv`` (or a per-map table of the baselines) as a DataFrame, checked whole.

    Checked: it parses and its last line ends with a newline (a truncated write does not);
    every share column (:func:`fraction_columns`: iou, precision, recall, matched_*, room_*,
    pq, sq, rq, pq_semantic, ipa_*, accuracy, class_iou, iou_<class>, view_accuracy*, ...)
    holds numbers in [0, 1] or nothing (NaN), and ``iou``/``precision``/``recall`` are
    present in every ``ok`` row; for a runner job (``summary.json`` beside it) also:
    ``house_id`` and ``status`` columns, every row with a house id and a status of ``ok`` or
    ``failed``, and as many rows as the summary's ``n_houses``. Line numbers in messages
    count the header as line 1.

    Raises:
        ValueError: one line naming the file and what is wrong.
    """
    import json

    import pandas as pd

    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise ValueError(f"{path}: cannot read ({e.strerror or e})") from None
    if not raw.strip():
        raise ValueError(f"{path}: empty metrics file")
    if not raw.endswith(b"\n"):
        raise ValueError(f"{path}: truncated (the last line has no newline)")
    try:
        import io

        # low_memory=False: one type per column over the whole file (a large sweep's file read in
        # chunks could give a column floats in one chunk and text in another)
        df = pd.read_csv(io.BytesIO(raw), keep_default_na=True, low_memory=False)
    except Exception as e:  # noqa: BLE001 - any parser error is a malformed file
        raise ValueError(f"{path}: malformed CSV ({type(e).__name__}: {str(e).strip()[:120]})") from None
    _check_fractions(path, df)
    summary = path.parent / SUMMARY
    if not summary.exists():  # not a runner job (e.g. a per-map table of the baselines)
        return df
    missing = [c for c in ("house_id", "status") if c not in df]
    if missing:
        raise ValueError(f"{path}: malformed metrics file, no column(s) {missing}")
    bad = df["house_id"].isna() | ~df["status"].isin(["ok", "failed"])
    if bad.any():
        i = int(bad.to_numpy().nonzero()[0][0])
        raise ValueError(f"{path}: malformed row {i + 2} (house_id={df['house_id'].iloc[i]!r}, "
                         f"status={df['status'].iloc[i]!r}; expected a house id and ok|failed)")
    if path.name == METRICS:
        try:
            n = json.loads(summary.read_text(encoding="utf-8")).get("n_houses")
        except (ValueError, AttributeError):  # (the summary itself is checked where it is read: Job.summary)
            n = None
        if isinstance(n, int) and n != len(df):
            raise ValueError(f"{path}: {len(df)} rows but {summary.name} says {n} houses (truncated?)")
    return df


@lru_cache(maxsize=256)
def _load_config(path: str, mtime_ns: int, size: int):
    from omegaconf import DictConfig, OmegaConf

    try:
        cfg = OmegaConf.load(path)
    except Exception as e:  # noqa: BLE001 - any YAML error is a malformed file
        raise ValueError(f"{path}: unreadable config ({type(e).__name__}: "
                         f"{' '.join(str(e).split())[:120]})") from None
    if not isinstance(cfg, DictConfig) or not isinstance(cfg.get("run"), DictConfig):
        what = "empty" if isinstance(cfg, DictConfig) and not len(cfg) else (
            "no run section" if isinstance(cfg, DictConfig) else "a list")
        raise ValueError(f"{path}: malformed resolved config ({what}; expected the mapping the runner writes)")
    OmegaConf.set_readonly(cfg, True)
    return cfg


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


def write_last_sweep(sweep_dir: str | Path, jobs: Sequence[Job], started: float, command: Sequence[str]) -> Path:
    """Record the job folders a multirun into ``sweep_dir`` ran (relative to it), when it
    started and ended (UTC, ISO 8601) and its command line, in ``last_sweep.json`` there."""
    import json
    import time
    from datetime import datetime, timezone

    from envs.atomic import atomic_write_text

    sweep_dir = Path(sweep_dir)
    rel = sorted({_relative(j.dir, sweep_dir) for j in jobs})
    doc = {"started_at": datetime.fromtimestamp(started, timezone.utc).isoformat(timespec="seconds"),
           "finished_at": datetime.fromtimestamp(time.time(), timezone.utc).isoformat(timespec="seconds"),
           "command": list(command), "jobs": rel}
    path = sweep_dir / LAST_SWEEP
    atomic_write_text(path, json.dumps(doc, indent=1) + "\n")
    return path


def _relative(p: Path, root: Path) -> str:
    try:
        return Path(p).resolve().relative_to(Path(root).resolve()).as_posix() or "."
    except ValueError:
        return str(Path(p).resolve())


def last_sweep(sweep_dir: str | Path) -> dict[str, Any] | None:
    """The ``last_sweep.json`` of ``sweep_dir`` (None when absent).

    Raises:
        ValueError: the file is there but unreadable (one line naming it)."""
    import json

    path = Path(sweep_dir) / LAST_SWEEP
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        jobs = doc["jobs"]
        if not isinstance(jobs, list):
            raise TypeError("jobs is not a list")
    except (ValueError, KeyError, TypeError) as e:
        raise ValueError(f"{path}: unreadable ({e}); expected the job list a multirun writes at its end") from None
    return doc


@dataclass(frozen=True)
class Scope:
    """What a table or report reads: the metrics files, and one line saying which runs they
    are ("" when they are exactly one sweep's, or files that are not a sweep's)."""

    files: list[Path]
    note: str
    #: job folders of other runs read beside the last sweep (0 with ``last_only``).
    n_other: int = 0


def sweep_scope(paths: Sequence[str | Path], last_only: bool = False) -> Scope:
    """The metrics files under ``paths``, scoped by the sweep folders' ``last_sweep.json``.

    A sweep folder at or under a path (one holding ``last_sweep.json``) that also holds job
    folders its last multirun did not run (an earlier sweep with other houses or settings) is
    said so in ``note``; with ``last_only`` those are left out and ``note`` says how many. Jobs
    under no sweep folder (single runs) are read as they are.

    Raises:
        FileNotFoundError: no metrics file under ``paths``.
        ValueError: ``last_only`` and a folder without ``last_sweep.json`` (one line), or a
            job of the last sweep whose metrics are gone."""
    files = list(iter_metric_files(paths))
    if not files:
        raise FileNotFoundError(f"no metrics.csv under {[str(p) for p in paths]}")
    keep: list[Path] = []
    notes: list[str] = []
    n_other = 0
    for p in map(Path, paths):
        if not p.is_dir():  # a metrics file named as such: read as it is
            keep.extend(f for f in files if f.resolve() == p.resolve())
            continue
        under = [f for f in files if p.resolve() in f.resolve().parents]
        # the sweep folders at or under p (results/runs holds one per run name)
        sweeps = sorted({m.parent for m in p.rglob(LAST_SWEEP)}, key=lambda d: len(d.parts), reverse=True)
        if not sweeps:
            if last_only:
                raise ValueError(f"{p}: no {LAST_SWEEP} (a multirun writes it when it ends); without --last-sweep "
                                 f"every job under it is read")
            keep.extend(under)
            continue
        by_sweep: dict[Path, list[Path]] = {}
        for f in under:  # each job belongs to the deepest sweep folder holding it, if any
            d = next((d for d in sweeps if d.resolve() in f.resolve().parents), None)
            if d is None:
                keep.append(f)  # a single run beside the sweeps: read as it is
            else:
                by_sweep.setdefault(d, []).append(f)
        for d in sorted(by_sweep):
            doc = last_sweep(d) or {"jobs": []}
            mine = {(d / j).resolve() for j in doc["jobs"]}
            ours = [f for f in by_sweep[d] if f.parent.resolve() in mine]
            other = [f for f in by_sweep[d] if f.parent.resolve() not in mine]
            gone = sorted(mine - {f.parent.resolve() for f in ours})
            if last_only and gone:
                raise ValueError(f"{d}: {len(gone)} job(s) of the last sweep have no {METRICS} (e.g. {gone[0]}); "
                                 f"run the sweep again")
            when = doc.get("finished_at", "?")
            if last_only:
                keep.extend(ours)
                if other:
                    notes.append(f"{d}: the last sweep only ({len(ours)} jobs, finished {when}); left out "
                                 f"{len(other)} job folder(s) of earlier runs in that folder")
            else:
                keep.extend(by_sweep[d])
                n_other += len(other)
                if other:
                    notes.append(f"{d}: includes {len(other)} job folder(s) of earlier runs beside the last "
                                 f"sweep's {len(ours)} (finished {when}); --last-sweep reads that sweep alone")
    seen: set[Path] = set()
    out = [f for f in keep if not (f.resolve() in seen or seen.add(f.resolve()))]
    if not out:
        raise FileNotFoundError(f"no metrics.csv of the last sweep under {[str(p) for p in paths]}")
    return Scope(out, "; ".join(notes), n_other)


def iter_metric_files(paths: Sequence[str | Path]) -> Iterator[Path]:
    """The ``metrics.csv`` of every job under ``paths`` (a path may be a CSV file itself), each
    file once."""
    seen: set[Path] = set()
    for p in map(Path, paths):
        if p.is_file():
            found = [p]
        elif p.is_dir():
            found = sorted(p.rglob(METRICS))
        else:
            raise FileNotFoundError(f"no run folder or metrics file at {p}")
        for f in found:  # a file under two of the paths (a run and its parent) is read once
            if f.resolve() not in seen:
                seen.add(f.resolve())
                yield f


__all__ = ["CacheStore", "Job", "claim_job_dir", "entry_name", "find_jobs", "flat_settings", "fraction_columns",
           "iter_metric_files", "job_dir_for", "last_sweep", "sweep_scope", "write_last_sweep", "Scope", "LAST_SWEEP", "read_metrics", "safe_name", "METRICS", "NON_ROW_KEYS",
           "SELECTION_KEYS", "SUMMARY", "CONFIG", "TIMINGS", "IDENTITY", "SWEEP_SUMMARY"]
