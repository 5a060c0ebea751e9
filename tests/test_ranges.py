"""Value ranges next to the classes (envs/ranges.py, read by benchmark/harness/typed.py): a stage
says the range of a setting on its parameter (``window: Annotated[int, Odd()]``); the config
check refuses a value out of it in one line naming group.key, the value and the range; the
shipped configs pass; and the far-away table of checks.py is gone (``run``, the one node that is
not a stage's, is typed by a dataclass the same way: tests/test_run_settings.py)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import pytest
import yaml
from omegaconf import OmegaConf

import benchmark.harness.checks as checks
from benchmark.config import compose, compose_job
from benchmark.harness.checks import ConfigError
from benchmark.harness.run_settings import RunSettings
from benchmark.harness.typed import _signature, check_targets, check_typed, settings_params
from benchmark.paths import CONF_DIR
from envs.ranges import (
    CAMERA_FOV,
    DROPOUT,
    Angle,
    Between,
    Integer,
    LowHigh,
    Metres,
    NonEmpty,
    NonNegative,
    Odd,
    OneOf,
    Positive,
    Seconds,
    Share,
    Text,
)

CONF = Path(CONF_DIR)


def _yaml_targets() -> dict[str, set[str]]:
    """group -> the ``_target_`` classes of its options (top-level nodes of ``conf/<group>/*.yaml``)."""
    out: dict[str, set[str]] = {}
    for f in sorted(CONF.glob("*/*.yaml")):
        node = yaml.safe_load(f.read_text()) or {}
        if isinstance(node, dict) and isinstance(node.get("_target_"), str):
            out.setdefault(f.parent.name, set()).add(node["_target_"])
    return out


# ------------------------------------------------------------------ the markers, known answers
@pytest.mark.parametrize("marker,good,bad", [
    (Positive(), [1e-9, 3, 1e9], [0, -1, math.inf, math.nan, True, "1", None]),
    (NonNegative(), [0, 0.0, 2.5], [-1e-9, -math.inf, math.inf, math.nan, False]),
    (Share(), [0, 0.5, 1], [-0.01, 1.01, math.nan, True]),
    (Angle(), [1e-6, 90, 360], [0, 360.001, -90, math.inf]),
    (CAMERA_FOV, [1, 179.9], [0, 180, 200]),
    (DROPOUT, [0, 0.999], [1, 1.0, -0.1]),
    (Metres(inf_ok=True), [0.1, math.inf], [0, -math.inf, math.nan, -1]),
    (Metres(), [0.1], [0, math.inf]),
    (Between(1, what="a number >= 1"), [1, 1.25], [0.999, math.inf]),
    (Integer(0), [0, 7], [-1, 1.0, True, "3", None]),
    (Integer(1), [1, 2], [0, 1.5]),
    (Odd(), [1, 3, 5, 101], [0, 2, 4, -1, 5.0, True]),
    (OneOf(4, 8), [4, 8], [6, "4", True]),
    (OneOf("ros", "sim"), ["ros", "sim"], ["Ros", None, 1]),
    (OneOf(True, False), [True, False], [1, 0]),
    (LowHigh(), [[1, 2], (2.0, 2.0)], [[2, 1], [0, 1], [1], [1, 2, 3], "ab", [1, math.inf], 3]),
    (Seconds(), [0.5, 30], [0, -1, math.inf, math.nan, True, "30"]),
    (Text(), ["", "x", 2024, 1.5], [True, None, [1], {"a": 1}, math.nan, math.inf]),
    (NonEmpty(), [[1], ("a", "b")], [[], (), "ab", None, 3, {"a": 1}]),
])
def test_markers_accept_the_range_and_refuse_the_rest(marker, good, bad):
    assert [marker(v) for v in good] == [True] * len(good)
    assert [marker(v) for v in bad] == [False] * len(bad)


def test_the_words_of_the_markers():
    assert [m.what for m in (Positive(), NonNegative(), Share(), Integer(1), Odd(), Angle(), Metres(inf_ok=True),
                             OneOf("a", "b"), LowHigh(), Between(0, 2, low_open=True), Between(1), Seconds(),
                             Text(), NonEmpty("house ids"))] == [
        "a number > 0", "a number >= 0", "a number in [0, 1]", "an integer >= 1", "an odd integer >= 1",
        "an angle in (0, 360] degrees", "metres > 0 (.inf: unlimited)", "one of 'a', 'b'",
        "[low, high] with 0 < low <= high", "a number in (0, 2]", "a number >= 1", "seconds > 0",
        "a string or a number (read as text)", "a non-empty list of house ids"]
    assert Odd().explain(4) == "expected an odd integer >= 1"
    assert Integer(1).explain(0, nullable=True) == "expected an integer >= 1, or null"


# ------------------------------------------------------------------ (a) the shipped defaults pass
#: every (group, key) the old table of checks.py held for a stage group, now said on the classes.
MOVED = {
    "env": "resolution wall_thickness clearance max_object_base n_houses seed_start start stop open_plan_share length "
           "depth reachable image_preset free_thresh occupied_thresh max_map_pixels poses_frame",
    "viewpoints": "offset spacing n_headings heading_spread min_contour off_map budget sensor_range scan_height "
                  "scan_spacing range_noise dropout min_run max_run",
    "renderer": "fov max_range occluder_height width height grid_size min_share",
    "classifier": "accuracy alpha batch_size image_size train_start train_stop",
    "aggregator": "k connectivity weighting fov max_range_m blocked_ray_m window vote ray_density",
    "postprocess": "target_resolution window iterations min_area dp_tolerance",
    "metrics": "match connectivity min_segment_m2 min_colour_m2 instances",
    "segmenter": "min_seed_area min_room_area max_area step max_door window widening",
    "mapping": "height max_range angular_step range_noise dropout spacing",
    "pose_error": "sigma_xy sigma_yaw drift_xy drift_yaw loop_closure",
    "label_noise": "share",
}


@pytest.mark.parametrize("group", sorted(MOVED))
def test_every_moved_key_has_a_range_on_each_class_of_its_group_that_takes_it(group):
    """Each key of the old table has a range on every class of ``conf/<group>`` that takes it
    (and at least one class does): nothing was lost in the move."""
    sigs = {t: _signature(t) for t in _yaml_targets()[group]}
    assert all(s is not None for s in sigs.values()), sigs
    for key in MOVED[group].split():
        takers = {t: s[0][key] for t, s in sigs.items() if key in s[0]}
        assert takers, f"{group}.{key}: no class of conf/{group} takes it"
        unranged = [t for t, p in takers.items() if not p.ranges]
        assert not unranged, f"{group}.{key}: no range on {unranged}"


def test_the_signature_defaults_are_in_their_ranges():
    """A class's own default of a ranged parameter is in the range (the config's may differ)."""
    import dataclasses
    import importlib
    import inspect

    seen = 0
    for targets in _yaml_targets().values():
        for t in sorted(targets):
            sig = _signature(t)
            if sig is None:
                continue
            module, _, name = t.rpartition(".")
            obj = getattr(importlib.import_module(module), name)
            defaults = {p.name: p.default for p in inspect.signature(obj).parameters.values()}
            settings = getattr(obj, "SETTINGS", None)
            if dataclasses.is_dataclass(settings):
                defaults |= {f.name: f.default for f in dataclasses.fields(settings)}
            for key, param in sig[0].items():
                d = defaults.get(key, inspect.Parameter.empty)
                if not param.ranges or d is inspect.Parameter.empty or (d is None and param.nullable):
                    continue
                d = list(d) if isinstance(d, tuple) else d
                assert all(r(d) for r in param.ranges), f"{t}.{key} = {d!r}: outside {param.ranges}"
                seen += 1
    assert seen >= 100  # 113 ranged parameters of the shipped classes, 5 of them null by default


def _options() -> list[list[str]]:
    groups = sorted(p.name for p in CONF.iterdir() if p.is_dir() and p.name not in ("hydra", "scoring", "experiment"))
    bench = {str(k).split(" ")[-1].split("/")[0] for d in OmegaConf.load(CONF / "config.yaml").defaults
             if isinstance(d, dict) or OmegaConf.is_dict(d) for k in d}
    return [[f"{'' if g in bench else '+'}{g}={f.stem}"] for g in groups for f in sorted((CONF / g).glob("*.yaml"))]


@pytest.mark.slow
def test_every_shipped_option_passes_its_ranges():
    """Each option of each group of conf/ (robot conditions included), composed into the bench
    config, and the roomseg-segment defaults pass the types and ranges of their classes; the
    ranged parameters they set are counted, so that the check cannot pass by seeing none."""
    checked = 0
    for overrides in _options():
        plain = OmegaConf.to_container(compose_job(overrides)[0], resolve=True)
        check_typed(plain)
        for node in plain.values():
            sig = _signature(node["_target_"]) if isinstance(node, dict) and isinstance(node.get("_target_"), str) else None
            checked += sum(1 for k in node if sig and k in sig[0] and sig[0][k].ranges)
    check_typed(OmegaConf.to_container(compose("segment"), resolve=True), "segment")
    assert checked >= 500, checked


# ------------------------------------------------------------------ (b) bad values: one line
@pytest.mark.parametrize("overrides,line", [
    (["aggregator=vision_cone", "aggregator.window=4"], "aggregator.window=4: expected an odd integer >= 1"),
    (["aggregator.k=0"], "aggregator.k=0: expected an integer >= 1"),
    (["aggregator.k=null"], "aggregator.k=None: expected an integer >= 1"),
    (["aggregator.connectivity=6"], "aggregator.connectivity=6: expected one of 4, 8"),
    (["postprocess.window=4"], "postprocess.window=4: expected an odd integer >= 1"),
    (["segmenter=voronoi", "segmenter.widening=0.5"], "segmenter.widening=0.5: expected a number >= 1"),
    (["env.length=[14,9]"], "env.length=[14, 9]: expected [low, high] with 0 < low <= high"),
    (["env.open_plan_share=1.5"], "env.open_plan_share=1.5: expected a number in [0, 1]"),
    (["renderer.fov=180"], "renderer.fov=180: expected an angle in (0, 180) degrees"),
    (["renderer.max_range=inf"], "renderer.max_range=inf: expected a number > 0"),
    (["renderer.max_range=nan"], "renderer.max_range=nan: expected a number > 0"),
    (["classifier=oracle", "classifier.accuracy=1.5"], "classifier.accuracy=1.5: expected a number in [0, 1]"),
    (["metrics.match=area"], "metrics.match='area': expected one of 'iou', 'overlap'"),
    (["viewpoints.heading_spread=400"], "viewpoints.heading_spread=400: expected a number in [0, 360] degrees"),
    (["corruption=explore_3", "viewpoints.dropout=1.0"], "viewpoints.dropout=1.0: expected a share in [0, 1)"),
    (["corruption=scan_3", "mapping.height=3.0"],
     "mapping.height=3.0: expected metres, 0 < height < 2.6 (below the walls)"),
    (["corruption=scan_3", "mapping.max_range=0"], "mapping.max_range=0: expected metres > 0 (.inf: unlimited)"),
    (["corruption=pose_3", "pose_error.loop_closure=0"], "pose_error.loop_closure=0: expected a number > 0, or null"),
    (["corruption=classifier_3", "label_noise.share=-0.1"], "label_noise.share=-0.1: expected a number in [0, 1]"),
])
def test_a_value_out_of_range_is_one_line_naming_key_value_and_range(overrides, line):
    with pytest.raises(ConfigError) as e:
        check_typed(OmegaConf.to_container(compose_job(overrides)[0], resolve=True))
    assert str(e.value) == line


@pytest.mark.parametrize("overrides", [
    ["corruption=scan_3", "mapping.max_range=inf"],  # an unlimited scanner
    ["corruption=pose_3", "pose_error.loop_closure=null"],  # null where the type admits it
    ["aggregator=vision_cone", "aggregator.window=1", "aggregator.fov=360"],  # the closed ends
    ["env.open_plan_share=0", "env.length=[9,9]"],
])
def test_values_at_the_ends_of_a_range_pass(overrides):
    check_typed(OmegaConf.to_container(compose_job(overrides)[0], resolve=True))


def test_mapping_keys_are_those_of_its_settings_dataclass():
    """ScanMapping takes ``**settings`` (envs.maps.scan.ScanSettings): its keys, types and ranges
    are the dataclass's, so a misspelt key is refused before any work, not at its build."""
    with pytest.raises(ConfigError, match=r"^mapping.heigth: unknown key, not a parameter of envs.maps.mapping.ScanMapping "
                                          r"\(valid: route, height, max_range, .*\); did you mean 'height'\?$"):
        check_targets({"mapping": {"_target_": "envs.maps.mapping.ScanMapping", "heigth": 0.3}})
    with pytest.raises(ConfigError, match=r"^mapping.seed='x': expected an integer \(the type of ScanMapping's seed\)$"):
        check_targets({"mapping": {"_target_": "envs.maps.mapping.ScanMapping", "seed": "x"}})
    with pytest.raises(ConfigError, match=r"^mapping.route='everywhere': expected one of 'views', 'explore'$"):
        check_targets({"mapping": {"_target_": "envs.maps.mapping.ScanMapping", "route": "everywhere"}})


# ------------------------------------------------------------------ a user's own stage
class MyAggregator:
    """A user's stage: its ranges are its annotations, nothing to register."""

    def __init__(self, window: Annotated[int, Odd()] = 5, radius_m: Annotated[float, Positive()] = 1.0,
                 start: Annotated[int | None, Integer(0)] = None, note: str = ""):
        self.window, self.radius_m, self.start, self.note = window, radius_m, start, note


@dataclass(frozen=True)
class MySettings:
    share: Annotated[float, Share()] = 0.5
    steps: int = 3


class MyMapper:
    SETTINGS = MySettings

    def __init__(self, **settings):
        self.settings = MySettings(**settings)


@pytest.mark.parametrize("node,line", [
    ({"window": 4}, "aggregator.window=4: expected an odd integer >= 1"),
    ({"window": 5, "radius_m": -1.0}, "aggregator.radius_m=-1.0: expected a number > 0"),
    ({"start": -2}, "aggregator.start=-2: expected an integer >= 0, or null"),
    ({"window": "5"}, "aggregator.window='5': expected an integer (the type of MyAggregator's window)"),
])
def test_a_users_own_stage_gets_its_ranges_checked(node, line):
    target = f"{__name__}.MyAggregator"
    with pytest.raises(ConfigError) as e:
        check_targets({"aggregator": {"_target_": target, **node}})
    assert str(e.value) == line
    check_targets({"aggregator": {"_target_": target, "window": 7, "radius_m": 0.5, "start": None, "note": "x"}})
    with pytest.raises(ConfigError, match=r"^mapping.share=2: expected a number in \[0, 1\]$"):
        check_targets({"mapping": {"_target_": f"{__name__}.MyMapper", "share": 2}})
    with pytest.raises(ConfigError, match="did you mean 'steps'"):
        check_targets({"mapping": {"_target_": f"{__name__}.MyMapper", "step": 2}})


# ------------------------------------------------------------------ (c) the old table is gone
def test_no_rules_table_is_left_and_run_is_typed_by_its_dataclass():
    """The ranges of ``run`` are annotations on RunSettings' fields, read by the same check as a
    stage's parameters; checks.py keeps no table of its own (a stage's rule cannot go back there)."""
    assert not hasattr(checks, "RULES") and not hasattr(checks, "_WHAT")
    params = settings_params(RunSettings)
    assert params["limit"].ranges == (Integer(1),) and params["limit"].nullable
    assert params["workers"].ranges == (Integer(1),)
    assert params["executor"].ranges == (OneOf("local", "ray"),) and not params["executor"].nullable
    with pytest.raises(ConfigError, match=r"^run.limit=0: expected an integer >= 1, or null$"):
        checks.check_config({"run": {"limit": 0}})
