"""Typed configuration: every key a config holds is one a stage reads, with a value of the type
it declares, checked when the config is composed and before any work.

Three checks, each one line naming the key, the value and what is expected:

* **Known keys at the top** (:func:`check_top_keys`): a key that is neither in the default
  config nor a config group (``+aggregater=vision_cone``, which Hydra lets through with ``+``)
  is refused with the nearest known name.
* **Typed ``_target_`` nodes** (:func:`check_targets`): a node with ``_target_`` is the keyword
  arguments of that class or function, so its signature is its schema: a key that is not a
  parameter (unless it takes ``**kwargs``) is refused with the nearest parameter; a value that
  does not fit the parameter's annotation (``int``, ``float``, ``bool``, ``str``, ``Literal``,
  ``Optional``, sequences, mappings) is refused; null is left to the stage (a value filled in
  later, such as ``roomseg-segment``'s classes from its labels file). A user's own stage is
  checked the same way.
* **The robot label** (:class:`RobotLabel`): ``robot.corruption`` a family of
  ``conf/corruption`` and ``robot.severity`` an integer 0..5.

Value ranges that a type cannot say (a share in [0, 1], an odd window, metres > 0) are said on
the same parameters, ``window: Annotated[int, Odd()]`` with the markers of :mod:`envs.ranges`,
and :func:`check_targets` checks them after the type: ``aggregator.window=4: expected an odd
integer >= 1``. A ranged parameter refuses null unless its type admits None (the message then
ends ", or null"). A class taking ``**settings`` for a dataclass names it in ``SETTINGS``
(``envs.maps.mapping.ScanMapping``): its keys are the dataclass's fields, typed and ranged.
A user's own stage gets its ranges checked by annotating its parameters the same way.

The ``run`` node, which no ``_target_`` class takes, is typed the same way too: its schema is
the dataclass :class:`benchmark.harness.run_settings.RunSettings` (``run.ray`` a nested one),
and :func:`check_fields`, the check of one mapping against parameters or fields that
:func:`check_targets` uses for each ``_target_`` node, checks it
(:func:`benchmark.harness.checks.check_config`); no table of rules is left.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import importlib
import inspect
import math
import re
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from envs.ranges import Range


class ConfigError(ValueError):
    """An out-of-range or malformed setting; the message is one line naming key, value and rule."""


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


def unknown_keys_line(path: str, unknown: Sequence[str], valid: Sequence[str]) -> str:
    """``run.limt: unknown key (with or without +); valid keys under run: name, ...; did you mean
    'run.limit'?`` (the nearest valid key of each unknown one that has one, by
    :func:`difflib.get_close_matches`)."""
    names = ", ".join(f"{path}.{k}" for k in unknown)
    close = [f"{path}.{m[0]}" for k in unknown if (m := difflib.get_close_matches(str(k), [str(v) for v in valid],
                                                                                 n=1, cutoff=0.6))]
    hint = f"; did you mean {' / '.join(repr(c) for c in close)}?" if close else ""
    return (f"{names}: unknown key{'s' if len(unknown) > 1 else ''} (with or without +); valid keys "
            f"under {path}: {', '.join(valid)}{hint}")


#: keys of a ``_target_`` node that Hydra reads itself.
HYDRA_KEYS = frozenset({"_target_", "_partial_", "_convert_", "_recursive_", "_args_"})
#: the highest severity of a robot condition.
MAX_SEVERITY = 5


def nearest(name: str, known: Sequence[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest of ``known``, or ``""``."""
    best = difflib.get_close_matches(str(name), [str(k) for k in known], n=1, cutoff=0.6)
    return f"; did you mean {best[0]!r}?" if best else ""


@functools.lru_cache(maxsize=8)
def known_top_keys(config_name: str = "config") -> tuple[str, ...]:
    """The keys a composed config may hold at the top: the primary config's own keys (read from
    its YAML file; composing it is not needed, and would cost every command's start-up a
    compose) and every config group of ``conf/`` (a chosen group, such as ``segmenter``, adds
    its key; a ``_global_`` option sets keys that are already among these)."""
    from omegaconf import OmegaConf

    from benchmark.config import config_location
    from benchmark.paths import CONF_DIR

    folder = Path(config_location(config_name)[0])
    own = {str(k) for k in OmegaConf.load(folder / f"{config_name}.yaml") if k not in ("defaults", "hydra")}
    groups = {p.name for f in (folder, Path(CONF_DIR)) for p in f.iterdir() if p.is_dir() and p.name != "hydra"}
    return tuple(sorted(own | groups))


def check_top_keys(keys: Sequence[str], config_name: str = "config", where: str = "") -> None:
    """Refuse top-level keys no stage reads.

    Raises:
        ConfigError: ``unknown key 'aggregater' (with or without +); did you mean 'aggregator'?``."""
    known = known_top_keys(config_name)
    for k in keys:
        if str(k) not in known:
            hint = nearest(k, known) or f"; valid keys: {', '.join(known)}"
            raise ConfigError(f"{k}: unknown key{where} (with or without +); no stage reads it{hint}")


def check_top_overrides(args: Sequence[str], config_name: str = "config") -> None:
    """:func:`check_top_keys` on command-line overrides (``[+|++|~]key[.sub]=value``), before
    Hydra composes or creates anything (flags and Hydra's own ``hydra.*`` are left alone)."""
    tops = [re.split(r"[./@]", key, maxsplit=1)[0] for key, _ in overrides(args)]  # group/option@pkg, a.b
    check_top_keys([k for k in tops if k and k != "hydra"], config_name, " on the command line")


@dataclass(frozen=True)
class RobotLabel:
    """What every row says of the robot's conditions (``robot:`` of ``conf/config.yaml``).

    Attributes:
        corruption: the family: ``clean`` or a prefix of a ``conf/corruption`` file.
        severity: 0 (clean, or a family's own severity 0: :meth:`own_severity_zero`) ..
            :data:`MAX_SEVERITY`.
    """

    corruption: str = "clean"
    severity: int = 0

    @staticmethod
    def families() -> tuple[str, ...]:
        from benchmark.paths import CONF_DIR

        names = {p.stem.rsplit("_", 1)[0] for p in (Path(CONF_DIR) / "corruption").glob("*.yaml")}
        return tuple(sorted(names | {"clean"}))

    @staticmethod
    def own_severity_zero() -> tuple[str, ...]:
        """Families whose severity 0 is a condition of their own (a ``<family>_0.yaml`` in
        ``conf/corruption``: ``explore_0``, the unlimited exploration), not ``clean``."""
        from benchmark.paths import CONF_DIR

        return tuple(sorted(p.stem[:-2] for p in (Path(CONF_DIR) / "corruption").glob("*_0.yaml")))

    @classmethod
    def check(cls, node: Any) -> RobotLabel:
        """The label of a ``robot`` node.

        Raises:
            ConfigError: an unknown key, an unknown family, or a severity that is not an
                integer 0..5 (0 exactly for ``clean``; 1..5 for a family without its own 0)."""
        if node is None:
            return cls()
        if not isinstance(node, Mapping):
            raise ConfigError(f"robot={node!r}: expected a mapping with corruption and severity")
        for k in node:
            if k not in ("corruption", "severity"):
                raise ConfigError(f"robot.{k}: unknown key; expected corruption, severity{nearest(k, ['corruption', 'severity'])}")
        fams = cls.families()
        corruption = node.get("corruption", "clean")
        if corruption not in fams:
            raise ConfigError(f"robot.corruption={corruption!r}: expected one of {', '.join(fams)}"
                              f"{nearest(str(corruption), fams)}")
        sev = node.get("severity", 0)
        if isinstance(sev, bool) or not isinstance(sev, int) or not 0 <= sev <= MAX_SEVERITY:
            raise ConfigError(f"robot.severity={sev!r}: expected an integer 0..{MAX_SEVERITY}")
        own_zero = corruption in cls.own_severity_zero()
        if (corruption == "clean" and sev != 0) or (sev == 0 and corruption != "clean" and not own_zero):
            raise ConfigError(f"robot.severity={sev!r} with robot.corruption={corruption!r}: expected severity 0 "
                              f"exactly for clean (and 1..{MAX_SEVERITY} for a corruption; 0 too for a family with "
                              f"its own severity 0: {', '.join(cls.own_severity_zero()) or 'none'})")
        return cls(str(corruption), int(sev))


# --------------------------------------------------------------------------- _target_ nodes


@dataclass(frozen=True)
class Param:
    """What a ``_target_`` node's key must hold: the parameter's type and its value ranges.

    Attributes:
        hint: the annotation without its ranges (None: not annotated, any value).
        ranges: the :class:`envs.ranges.Range` markers of ``Annotated[...]``, in order.
    """

    hint: Any = None
    ranges: tuple[Range, ...] = ()

    @property
    def nullable(self) -> bool:
        """Whether the type admits null (``int | None``): then a range allows null too."""
        return _fits(None, self.hint) is not False


def _ranges(hint: Any) -> tuple[Range, ...]:
    """The :class:`Range` markers of ``hint``: of ``Annotated[T, m, ...]``, and of each
    ``Annotated`` member of a union (``Annotated[int, Integer(0)] | None``)."""
    if typing.get_origin(hint) is typing.Annotated:
        return tuple(m for m in hint.__metadata__ if isinstance(m, Range))
    return tuple(m for h in typing.get_args(hint) for m in _ranges(h))


def _hints(obj: Any) -> dict[str, Param]:
    """parameter -> :class:`Param` from the annotations of ``obj`` (a function, or a class's
    ``__init__``, or a dataclass's fields); empty where an annotation does not resolve."""
    target = obj.__init__ if inspect.isclass(obj) and not dataclasses.is_dataclass(obj) else obj
    try:
        bare = typing.get_type_hints(target, include_extras=False)
        full = typing.get_type_hints(target, include_extras=True)
    except Exception:  # noqa: BLE001 - an annotation that does not resolve is not checked
        return {}
    return {k: Param(bare.get(k), _ranges(full.get(k))) for k in bare}


@functools.lru_cache(maxsize=256)
def _signature(target: str) -> tuple[dict[str, Param], bool] | None:
    """(parameter -> :class:`Param`, takes **kwargs) of ``target``, or None when it cannot be
    imported (the stage's own build then says why).

    A class that takes ``**settings`` and hands them to a dataclass names that dataclass in a
    ``SETTINGS`` class attribute (``envs.maps.mapping.ScanMapping.SETTINGS = ScanSettings``):
    its keys are then the dataclass's fields, with their types and ranges, and no others."""
    module, _, name = target.rpartition(".")
    try:
        obj = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError, ValueError):
        return None
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        return None
    hints = _hints(obj)
    params, var_kw = {}, False
    for p in sig.parameters.values():
        if p.kind is p.VAR_KEYWORD:
            var_kw = True
        elif p.kind is not p.VAR_POSITIONAL:
            params[p.name] = hints.get(p.name, Param())
    settings = getattr(obj, "SETTINGS", None) if inspect.isclass(obj) else None
    if var_kw and settings_class(settings) is not None:
        params.update(settings_params(settings))
        var_kw = False
    return params, var_kw


def settings_class(hint: Any) -> type | None:
    """``hint`` if it is a dataclass (a class, not an instance), else None."""
    return hint if inspect.isclass(hint) and dataclasses.is_dataclass(hint) else None


@functools.lru_cache(maxsize=64)
def settings_params(settings: type) -> dict[str, Param]:
    """field -> :class:`Param` of a dataclass, in the order of its fields (a field whose
    annotation does not resolve holds any value)."""
    fields = _hints(settings)
    return {f.name: fields.get(f.name, Param()) for f in dataclasses.fields(settings)}


def _fits(value: Any, hint: Any) -> bool | None:
    """Whether ``value`` (a plain config value) fits ``hint``; None where the hint says nothing
    this check knows."""
    if hint is None or hint is Any:
        return None
    origin = typing.get_origin(hint)
    if origin is typing.Union or (origin is not None and str(origin) == "<class 'types.UnionType'>"):
        answers = [_fits(value, h) for h in typing.get_args(hint)]
        if any(a is True for a in answers):
            return True
        return None if any(a is None for a in answers) else False
    if hint is type(None):
        return value is None
    if origin is typing.Literal:
        return value in typing.get_args(hint)
    if hint is bool:
        return isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if hint is float:
        return isinstance(value, int | float) and not isinstance(value, bool)
    if hint is str:
        return isinstance(value, str)
    if hint is Path:
        return isinstance(value, str)
    if settings_class(hint) is not None:  # a nested dataclass of settings (run.ray): its keys
        return isinstance(value, Mapping)
    base = origin or hint
    if base in (list, tuple, Sequence, typing.Sequence) or (inspect.isclass(base) and base in (list, tuple)):
        return isinstance(value, list | tuple)
    if base in (dict, Mapping, typing.Mapping):
        return isinstance(value, Mapping)
    return None


def _what(hint: Any) -> str:
    """The words of a type: ``an integer``; a union's members with ``or`` (``, or null`` last
    for None); a dataclass of settings by its fields."""
    args = typing.get_args(hint)
    origin = typing.get_origin(hint)
    if args and (origin is typing.Union or str(origin) == "<class 'types.UnionType'>"):
        words = [_what(h) for h in args if h is not type(None)]
        return " or ".join(words) + (", or null" if type(None) in args else "")
    if settings_class(hint) is not None:
        return f"a mapping of {', '.join(f.name for f in dataclasses.fields(hint))}"
    text = str(hint).replace("typing.", "").replace("NoneType", "None").replace("<class '", "").replace("'>", "")
    return {"int": "an integer", "float": "a number", "bool": "true or false", "str": "a string"}.get(text, text)


def check_fields(node: Mapping[str, Any], params: Mapping[str, Param], path: str, *, owner: str | None = None,
                 var_kw: bool = False) -> None:
    """Check the keys and values of one mapping against ``params`` (a signature's parameters,
    or a dataclass's fields: :func:`settings_params`); a value that is itself a dataclass of
    settings (``run.ray``) is checked against that dataclass's fields the same way.

    Args:
        node: the mapping (plain config values).
        params: key -> :class:`Param` (type and ranges).
        path: the dotted name of ``node`` (``aggregator``, ``run``).
        owner: the class or function whose parameters these are (a ``_target_``): then a null
            value is left to it unless the parameter is ranged (a value filled in later), and a
            wrong type names its parameter. None for the harness's own settings (``run``):
            null only where the type admits None, and a value is described by all it must be
            (``run.limit='abc': expected an integer >= 1, or null``).
        var_kw: whether a key that is not in ``params`` is let through (``**kwargs``).

    Raises:
        ConfigError: the first unknown key or bad value, in one line."""
    for key, value in node.items():
        if key in HYDRA_KEYS:
            continue
        dotted = f"{path}.{key}" if path else str(key)
        if key not in params:
            if var_kw:
                continue
            if owner is None:
                raise ConfigError(unknown_keys_line(path, [str(key)], list(params)))
            raise ConfigError(f"{dotted}: unknown key, not a parameter of {owner} (valid: "
                              f"{', '.join(params)}){nearest(key, list(params))}")
        if isinstance(value, Mapping) and "_target_" in value:
            continue  # a nested stage: check_targets checks it on its own
        _check_value(value, params[key], dotted, owner)


def _check_value(value: Any, param: Param, dotted: str, owner: str | None) -> None:
    """One value of :func:`check_fields`: the type first, then each range."""
    settings = settings_class(param.hint)
    if settings is not None and isinstance(value, Mapping):
        check_fields(value, settings_params(settings), dotted,
                     owner=None if owner is None else f"{settings.__module__}.{settings.__qualname__}")
        return
    unset = value is None or (owner is not None and isinstance(value, float) and math.isnan(value))
    if unset and owner is not None and not param.ranges:
        return  # null: not set yet (roomseg-segment's ${classes} comes from its labels)
    if value is None and param.nullable:
        return
    if value is None or _fits(value, param.hint) is False:
        if owner is not None and not unset:
            raise ConfigError(f"{dotted}={value!r}: expected {_what(param.hint)} "
                              f"(the type of {owner.rsplit('.', 1)[-1]}'s {dotted.rsplit('.', 1)[-1]})")
        if owner is None:
            words = " and ".join(r.what for r in param.ranges) or _what(param.hint)
            raise ConfigError(f"{dotted}={value!r}: expected {words}{', or null' if param.nullable else ''}")
    for rule in param.ranges:
        if not rule(value):
            raise ConfigError(f"{dotted}={value!r}: {rule.explain(value, param.nullable)}")


def locate_problem(target: str) -> str | None:
    """Why ``target`` (a ``_target_``: ``module.name``, or ``module.Class.attr``) cannot be
    found, in words: a module that is not on Python's path (a plug-in's folder that is not
    there), or a module without that name; None when it is found, or when its module exists
    but fails to import (a dependency it imports is missing: the stage's own build says what to
    install)."""
    parts = str(target).split(".")
    if len(parts) < 2 or not all(parts):
        return "not a dotted path, module.name"
    for i in range(len(parts) - 1, 0, -1):
        module = ".".join(parts[:i])
        try:
            obj = importlib.import_module(module)
        except ModuleNotFoundError as e:
            if e.name and (module == e.name or module.startswith(e.name + ".")):
                continue  # no such module: a shorter prefix may be one
            return None
        except Exception:  # noqa: BLE001 - the module is there; its build reports its own error
            return None
        for k, attr in enumerate(parts[i:]):
            if not hasattr(obj, attr):
                owner = ".".join(parts[: i + k])
                return f"{owner} has no {attr!r}"
            obj = getattr(obj, attr)
        return None
    return f"no module named {parts[0]!r} on Python's path"


def check_targets(node: Any, path: str = "") -> None:
    """Check every ``_target_`` node under ``node`` (a plain config) against its signature
    (:func:`check_fields`, with the target as owner).

    Raises:
        ConfigError: ``aggregator.kk: not a parameter of benchmark.aggregators...VisionCone;
            did you mean 'k'?``, ``aggregator.k='x': expected an integer`` (the type) or
            ``aggregator.window=4: expected an odd integer >= 1`` (a range of the annotation,
            :mod:`envs.ranges`); the type is checked first."""
    if isinstance(node, Mapping):
        target = node.get("_target_")
        if isinstance(target, str):
            sig = _signature(target)
            if sig is not None:
                check_fields(node, sig[0], path, owner=target, var_kw=sig[1])
            else:
                problem = locate_problem(target)
                if problem is not None:
                    where = f"{path}._target_" if path else "_target_"
                    raise ConfigError(f"{where}={target!r}: {problem}; expected an importable class or function "
                                      f"(a plug-in: put the folder that holds its package on PYTHONPATH, "
                                      f"docs/plugins.md)")
        for key, value in node.items():
            if key != "_target_":
                check_targets(value, f"{path}.{key}" if path else str(key))
    elif isinstance(node, list | tuple):
        for i, v in enumerate(node):
            check_targets(v, f"{path}[{i}]")


def check_typed(plain: Mapping[str, Any], config_name: str = "config") -> None:
    """The three checks of this module on a composed config (plain, resolved, no ``hydra``).

    Raises:
        ConfigError: the first key that no stage reads or whose value has the wrong type."""
    check_top_keys([k for k in plain if k != "hydra"], config_name)
    if config_name == "config":
        RobotLabel.check(plain.get("robot"))
    check_targets({k: v for k, v in plain.items() if k != "hydra"})


__all__ = ["ConfigError", "Param", "overrides", "unknown_keys_line", "RobotLabel", "check_fields", "check_typed", "check_targets", "check_top_keys", "settings_class", "settings_params", "check_top_overrides", "known_top_keys",
           "nearest", "locate_problem", "MAX_SEVERITY"]
