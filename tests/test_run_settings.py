"""``run`` typed like the stages: RunSettings (benchmark/harness/run_settings.py) is the schema of
the ``run:`` node of conf/config.yaml (same keys, same order, same defaults); every key's type
and range is refused in one line by check_config and, before a sweep, on the command line, with
the same words; the shipped configs pass."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from benchmark.config import compose, compose_job
from benchmark.harness.checks import ConfigError, check_config, check_run_overrides, run_keys
from benchmark.harness.run_settings import STAGES, RayAddress, RaySettings, RunSettings, StageNames
from benchmark.paths import CONF_DIR

CONF = Path(CONF_DIR)


def _yaml_run() -> dict:
    """The ``run:`` node as written in conf/config.yaml (the file, not the code under test)."""
    return OmegaConf.to_container(OmegaConf.load(CONF / "config.yaml").run, resolve=False)


def test_the_fields_are_the_keys_of_the_run_node_in_its_order():
    node = _yaml_run()
    assert [f.name for f in dataclasses.fields(RunSettings)] == list(node)
    assert [f.name for f in dataclasses.fields(RaySettings)] == list(node["ray"])
    assert run_keys() == tuple(node)


def test_the_defaults_are_those_of_the_default_config():
    """RunSettings() is the composed default ``run`` node, resolved (cache_dir: results/cache)."""
    composed = OmegaConf.to_container(compose("config").run, resolve=True)
    assert dataclasses.asdict(RunSettings()) == composed
    assert composed["cache_dir"] == "results/cache" and composed["ray"]["connect_timeout"] == 30
    check_config(compose("config"))  # and they pass


@pytest.mark.parametrize("experiment", sorted(p.stem for p in (CONF / "experiment").glob("*.yaml")))
def test_the_shipped_configs_pass(experiment):
    cfg, _ = compose_job([f"experiment={experiment}"])
    check_config(cfg)


#: (run node, the line) for every kind of key: the words a user reads.
BAD = [
    ({"name": True}, "run.name=True: expected one folder name (a string or a number; no / or \\, not starting "
                     "with a dot, at most 120 characters)"),
    ({"name": "../../x"}, "run.name='../../x': expected one folder name (a string or a number; no / or \\, not "
                          "starting with a dot, at most 120 characters)"),
    ({"label": [1]}, "run.label=[1]: expected a string or a number (read as text)"),
    ({"houses": []}, "run.houses=[]: expected a non-empty list of house ids, or null"),
    ({"houses": "h1"}, "run.houses='h1': expected a non-empty list of house ids, or null"),
    ({"limit": 0}, "run.limit=0: expected an integer >= 1, or null"),
    ({"limit": 2.5}, "run.limit=2.5: expected an integer >= 1, or null"),
    ({"force": ["bogus", "score"]}, "run.force=['bogus', 'score']: unknown stage(s) ['bogus']; expected names from "
                                    f"{list(STAGES)} or 'all'"),
    ({"force": "renders"}, "run.force='renders': unknown stage(s) ['renders']"),
    ({"force": 3}, f"run.force=3: expected a list of stage names from {list(STAGES)} or 'all', or null"),
    ({"progress": "yes"}, "run.progress='yes': expected true or false"),
    ({"save_maps": None}, "run.save_maps=None: expected true or false"),
    ({"results_dir": 3}, "run.results_dir=3: expected a string"),
    ({"cache_dir": None}, "run.cache_dir=None: expected a string"),
    ({"cache_salt": False}, "run.cache_salt=False: expected a string or a number (read as text)"),
    ({"allow_failures": 1}, "run.allow_failures=1: expected true or false"),
    ({"cache_failures": "true"}, "run.cache_failures='true': expected true or false"),
    ({"workers": 0}, "run.workers=0: expected an integer >= 1, or null"),
    ({"executor": "threads"}, "run.executor='threads': expected one of 'local', 'ray'"),
    ({"ray": "auto"}, "run.ray='auto': expected a mapping of address, connect_timeout"),
    ({"ray": {"address": "head"}}, "run.ray.address='head': expected auto, host:port or ray://host:port, or null"),
    ({"ray": {"connect_timeout": 0}}, "run.ray.connect_timeout=0: expected seconds > 0"),
    ({"ray": {"adress": "auto"}}, "run.ray.adress: unknown key (with or without +); valid keys under run.ray: "
                                  "address, connect_timeout"),
]


@pytest.mark.parametrize("node,line", BAD)
def test_a_bad_run_value_is_one_line_naming_key_value_and_what(node, line):
    with pytest.raises(ConfigError) as e:
        check_config({"run": node})
    assert str(e.value).startswith(line) and "\n" not in str(e.value)


GOOD = [{"name": 2024, "label": "", "cache_salt": 2}, {"houses": ["h1", 7], "limit": 1}, {"houses": None},
        {"force": "all"}, {"force": ["classify"]}, {"force": []}, {"force": None}, {"workers": 1, "executor": "ray"},
        {"ray": {"address": None, "connect_timeout": 0.5}}, {"ray": {"address": "auto"}},
        {"ray": {"address": "10.0.0.1:6379"}}, {"ray": {"address": "ray://head:10001"}}, {"ray": {}}]


@pytest.mark.parametrize("node", GOOD)
def test_good_run_values_pass(node):
    check_config({"run": node})


@pytest.mark.parametrize("override,line", [
    ("run.limit=0", "run.limit=0: expected an integer >= 1, or null"),
    ("run.progress=yes", "run.progress='yes': expected true or false"),  # Hydra reads yes as text
    ("run.force=[bogus]", "run.force=['bogus']: unknown stage(s) ['bogus']"),
    ("run.houses=[]", "run.houses=[]: expected a non-empty list of house ids, or null"),
    ("run.ray.address=nowhere", "run.ray.address='nowhere': expected auto, host:port or ray://host:port, or null"),
    ("run.ray.connect_timeout=-1", "run.ray.connect_timeout=-1: expected seconds > 0"),
])
def test_the_command_line_refuses_what_the_job_would_with_the_same_line(override, line):
    """Before a sweep (check_run_overrides, on the text) and in each job (check_config, on the
    composed config): the same line."""
    with pytest.raises(ConfigError) as before:
        check_run_overrides(["-m", override, "aggregator=graph_knn,vision_cone"])
    cfg, _ = compose_job([override])
    with pytest.raises(ConfigError) as job:
        check_config(cfg)
    assert str(before.value) == str(job.value) and str(job.value).startswith(line)


def test_the_command_line_leaves_sweeps_interpolations_and_other_groups_to_later():
    check_run_overrides(["-m", "run.limit=0,1", "run.workers=range(0,2)", "run.results_dir=${oc.env:HOME}/r",
                         "run.name=2024", "run.label=yes", "run.ray.address=auto", "aggregator.k=0", "~run.label"])
    with pytest.raises(ConfigError, match=r"^run.ray.foo: unknown key \(with or without \+\); valid keys under run.ray"):
        check_run_overrides(["+run.ray.foo=1"])


def test_the_markers_of_run_known_answers():
    ray = RayAddress()
    assert [ray(v) for v in ("auto", "h:1", "10.0.0.1:6379", "ray://h:10001", "[::1]:6379")] == [True] * 5
    assert [ray(v) for v in ("nowhere", "h:", ":1", "ray://", "ray://h", "h:x", "Auto", 6379, None)] == [False] * 9
    stages = StageNames(("a", "b"))
    assert [stages(v) for v in ("a", "all", ["a", "b"], [], ("b",))] == [True] * 5
    assert [stages(v) for v in ("c", ["a", "c"], [1], 3, None, {"a": 1})] == [False] * 6
    assert stages.explain(["c", "a", "d"]) == "unknown stage(s) ['c', 'd']; expected names from ['a', 'b'] or 'all'"
    assert stages.explain([1], nullable=True) == "expected a list of stage names from ['a', 'b'] or 'all', or null"
