"""Configuration checked before any work: one line naming the key, the value and what is allowed.

:func:`check_config` walks the rules below over a composed config (a plain dict or an
OmegaConf node). A rule is (group, key) -> test; the group is the config node the key sits
in (``env``, ``aggregator``, ``run``, ...), so ``aggregator.window`` (pixels, odd) and
``segmenter.window`` (metres) are checked differently. Keys a rule does not name pass
unchecked (a user's own stage validates its own arguments when it is built), except under
``run``: a key there that the ``run:`` node of ``conf/config.yaml`` does not have (a typo,
or one added with ``+run.<key>``, which Hydra lets through) is refused, listing the valid
keys (:func:`check_run_keys`).
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


def positive(v: Any) -> bool:
    return _num(v) and v > 0


def non_negative(v: Any) -> bool:
    return _num(v) and v >= 0


def fraction(v: Any) -> bool:
    return _num(v) and 0 <= v <= 1


def pos_int(v: Any) -> bool:
    return _int(v) and v >= 1


def nonneg_int(v: Any) -> bool:
    return _int(v) and v >= 0


def odd_int(v: Any) -> bool:
    return _int(v) and v >= 1 and v % 2 == 1


def angle(v: Any) -> bool:
    return _num(v) and 0 < v <= 360


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


def range_m(v: Any) -> bool:
    """A range in metres: > 0, infinity allowed (an unlimited sensor)."""
    return isinstance(v, int | float) and not isinstance(v, bool) and v > 0 and not math.isnan(v)


def range_pair(v: Any) -> bool:
    return isinstance(v, list | tuple) and len(v) == 2 and all(positive(x) for x in v) and v[0] <= v[1]


_WHAT: dict[Callable, str] = {
    positive: "a number > 0", non_negative: "a number >= 0", fraction: "a number in [0, 1]",
    pos_int: "an integer >= 1", nonneg_int: "an integer >= 0", odd_int: "an odd integer >= 1",
    range_m: "metres > 0 (.inf: unlimited)",
    angle: "an angle in (0, 360] degrees", range_pair: "[low, high] with 0 < low <= high",
}

#: (group, key) -> rule. ``*`` matches any group.
RULES: dict[tuple[str, str], Rule] = {
    ("env", "resolution"): positive, ("env", "wall_thickness"): non_negative, ("env", "clearance"): non_negative,
    ("env", "max_object_base"): non_negative, ("env", "n_houses"): pos_int, ("env", "seed_start"): nonneg_int,
    ("env", "start"): optional(nonneg_int), ("env", "stop"): optional(nonneg_int),
    ("env", "open_plan_share"): fraction, ("env", "length"): range_pair, ("env", "depth"): range_pair,
    ("env", "reachable"): one_of("start", "largest", "all"), ("env", "image_preset"): one_of("ros", "white_only"),
    ("env", "free_thresh"): optional(fraction), ("env", "occupied_thresh"): optional(fraction),
    ("env", "max_map_pixels"): optional(pos_int), ("env", "poses_frame"): one_of("ros", "sim", "pixel"),
    ("viewpoints", "offset"): non_negative, ("viewpoints", "spacing"): positive,
    ("viewpoints", "n_headings"): pos_int, ("viewpoints", "heading_spread"): lambda v: _num(v) and 0 <= v <= 360,
    ("viewpoints", "min_contour"): non_negative, ("viewpoints", "off_map"): one_of("error", "drop"),
    ("renderer", "fov"): lambda v: _num(v) and 0 < v < 180, ("renderer", "max_range"): positive,
    ("renderer", "occluder_height"): non_negative, ("renderer", "width"): pos_int, ("renderer", "height"): pos_int,
    ("renderer", "grid_size"): positive, ("renderer", "min_share"): fraction,
    ("classifier", "accuracy"): fraction, ("classifier", "alpha"): positive, ("classifier", "batch_size"): pos_int,
    ("classifier", "image_size"): pos_int, ("classifier", "train_start"): nonneg_int,
    ("classifier", "train_stop"): optional(nonneg_int),
    ("aggregator", "k"): pos_int, ("aggregator", "connectivity"): one_of(4, 8),
    ("aggregator", "weighting"): one_of("majority", "probability"), ("aggregator", "fov"): angle,
    ("aggregator", "max_range_m"): positive, ("aggregator", "blocked_ray_m"): non_negative,
    ("aggregator", "window"): odd_int, ("aggregator", "vote"): one_of("label", "probability"),
    ("aggregator", "ray_density"): positive,
    ("postprocess", "target_resolution"): positive, ("postprocess", "window"): odd_int,
    ("postprocess", "iterations"): nonneg_int, ("postprocess", "min_area"): non_negative,
    ("postprocess", "dp_tolerance"): non_negative,
    ("metrics", "match"): one_of("iou", "overlap"), ("metrics", "connectivity"): one_of(4, 8),
    ("metrics", "min_segment_m2"): non_negative, ("metrics", "min_colour_m2"): non_negative,
    ("metrics", "instances"): one_of("ids", "connected"),
    ("segmenter", "min_seed_area"): non_negative, ("segmenter", "min_room_area"): non_negative,
    ("segmenter", "max_area"): positive, ("segmenter", "step"): positive,
    ("segmenter", "max_door"): positive, ("segmenter", "window"): positive,
    ("segmenter", "widening"): lambda v: _num(v) and v >= 1,
    # robot conditions (conf/mapping, conf/pose_error, conf/label_noise, exploration viewpoints):
    # checked before any work, so that a bad value caches nothing
    ("mapping", "height"): lambda v: _num(v) and 0 < v < 2.6, ("mapping", "max_range"): range_m,
    ("mapping", "angular_step"): angle, ("mapping", "range_noise"): non_negative,
    ("mapping", "dropout"): lambda v: _num(v) and 0 <= v < 1, ("mapping", "spacing"): positive,
    ("pose_error", "sigma_xy"): non_negative, ("pose_error", "sigma_yaw"): non_negative,
    ("pose_error", "drift_xy"): non_negative, ("pose_error", "drift_yaw"): non_negative,
    ("pose_error", "loop_closure"): optional(positive), ("label_noise", "share"): fraction,
    ("viewpoints", "budget"): range_m, ("viewpoints", "sensor_range"): range_m,
    ("viewpoints", "scan_height"): lambda v: _num(v) and 0 < v < 2.6, ("viewpoints", "scan_spacing"): positive,
    ("viewpoints", "range_noise"): non_negative, ("viewpoints", "dropout"): lambda v: _num(v) and 0 <= v < 1,
    ("viewpoints", "min_run"): positive, ("viewpoints", "max_run"): positive,
    ("run", "limit"): optional(pos_int), ("run", "progress"): one_of(True, False),
    ("run", "save_maps"): one_of(True, False), ("run", "allow_failures"): one_of(True, False),
    ("run", "cache_failures"): one_of(True, False),
    ("run", "workers"): optional(pos_int), ("run", "executor"): one_of("local", "ray"),
    ("run", "ray"): ray_settings,
}
_WHAT_EXTRA = {("viewpoints", "heading_spread"): "a number in [0, 360] degrees",
               ("mapping", "height"): "metres, 0 < height < 2.6 (below the walls)",
               ("viewpoints", "scan_height"): "metres, 0 < height < 2.6 (below the walls)",
               ("mapping", "dropout"): "a share in [0, 1)", ("viewpoints", "dropout"): "a share in [0, 1)",
               ("renderer", "fov"): "an angle in (0, 180) degrees",
               ("segmenter", "widening"): "a number >= 1"}


def _describe(group: str, key: str, rule: Rule) -> str:
    return _WHAT_EXTRA.get((group, key)) or _WHAT.get(rule) or rule.__doc__ or "a valid value"


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
            raise ConfigError(f"run.{key}={value!r}: expected {_describe('run', key, rule)}")


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
                raise ConfigError(f"{group}.{key}={value!r}: expected {_describe(group, key, rule)}")
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
