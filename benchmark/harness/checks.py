"""Configuration checked before any work: one line naming the key, the value and what is allowed.

:func:`check_config` checks what no stage class says itself: the ``run`` node (not a
``_target_`` node: it configures the harness, not a stage), with the rules of :data:`RULES`
((group, key) -> test; only ``run`` keys), ``run.force`` and ``run.houses``, and one rule
across two keys (``env.stop`` above ``env.start``). A key under ``run`` that the ``run:`` node
of ``conf/config.yaml`` does not have (a typo, or one added with ``+run.<key>``, which Hydra
lets through) is refused, listing the valid keys (:func:`check_run_keys`).

The value ranges of the stages (``aggregator.window`` an odd number of pixels,
``segmenter.window`` metres > 0, a share in [0, 1]) are not here: each stage class says them
on its parameters (``window: Annotated[int, Odd()]``, markers of :mod:`envs.ranges`), and
:func:`benchmark.harness.typed.check_targets` checks them with the types, for a user's own
stage as for ours.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any


class ConfigError(ValueError):
    """An out-of-range or malformed setting; the message is one line naming key, value and rule."""


Rule = Callable[[Any], bool]


def _num(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def pos_int(v: Any) -> bool:
    return _int(v) and v >= 1


def ray_settings(v: Any) -> bool:
    """a mapping with address: null, auto or host:port, and connect_timeout: seconds > 0"""
    if not isinstance(v, Mapping):
        return False
    t = v.get("connect_timeout")
    if t is not None and not (_num(t) and t > 0):
        return False
    a = v.get("address")
    return a is None or (isinstance(a, str) and (a == "auto" or a.startswith("ray://")
                                                 or (":" in a and a.rsplit(":", 1)[1].isdigit())))


def one_of(*allowed: Any) -> Rule:
    def rule(v: Any) -> bool:
        return v in allowed
    rule.__doc__ = "one of " + ", ".join(map(repr, allowed))
    return rule


def optional(rule: Rule) -> Rule:
    def opt(v: Any) -> bool:
        return v is None or rule(v)
    opt.__doc__ = (rule.__doc__ or _WHAT.get(rule, rule.__name__)) + ", or null"
    return opt


_WHAT: dict[Callable, str] = {pos_int: "an integer >= 1"}

#: (group, key) -> rule, for the groups that are not a stage's ``_target_`` node (``run``
#: only). A stage's ranges are said on its class's parameters (``Annotated[int, Odd()]``,
#: :mod:`envs.ranges`) and checked by :func:`benchmark.harness.typed.check_targets`; no stage
#: group may come back here (tests/test_ranges.py).
RULES: dict[tuple[str, str], Rule] = {
    ("run", "limit"): optional(pos_int), ("run", "progress"): one_of(True, False),
    ("run", "save_maps"): one_of(True, False), ("run", "allow_failures"): one_of(True, False),
    ("run", "cache_failures"): one_of(True, False),
    ("run", "workers"): optional(pos_int), ("run", "executor"): one_of("local", "ray"),
    ("run", "ray"): ray_settings,
}


def _describe(rule: Rule) -> str:
    return _WHAT.get(rule) or rule.__doc__ or "a valid value"


def _plain(cfg: Any) -> Mapping[str, Any]:
    try:
        from omegaconf import DictConfig, OmegaConf

        if isinstance(cfg, DictConfig):
            body = OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"])
            return OmegaConf.to_container(body, resolve=True)  # type: ignore[return-value]
    except ImportError:  # pragma: no cover - omegaconf is a core dependency
        pass
    return cfg


def run_keys() -> tuple[str, ...]:
    """The valid keys under ``run``: those of the ``run:`` node of ``conf/config.yaml``, in
    its order, read from the file each time (a key added there is valid at once; the
    composed default config has the same, checked in tests/test_config_keys.py)."""
    from omegaconf import DictConfig, OmegaConf

    from benchmark.paths import CONF_DIR

    node = OmegaConf.load(Path(CONF_DIR) / "config.yaml").get("run")
    if not isinstance(node, DictConfig):
        raise ConfigError(f"{Path(CONF_DIR) / 'config.yaml'}: no run: node")
    return tuple(str(k) for k in node.keys())


def check_run_keys(keys: Any) -> None:
    """Refuse keys under ``run`` that the default config does not have.

    Args:
        keys: the keys given under ``run`` (e.g. ``["limt"]`` for ``+run.limt=3``).

    Raises:
        ConfigError: ``run.<key>: unknown key; valid keys under run: name, label, ...``.
    """
    valid = run_keys()
    unknown = [str(k) for k in keys if str(k) not in valid]
    if unknown:
        names = ", ".join(f"run.{k}" for k in unknown)
        raise ConfigError(f"{names}: unknown key{'s' if len(unknown) > 1 else ''} (with or without +); valid keys "
                          f"under run: {', '.join(valid)}")


def overrides(args: Any) -> list[tuple[str, str | None]]:
    """(dotted key, value or None) of each ``[+|++|~]key[=value]`` override in ``args``, as typed
    on the command line (flags and their values are left out; a deletion ``~key`` has no value)."""
    out = []
    for a in map(str, args):
        if a.startswith("-") or ("=" not in a and not a.startswith("~")):  # flags, values of flags
            continue
        key, eq, value = a.partition("=")
        out.append((key.lstrip("+~"), value if eq and not a.startswith("~") else None))
    return out


def check_run_overrides(args: Any) -> None:
    """:func:`check_run_keys` on the command line, before Hydra composes or creates anything:
    the ``run.<key>`` of every ``[+|++|~]run.<key>[=value]`` override in ``args`` (other
    arguments are left to Hydra).

    Raises:
        ConfigError: as :func:`check_run_keys`, or a value a rule refuses (one line)."""
    keys, values = [], []
    for key, text in overrides(args):
        if key.startswith("run.") and len(key) > 4:
            keys.append(key[4:].split(".", 1)[0])
            if text is not None:
                values.append((key[4:], text))
    if keys:
        check_run_keys(keys)
    # a value the config check would refuse in every job (run.limit=0 in a sweep of 624 jobs):
    # refused once, before the sweep starts (swept values, a,b,c, are left to each job)
    import yaml

    for key, text in values:
        rule = RULES.get(("run", key))
        if rule is None or "," in text or text.startswith(("range(", "choice(", "glob(")):
            continue
        try:
            value = yaml.safe_load(text) if text else None
        except yaml.YAMLError:
            continue
        if not rule(value):
            raise ConfigError(f"run.{key}={value!r}: expected {_describe(rule)}")


def check_config(cfg: Any, stages: tuple[str, ...] = ("render", "classify", "score")) -> None:
    """Check the keys under ``run`` (:func:`check_run_keys`), every setting a rule names, and
    ``run.force`` / ``run.houses``.

    Raises:
        ConfigError: the first bad setting: ``<group>.<key>=<value>: expected <rule>``, or
            the unknown keys under ``run`` with the valid ones.
    """
    c = _plain(cfg)
    if isinstance(c.get("run"), Mapping):
        check_run_keys(c["run"].keys())
    for group, node in c.items():
        if not isinstance(node, Mapping):
            continue
        for key, value in node.items():
            rule = RULES.get((group, key))
            if rule is not None and not rule(value):
                raise ConfigError(f"{group}.{key}={value!r}: expected {_describe(rule)}")
    env = c.get("env") or {}
    if isinstance(env, Mapping) and _int(env.get("start")) and _int(env.get("stop")) and env["stop"] <= env["start"]:
        raise ConfigError(f"env.stop={env['stop']!r}: expected a house index above env.start={env['start']!r} "
                          f"(or null for the end of the file)")
    run = c.get("run") or {}
    force = run.get("force")
    items = [force] if isinstance(force, str) else (force or [])
    if not isinstance(items, list | tuple) or any(not isinstance(f, str) for f in items):
        raise ConfigError(f"run.force={force!r}: expected a list of stage names from {list(stages)} or 'all'")
    unknown = [f for f in items if f not in (*stages, "all")]
    if unknown:
        raise ConfigError(f"run.force={list(items)!r}: unknown stage(s) {unknown}; expected names from "
                          f"{list(stages)} or 'all'")
    houses = run.get("houses")
    if houses is not None and (not isinstance(houses, list | tuple) or not houses):
        raise ConfigError(f"run.houses={houses!r}: expected a non-empty list of house ids, or null for all")


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


__all__ = ["ConfigError", "RULES", "overrides", "check_config", "check_run_keys", "check_run_overrides", "check_writable", "run_keys"]
