"""The YAML every job writes (``.hydra/*.yaml``, ``resolved_config.yaml``):
:func:`benchmark.config.yaml_text` gives ``OmegaConf.to_yaml``'s text, character for character,
on every option of every group ``conf/`` composes (with Hydra's own node: help templates, logging
configs) and on strings chosen where two YAML emitters could differ."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from benchmark.config import _ascii_only, _libyaml_dumper, register_resolvers, yaml_text
from benchmark.paths import CONF_DIR

CONF = Path(CONF_DIR)
GROUPS = sorted(p.name for p in CONF.iterdir() if p.is_dir() and p.name not in ("hydra", "scoring"))


def _same_text(cfg) -> str:
    want = OmegaConf.to_yaml(cfg)
    got = yaml_text(OmegaConf.to_container(cfg, enum_to_str=True))
    assert got == want
    return got


def test_every_composed_config_writes_as_omegaconf_writes_it():
    register_resolvers()
    n = 0
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        for group in GROUPS:
            for option in sorted(p.stem for p in (CONF / group).glob("*.yaml")):
                cfg = compose("config", overrides=[f"{group}={option}"], return_hydra_config=True)
                _same_text(cfg)           # the job's config with Hydra's node (hydra.yaml's content)
                _same_text(cfg.hydra)     # hydra.yaml
                _same_text(cfg.hydra.overrides.task)  # overrides.yaml
                n += 1
    assert n > 60


@pytest.mark.parametrize("value", [
    "true", "False", "yes", "off", "null", "~", "1", "-2", "1.0", "1e-05", ".inf", "0x1f", "1_000",
    "", " leading", "trailing ", "tab\there", "a: b", "- item", "#comment", "it's", 'say "hi"',
    "multi\nline\ntext", "ends with newline\n", "${paths.data_dir}/x", "{braces}", "[1, 2]", "@at", "`tick",
    "ünïcödé ✓", "日本語", "emoji 🤖", "\x07bell", "line\u2028sep", "x" * 200,
    "a long line of words " * 12, "* star", "! bang", "% percent", "& anchor", "| pipe", "> fold", "? q",
])
def test_strings_write_as_omegaconf_writes_them(value):
    cfg = OmegaConf.create({"key": value, "list": [value, {"nested": value}], value or "empty": 1})
    text = _same_text(cfg)
    assert yaml.safe_load(text)["key"] == value
    container = OmegaConf.to_container(cfg)
    if yaml.__with_libyaml__ and _ascii_only(container):  # the strings libyaml writes: as OmegaConf's dumper
        assert yaml.dump(container, default_flow_style=False, allow_unicode=True, sort_keys=False,
                         Dumper=_libyaml_dumper()) == text


def test_numbers_and_nesting_write_as_omegaconf_writes_them():
    cfg = OmegaConf.create({"f": 0.1, "g": 1e-20, "big": 10**30, "neg": -0.0, "inf": float("inf"), "b": True,
                            "n": None, "empty_list": [], "empty_dict": {}, "deep": {"a": [[1, [2, {"c": "3"}]]]},
                            "interp": "${f}", "missing": "???"})
    _same_text(cfg)


def test_libyaml_emits_where_pyyaml_has_it(monkeypatch):
    """The fast path is the one taken: libyaml's dumper (this machine's PyYAML has it)."""
    if not yaml.__with_libyaml__:
        pytest.skip("this PyYAML was built without libyaml: OmegaConf's own dumper writes")
    used = []
    real = yaml.dump
    monkeypatch.setattr(yaml, "dump", lambda data, **kw: used.append(kw["Dumper"]) or real(data, **kw))
    assert yaml_text({"a": "true"}) == "a: 'true'\n"
    assert used == [_libyaml_dumper()] and issubclass(used[0], yaml.CDumper)
    assert yaml_text({"a": ["emoji \U0001F916"]}) == "a:\n- emoji \U0001F916\n"  # not ASCII: OmegaConf's dumper
    assert used[1] is not _libyaml_dumper()
