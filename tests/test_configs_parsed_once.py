"""Hydra's YAML configs parsed once per process (benchmark.config.parse_configs_once): every
config file loads as OmegaConf.load loads it, each load is a new object, an edited file is
parsed again, and composed jobs equal those composed with Hydra's own loading."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from omegaconf import DictConfig, OmegaConf

from benchmark.config import _PARSED_CONFIGS, _ConfigsParsedOnce, compose

ROOT = Path(__file__).resolve().parents[1]


def _hydra_package_configs() -> list[Path]:
    import hydra

    return sorted((Path(hydra.__file__).parent / "conf").rglob("*.yaml"))


def _same(a, b) -> bool:
    return (type(a) is type(b) and OmegaConf.to_container(a, resolve=False) == OmegaConf.to_container(b, resolve=False)
            and OmegaConf.to_yaml(a) == OmegaConf.to_yaml(b))


def test_every_config_loads_as_omegaconf_loads_it_and_each_load_is_a_new_object():
    files = sorted((ROOT / "conf").rglob("*.yaml")) + _hydra_package_configs()
    assert len(files) > 100
    load = _ConfigsParsedOnce().load
    for f in files:
        want = OmegaConf.load(f)
        with open(f, encoding="utf-8") as fh:
            first = load(fh)
        with open(f, encoding="utf-8") as fh:
            second = load(fh)  # from the parse kept by its text
        assert _same(first, want) and _same(second, want), f
        assert first is not second
        if isinstance(first, DictConfig) and len(first):
            key = next(iter(first))
            first[key] = "changed"  # (Hydra merges into the configs it loads)
            with open(f, encoding="utf-8") as fh:
                assert _same(load(fh), want), f
    assert f.read_text(encoding="utf-8") in _PARSED_CONFIGS


def test_an_edited_config_is_parsed_again_and_a_bad_one_fails_as_before(tmp_path):
    load = _ConfigsParsedOnce().load
    f = tmp_path / "c.yaml"
    f.write_text("a: 1\nb: [x, y]\n")
    with open(f, encoding="utf-8") as fh:
        assert OmegaConf.to_container(load(fh)) == {"a": 1, "b": ["x", "y"]}
    f.write_text("a: 2\nb: [x, y]\n")
    with open(f, encoding="utf-8") as fh:
        assert OmegaConf.to_container(load(fh)) == {"a": 2, "b": ["x", "y"]}
    f.write_text("")
    with open(f, encoding="utf-8") as fh:
        assert OmegaConf.to_container(load(fh)) == {}
    f.write_text("w: [unclosed\n")
    with pytest.raises(Exception) as want:
        OmegaConf.load(f)
    with open(f, encoding="utf-8") as fh, pytest.raises(type(want.value)) as got:
        load(fh)
    assert str(got.value) == str(want.value) and str(f) in str(got.value)
    assert got.value.__context__ is None  # not raised inside the once-parse's own handler
    with pytest.raises(OSError, match="Invalid loaded object type"):
        load(io.StringIO("3\n"))  # a YAML scalar, as OmegaConf.load refuses it


@pytest.mark.parametrize("corruption", ["clean", "slam_3", "explore_2", "realistic_5", "kidnap_1"])
def test_composed_jobs_equal_those_composed_with_hydra_s_own_loading(corruption, monkeypatch):
    from hydra._internal.core_plugins import file_config_source, importlib_resources_config_source

    jobs = [["experiment=robustness", f"corruption={corruption}", f"aggregator={a}", "classifier=objects"]
            for a in ("graph_knn", "vision_cone")] + [["experiment=robustness", f"corruption={corruption}",
                                                       "segmenter=voronoi"]]
    once = [OmegaConf.to_yaml(compose(overrides=j, hydra=True)) for j in jobs]  # compose() installs it
    assert isinstance(file_config_source.OmegaConf, _ConfigsParsedOnce)
    assert isinstance(importlib_resources_config_source.OmegaConf, _ConfigsParsedOnce)
    import benchmark.config as config_mod

    monkeypatch.setattr(config_mod, "parse_configs_once", lambda: None)
    for module in (file_config_source, importlib_resources_config_source):
        monkeypatch.setattr(module, "OmegaConf", OmegaConf)
    plain = [OmegaConf.to_yaml(compose(overrides=j, hydra=True)) for j in jobs]
    assert once == plain
    assert f"    corruption: {corruption}\n" in once[0]  # (hydra.runtime.choices: the job's own option)
