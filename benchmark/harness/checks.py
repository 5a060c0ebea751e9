"""Configuration checked before any work: one line naming the key, the value and what is allowed.

:func:`check_config` checks what no stage class says itself: the ``run`` node (not a
``_target_`` node: it configures the harness, not a stage), against its schema, the frozen
dataclass :class:`benchmark.harness.run_settings.RunSettings` (each key's type and range, as
``Annotated`` markers of :mod:`envs.ranges`, read by
:func:`benchmark.harness.typed.check_fields`, the check of the stages' parameters), and one
rule across two keys (``env.stop`` above ``env.start``). A key under ``run`` that
``RunSettings`` does not have (a typo, or one added with ``+run.<key>``, which Hydra lets
through) is refused, listing the valid keys (:func:`check_run_keys`); they are the keys of the
``run:`` node of ``conf/config.yaml`` (tests/test_run_settings.py). :func:`check_run_overrides`
does both on the command line, once, before a sweep starts. (:class:`ConfigError`, the one-line
error of every check, is :mod:`benchmark.harness.typed`'s, imported here too.)

The value ranges of the stages (``aggregator.window`` an odd number of pixels,
``segmenter.window`` metres > 0, a share in [0, 1]) are not here: each stage class says them
on its parameters (``window: Annotated[int, Odd()]``, markers of :mod:`envs.ranges`), and
:func:`benchmark.harness.typed.check_targets` checks them with the types, for a user's own
stage as for ours.
"""

from __future__ import annotations

import dataclasses
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from benchmark.harness.run_settings import RunSettings
from benchmark.harness.typed import (  # ConfigError, overrides: callers import them from here too
    ConfigError,
    check_fields,
    overrides,
    settings_class,
    settings_params,
    unknown_keys_line,
)


def _plain(cfg: Any) -> Mapping[str, Any]:
    try:
        from omegaconf import DictConfig

        if isinstance(cfg, DictConfig):
            from benchmark.config import resolved_body

            return resolved_body(cfg)
    except ImportError:  # pragma: no cover - omegaconf is a core dependency
        pass
    return cfg


def run_keys() -> tuple[str, ...]:
    """The valid keys under ``run``: the fields of
    :class:`benchmark.harness.run_settings.RunSettings`, in order (those of the ``run:`` node
    of ``conf/config.yaml``, in its order: tests/test_run_settings.py)."""
    return tuple(f.name for f in dataclasses.fields(RunSettings))


def check_run_keys(keys: Any) -> None:
    """Refuse keys under ``run`` that :class:`~benchmark.harness.run_settings.RunSettings` does
    not have.

    Args:
        keys: the keys given under ``run`` (e.g. ``["limt"]`` for ``+run.limt=3``).

    Raises:
        ConfigError: ``run.<key>: unknown key; valid keys under run: name, label, ...``.
    """
    valid = run_keys()
    unknown = [str(k) for k in keys if str(k) not in valid]
    if unknown:
        raise ConfigError(unknown_keys_line("run", unknown, valid))


def check_run(node: Any) -> None:
    """Check a ``run`` node (plain, resolved) against
    :class:`~benchmark.harness.run_settings.RunSettings`: its keys (:func:`check_run_keys`),
    then each value's type and range (:func:`benchmark.harness.typed.check_fields`). A key
    left out is not an error (the default config has them all).

    Raises:
        ConfigError: ``run.limit=0: expected an integer >= 1, or null``, ``run.force=['bogus']:
            unknown stage(s) ['bogus']; ...``, ``run.ray.address='x': expected auto, ...``."""
    if not isinstance(node, Mapping):
        raise ConfigError(f"run={node!r}: expected a mapping of {', '.join(run_keys())}")
    check_run_keys(node.keys())
    check_fields(node, settings_params(RunSettings), "run")


#: what :func:`_override_value` returns for a value the command-line check leaves alone.
_UNCHECKED = object()


def _override_value(text: str) -> Any:
    """The value Hydra makes of an override's ``text`` (``yes`` a string, ``[a,b]`` a list), or
    :data:`_UNCHECKED` for a sweep (``a,b``, ``range(...)``: each job checks its own value),
    an interpolation (resolved later) or text Hydra will refuse itself."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        override = OverridesParser.create().parse_override(f"key={text}")
    except Exception:  # noqa: BLE001 - Hydra says what is wrong with it, in its own words
        return _UNCHECKED
    if override.is_sweep_override():
        return _UNCHECKED
    value = override.value()
    return _UNCHECKED if "${" in repr(value) else value


#: run keys whose every swept value is checked on the command line: they name the folder Hydra
#: creates for a job before the job can check its own config (``run.name=a,../../x``).
CHECKED_WHEN_SWEPT = ("run.name",)


def _swept_values(text: str) -> list[Any]:
    """The values of a choice or range sweep ``text`` (``a,b``, ``range(1,3)``) as Hydra makes
    them, without interpolations; [] for anything else."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        override = OverridesParser.create().parse_override(f"key={text}")
        values = list(override.sweep_iterator()) if override.is_sweep_override() else []
    except Exception:  # noqa: BLE001 - not an enumerable sweep: Hydra says what is wrong with it
        return []
    return [v for v in values if "${" not in repr(v)]


def check_run_overrides(args: Any) -> None:
    """:func:`check_run` on the command line, before Hydra composes or creates anything: the
    ``run.<key>`` of every ``[+|++|~]run.<key>[=value]`` override in ``args`` must be a key of
    ``RunSettings`` (:func:`check_run_keys`, a nested one such as ``run.ray.<key>`` too), and
    its value, as Hydra reads it, of the key's type and range: a value every job of a sweep
    would refuse (``run.limit=0`` in a sweep of 624 jobs) is refused once, before the sweep
    starts. Swept values (``a,b,c``) and interpolations are left to each job, but for the keys
    of :data:`CHECKED_WHEN_SWEPT` (``run.name``: each job's folder is made before the job runs)
    every value of a choice or range sweep is checked here too; other arguments are left to Hydra.

    Raises:
        ConfigError: as :func:`check_run_keys`, or a value its field refuses (one line)."""
    keys, values = [], []
    for key, text in overrides(args):
        if key.startswith("run.") and len(key) > 4:
            keys.append(key[4:].split(".", 1)[0])
            if text is not None:
                values.append((key, text))
    if not keys:
        return
    check_run_keys(keys)
    for key, text in values:
        for value in _swept_values(text) if key in CHECKED_WHEN_SWEPT else ():
            check_fields({key.split(".")[-1]: value}, settings_params(RunSettings), "run")
        value = _override_value(text)
        if value is _UNCHECKED:
            continue
        *parents, last = key.split(".")[1:]
        params = settings_params(RunSettings)
        for part in parents:  # run.ray.address: the fields of RaySettings
            settings = settings_class(params[part].hint) if part in params else None
            if settings is None:
                params = None
                break
            params = settings_params(settings)
        if params is not None:
            check_fields({last: value}, params, ".".join(key.split(".")[:-1]))


def check_config(cfg: Any) -> None:
    """Check the ``run`` node (:func:`check_run`) and ``env.stop`` above ``env.start``.

    Raises:
        ConfigError: the first bad setting: ``<group>.<key>=<value>: expected <what>``, or
            the unknown keys under ``run`` with the valid ones.
    """
    c = _plain(cfg)
    if "run" in c:
        check_run(c["run"])
    env = c.get("env") or {}
    if isinstance(env, Mapping) and _int(env.get("start")) and _int(env.get("stop")) and env["stop"] <= env["start"]:
        raise ConfigError(f"env.stop={env['stop']!r}: expected a house index above env.start={env['start']!r} "
                          f"(or null for the end of the file)")


def _int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def check_writable(path: str | Path, key: str) -> Path:
    """Create ``path`` (a folder) if needed and check that a file can be written in it.

    Raises:
        ConfigError: one line naming the setting, the path and the system's reason."""
    p = Path(path)
    try:
        p.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".write-check.", dir=p)
        os.close(fd)
        os.unlink(tmp)
    except OSError as e:
        raise ConfigError(f"{key}: cannot write in {p} ({e.strerror or e})") from None
    return p


__all__ = ["ConfigError", "overrides", "check_config", "check_run", "check_run_keys", "unknown_keys_line", "check_run_overrides", "check_writable", "run_keys"]
