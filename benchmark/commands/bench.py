"""The Hydra app ``roomseg-bench`` (or ``python -m benchmark.commands.bench``).

    roomseg-bench                                   # defaults from conf/config.yaml
    roomseg-bench aggregator=vision_cone run.limit=5
    roomseg-bench -m aggregator=graph_knn,vision_cone postprocess=none,default
    roomseg-bench experiment=table4                 # a paper table's sweep

Exit status (one line on stderr for every error):

* 0: every house of every job succeeded;
* 1: some house failed (after every row is written; ``run.allow_failures=true`` exits 0), or a
  worker process was killed (a sweep worker, or one of the processes running a job's houses,
  ``run.workers``);
* 2: nothing ran: a bad setting, a config that does not compose, an unwritable folder, no house
  selected, a stage that cannot be built, or a job that could not write its results (a full
  disk: the line names the file) when no job finished;
* 3: some jobs finished and their results are complete, but others could not write theirs (a
  full disk): the line names the file and counts both;
* 130: interrupted (Ctrl-C stops every worker at once).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig

from benchmark.config import register_resolvers
from benchmark.harness import sweep
from benchmark.harness.checks import check_run_overrides
from benchmark.harness.executor import WorkerDied
from benchmark.harness.pipeline import StageError
from benchmark.harness.runner import CONF_DIR, ConfigError, run
from benchmark.harness.typed import check_top_overrides

PROG = "roomseg-bench"
register_resolvers()  # hydra.sweep.subdir's job_dir, before Hydra composes anything


def _save_config_whole(cfg, filename: str, output_dir: Path) -> None:
    """Hydra's ``_save_config`` (``.hydra/config.yaml``, ``hydra.yaml``, ``overrides.yaml`` of
    every job), written atomically: a job that cannot write them (a full disk) or is killed
    leaves the file whole or absent, never empty or cut. Its text is ``OmegaConf.to_yaml``'s
    (:func:`benchmark.config.yaml_text`)."""
    from omegaconf import OmegaConf

    from benchmark.config import yaml_text
    from envs.atomic import atomic_write_text

    text = yaml_text(OmegaConf.to_container(cfg, enum_to_str=True)) if OmegaConf.is_config(cfg) else OmegaConf.to_yaml(cfg)
    atomic_write_text(Path(output_dir) / filename, text, durable=False)


def _whole_hydra_files() -> None:
    import hydra.core.utils as hydra_utils

    if hasattr(hydra_utils, "_save_config"):  # (Hydra 1.1-1.3: run_job looks it up in its module)
        hydra_utils._save_config = _save_config_whole


class _WithoutHydraJobLine:
    """``sys.stderr`` less Hydra's own "Error executing job with overrides: [...]" line, which
    it writes before re-raising a job's error: :func:`main` says what failed in one line."""

    PREFIX = "Error executing job with overrides:"

    def __init__(self, stream) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        if text.startswith(self.PREFIX):
            return len(text)
        return self._stream.write(text)

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


@hydra.main(version_base="1.3", config_path=CONF_DIR, config_name="config")
def app(cfg: DictConfig) -> float:
    """One job: run the configuration, record its failed houses. Returns its mean IoU."""
    out_dir = Path(HydraConfig.get().runtime.output_dir)
    if HydraConfig.get().mode == RunMode.MULTIRUN:
        _console_warnings_only()  # a sweep's one progress line stands for its jobs; their lines go to bench.log
    sweep.clear_error(out_dir)
    try:
        df = run(cfg, out_dir)
    except (ConfigError, StageError) as e:  # nothing ran: one line, and exit status 2 at the end
        if HydraConfig.get().mode == RunMode.MULTIRUN:
            raise  # the job fails; the launching process reports it with the others (main)
        # nothing ran (exit status 2): the reason is the one line at the end, and the folders this
        # run made (Hydra's .hydra/, the job folder it claimed) go, those of other runs stay
        from benchmark.harness.runner import LAST_RUN

        sweep.OUTCOME["errors"].append(_one_line(e))
        _remove_refused(out_dir, LAST_RUN.get("dir"))
        return float("nan")
    except WorkerDied as e:  # a house worker died: one line, exit status 1 (a multirun's launcher ends the sweep)
        if HydraConfig.get().mode == RunMode.MULTIRUN:
            raise
        sweep.record_died(_one_line(e))
        return float("nan")
    sweep.record(df.attrs.get("n_failed", 0), bool(cfg.run.get("allow_failures", False)))
    failed = df[df["status"] != "ok"] if "status" in df else df.iloc[:0]
    if len(failed) and "first_failure" not in sweep.OUTCOME:  # the last line names it (a missing file's path)
        row = failed.iloc[0]
        sweep.OUTCOME["first_failure"] = f"{row.get('house_id', '?')}: {' '.join(str(row.get('error') or 'no reason recorded').split())}"
    ok = df[df["status"] == "ok"] if "status" in df else df
    return float(ok["iou"].mean()) if "iou" in ok and len(ok) else float("nan")


#: what a single run writes into its folder before any house runs: a folder holding nothing
#: else holds no results (Hydra's ``.hydra/``, the log, the claim, the resolved config).
_BEFORE_WORK = frozenset({".hydra", "bench.log", "job.json", "resolved_config.yaml", sweep.JOB_ERROR})


def _remove_refused(out_dir: Path, claimed: str | None) -> None:
    """A single run refused before any house ran (a bad setting, a stage that cannot be built):
    remove its folder (``out_dir``, and the ``~<key>`` sibling it claimed) where that folder
    holds nothing but what a run writes before its work (:data:`_BEFORE_WORK`); a folder with
    another run's results keeps them. Then the ``runs/`` folder above, if that left it empty."""
    import shutil

    for folder in dict.fromkeys(Path(d) for d in (out_dir, claimed) if d):
        try:
            names = {p.name for p in folder.iterdir()}
        except OSError:
            continue
        if names <= _BEFORE_WORK:
            _drop_log_handlers(folder)
            shutil.rmtree(folder, ignore_errors=True)
    try:
        Path(out_dir).parent.rmdir()  # only when empty (runs/ of a results folder this run made)
    except OSError:
        pass


def _drop_log_handlers(folder: Path) -> None:
    """Close and detach the logging file handlers writing into ``folder`` (Hydra's ``bench.log``)
    before it is removed: a handler left on a logger would reopen the removed file at the next
    record of this process (FileNotFoundError in whatever logs next)."""
    import logging

    root = Path(folder).resolve()
    loggers = [logging.getLogger(), *(lg for lg in logging.Logger.manager.loggerDict.values()
                                      if isinstance(lg, logging.Logger))]
    for lg in loggers:
        for h in list(lg.handlers):
            name = getattr(h, "baseFilename", None)
            if name and Path(name).resolve().is_relative_to(root):
                lg.removeHandler(h)
                h.close()


class _OncePerProcess:
    """A console filter of a sweep's jobs: each warning (its logger and message template, e.g.
    "%d of %d viewpoints are off the walkable map and were dropped") passes the first time this
    process logs it. A sweep's jobs repeat one warning for many houses and conditions (8,000
    lines in a robustness run); every one still goes to its job's ``bench.log``."""

    seen: set[tuple[str, str]] = set()  # per process: a fork worker runs many jobs

    def filter(self, record) -> bool:  # noqa: ANN001 - a logging.LogRecord
        key = (record.name, str(record.msg))
        if key in self.seen:
            return False
        self.seen.add(key)
        return True


def _console_warnings_only() -> None:
    """Raise the job's console log handlers (Hydra's ``job_logging`` console) to WARNING and show
    each warning once per process (:class:`_OncePerProcess`): the job's INFO lines and every
    warning still go to its log file (``<job>/bench.log``)."""
    import logging

    for h in logging.getLogger().handlers:
        if isinstance(h, logging.StreamHandler) and not isinstance(h, logging.FileHandler):
            h.setLevel(max(h.level, logging.WARNING))
            if not any(isinstance(f, _OncePerProcess) for f in h.filters):
                h.addFilter(_OncePerProcess())


def _finished_jobs() -> tuple[int, int]:
    """(jobs of this process's multirun that completed, jobs launched), from the local
    launcher's record of its job returns ((0, 0) for a single run, or another launcher)."""
    import importlib

    from hydra.core.utils import JobStatus

    try:
        launched = importlib.import_module("hydra_plugins.roomseg_sweep.roomseg_sweep").LAUNCHED
    except (ImportError, AttributeError):
        return 0, 0
    return sum(r.status == JobStatus.COMPLETED for r in launched), len(launched)


def _one_line(e: BaseException) -> str:
    return " ".join(str(e).split()) or type(e).__name__


def app_help() -> str:
    """``roomseg-bench --help``: the groups this app accepts (``conf/``, without the scoring
    app's own folder) with their options, and the default config."""
    from omegaconf import OmegaConf

    from benchmark.config import OWN_FOLDER, compose_job

    conf = Path(CONF_DIR)
    skip = {conf / d for d in OWN_FOLDER.values()}
    groups = sorted(p for p in conf.rglob("*") if p.is_dir() and any(p.glob("*.yaml"))
                    and not any(p == s or s in p.parents for s in skip))
    lines = [f"{PROG}: the benchmark's Hydra app (python -m benchmark.commands.bench); exit statuses: docs/reliability.md",
             "", "    roomseg-bench [group=option ...] [key=value ...]      # one configuration",
             "    roomseg-bench -m group=a,b key=1,2                   # a sweep (multirun)", "",
             "== Configuration groups ==", "Compose your configuration from those groups (group=option)", ""]
    lines += [f"{g.relative_to(conf).as_posix()}: {', '.join(sorted(p.stem for p in g.glob('*.yaml')))}"
              for g in groups if not g.relative_to(conf).as_posix().startswith("hydra")]
    cfg, _ = compose_job()
    lines += ["", "== Config ==", "Override anything in the config (foo.bar=value)", "",
              OmegaConf.to_yaml(cfg).rstrip(), "",
              "Hydra's own options: --hydra-help. Every command and group: docs/reference/."]
    return "\n".join(lines)


def main() -> int:
    """Run the app; turn known errors into one line and the outcome into the exit status."""
    from concurrent.futures.process import BrokenProcessPool

    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    os.environ["HYDRA_FULL_ERROR"] = "1"  # errors reach this function instead of Hydra's printer
    if any(a in ("--help", "-h") for a in sys.argv[1:]):
        print(app_help())  # only the groups this app accepts (Hydra's own lists every folder of conf/)
        return 0
    from benchmark.harness.hints import outside_root

    where = outside_root(PROG)  # results/ and ../shared/data are relative to the checkout's root
    if where is not None:
        print(where, file=sys.stderr)
        return 2
    try:
        from benchmark.config import quote_braces

        sys.argv[1:] = quote_braces(sys.argv[1:])  # viewpoints.path=poses/{house_id}.csv as typed
        check_run_overrides(sys.argv[1:])  # run.<typo> or +run.<typo>: refused before Hydra writes anything
        check_top_overrides(sys.argv[1:])  # aggregater=... or +aggregater=...: the nearest known key
        _whole_hydra_files()
        stderr, sys.stderr = sys.stderr, _WithoutHydraJobLine(sys.stderr)
        try:
            app()
        finally:
            sys.stderr = stderr
    except ValueError as e:  # raised by Hydra's defaults list (corruption=pose_3 pose_error=null), not ours
        if isinstance(e, ConfigError) or _finished_jobs()[1]:
            return _report_sweep(e) if _finished_jobs()[1] else _report_error(e)
        group_line = _group_value_line(sys.argv[1:]) if "Config group override" in str(e) else ""
        print(f"{PROG}: config error: {group_line or _one_line(e)}", file=sys.stderr)
        return 2
    except (ConfigError, StageError, HydraException, OmegaConfBaseException, OSError) as e:
        if _finished_jobs()[1]:  # a multirun whose jobs ran: report every failed job, count the finished
            return _report_sweep(e)
        return _report_error(e)
    except BrokenProcessPool as e:  # a sweep worker was killed (the local launcher says which sweep)
        print(f"{PROG}: error: {_one_line(e)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # the one Ctrl-C handler of every command: one line, exit 130, no worker left
        from benchmark.commands.cli import interrupted

        interrupted(PROG, "the houses already scored are cached, so the same command goes on from there")
    return _outcome()


def _report_error(e: BaseException) -> int:
    """One line for an error of a single run (or before any job ran); the exit status."""
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    if isinstance(e, (ConfigError, StageError)):
        print(f"{PROG}: error: {_one_line(e)}", file=sys.stderr)
        return 2
    if _refused_input(e) is not None:
        print(f"{PROG}: error: {_one_line(_refused_input(e))}", file=sys.stderr)
        return 2
    if isinstance(e, (HydraException, OmegaConfBaseException)):
        line = _unknown_key_line(e) or _missing_option_line(e) or _one_line(e).split(' full_key:')[0]
        print(f"{PROG}: config error: {line}", file=sys.stderr)
        return 2
    print(f"{PROG}: error: {_write_error(e)}", file=sys.stderr)
    return 2


def _group_options(group: str) -> list[str]:
    """The options of config group ``group`` in ``conf/`` (nested ones as ``sub/name``)."""
    folder = Path(CONF_DIR) / group
    return sorted(p.relative_to(folder).with_suffix("").as_posix() for p in folder.rglob("*.yaml"))


def _group_defaults() -> dict[str, str | None]:
    """group -> its default option (None: unset) in ``conf/config.yaml``'s defaults list."""
    from omegaconf import OmegaConf

    out: dict[str, str | None] = {}
    for item in OmegaConf.to_container(OmegaConf.load(Path(CONF_DIR) / "config.yaml")).get("defaults", []):
        if isinstance(item, dict):
            out.update({str(k): (None if v is None else str(v)) for k, v in item.items()})
    return out


def _group_value_line(args: list[str]) -> str:
    """Hydra's "Config group override must be a string or a list. Got NoneType" names no key:
    the first override of a config group whose value is not an option's name
    (``pose_error=null``, ``env=5``), with the group's options and what to do; "" when no such
    override is found."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from benchmark.harness.typed import nearest

    parser = OverridesParser.create()
    defaults = _group_defaults()
    corruption = ""
    found = None
    for a in args:
        try:
            o = parser.parse_override(a)
        except Exception:  # noqa: BLE001 - Hydra's own error names it
            continue
        key = o.key_or_group
        if key == "corruption" and isinstance(o.value(), str):
            corruption = str(o.value())
        if found is None and not o.is_sweep_override() and not isinstance(o.value(), str) and (Path(CONF_DIR) / key).is_dir():
            found = (key, a.split("=", 1)[1] if "=" in a else "", o.value())
    if found is None:
        return ""
    key, raw, value = found
    opts = _group_options(key)
    listed = f"{key}'s options: {', '.join(opts)}"
    if value is None and key in defaults and defaults[key] is None:
        set_by = f"; corruption={corruption} chooses its own {key} option" if corruption else ""
        return (f"{key}={raw}: a config group takes one of its options, not null; {key} is unset by default, so "
                f"leave the override out{set_by} ({listed})")
    return f"{key}={raw}: expected one of {listed}{nearest(str(raw), opts)}"


def _missing_option_line(e: BaseException) -> str:
    """Hydra's "Could not find 'aggregator/vision_cones' Available options in 'aggregator': ...
    Config search path: ..." as one line: the override, the group's options (those Hydra
    found, a plug-in's search path included) and the nearest one; "" for other errors."""
    import re

    from benchmark.harness.typed import nearest

    text = str(e)
    m = re.search(r"Could not find '([^']+)/([^'/]+)'", text)
    if not m:
        return ""
    group, option = m.group(1), m.group(2)
    listed = re.search(r"Available options in '[^']*':\s*(.*?)\s*(?:Config search path:|$)", text, re.S)
    opts = listed.group(1).split() if listed else _group_options(group)
    return (f"{group}={option}: unknown option; expected one of {group}'s options: {', '.join(opts)}"
            f"{nearest(option, opts)}")


def _unknown_key_line(e: BaseException) -> str:
    """Hydra's "Could not override 'aggregator.kk'. To append to your config use +..." as our
    line: the key is unknown with or without ``+`` (the typed check refuses it), so name the
    node's valid keys and the nearest one instead of advising ``+``; "" for other errors."""
    import re

    from benchmark.config import valid_keys_hint
    from benchmark.harness.typed import nearest

    m = re.search(r"Could not override '([^']+)'", str(e))
    if not m or "To append" not in str(e):
        return ""
    hint = valid_keys_hint(e, sys.argv[1:])
    valid = hint.split(": ", 1)[1].split(", ") if ": " in hint else []
    return f"{m.group(1)}: unknown key (with or without +){hint}{nearest(m.group(1).rsplit('.', 1)[-1], valid)}"


def _refused_input(e: BaseException) -> BaseException | None:
    """The ValueError with which a stage's or an environment's constructor refused its input
    (a damaged house file), when Hydra wrapped it (``Error in call to target ...``): its own
    line names the thing; None for any other error."""
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    cause = e.__cause__
    if isinstance(e, HydraException) and isinstance(cause, ValueError) and not isinstance(cause, OmegaConfBaseException):
        return cause
    return None


def _write_error(e: BaseException) -> str:
    from benchmark.harness.write_errors import failed_path

    where = failed_path(e)
    return f"cannot write{' ' + where if where else ''} ({getattr(e, 'strerror', None) or e})"


def _report_sweep(first: BaseException) -> int:
    """A multirun some of whose jobs failed (a job's config, a stage, a file it could not
    write): one line per distinct failure, then whether any job finished. Exit status 3 when
    some jobs finished (their results are complete), 2 when none did."""
    import importlib

    from hydra.core.utils import JobStatus

    launched = importlib.import_module("hydra_plugins.roomseg_sweep.roomseg_sweep").LAUNCHED
    failed = [r._return_value for r in launched if r.status != JobStatus.COMPLETED]
    lines = [(_write_error(f) if isinstance(f, OSError) else _one_line(_refused_input(f) or f))
             for f in (failed or [first])]
    for msg in dict.fromkeys(lines):
        print(f"{PROG}: error: {msg}", file=sys.stderr)
    done, total = _finished_jobs()
    sweep.write_summary_after_failure()
    if done:
        print(f"{PROG}: {done} of {total} job(s) finished and their results are complete; {total - done} could "
              f"not run or write theirs (above)", file=sys.stderr)
        return 3
    return 2


def _outcome() -> int:
    """The exit status of a run or multirun that ended normally, from :data:`sweep.OUTCOME`."""
    out = sweep.OUTCOME
    if out["died"]:
        print(f"{PROG}: error: {out['died'][0]}", file=sys.stderr)
        return 1
    if out["errors"]:
        for msg in dict.fromkeys(out["errors"]):
            print(f"{PROG}: error: {msg}", file=sys.stderr)
        return 2
    if out["n_failed"] and not out["allow_failures"]:
        first = f"; first {out['first_failure']}" if out.get("first_failure") else ""
        print(f"{PROG}: {out['n_failed']} house(s) failed in {out['jobs']} job(s){first} (the failed rows of "
              f"metrics.csv say why); run.allow_failures=true exits 0", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
