"""A job's config body resolved to a plain container (benchmark.config.resolved_body): the same
container as the masked copy without Hydra's node gives, with or without that node; a config
without it (what a Hydra app's job receives) is resolved without being copied."""

from __future__ import annotations

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from benchmark.config import register_resolvers, resolved_body
from benchmark.paths import CONF_DIR


def _reference(cfg):
    return OmegaConf.to_container(OmegaConf.masked_copy(cfg, [k for k in cfg if k != "hydra"]), resolve=True)


@pytest.mark.parametrize("overrides", [[], ["experiment=robustness", "corruption=realistic_3"],
                                       ["corruption=slam_2", "segmenter=voronoi"], ["run.results_dir=/tmp/r x"]])
def test_the_body_is_the_masked_copy_resolved(overrides, monkeypatch):
    register_resolvers()
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        full = compose("config", overrides=overrides, return_hydra_config=True)
    want = _reference(full)
    assert "hydra" not in want and want["run"]["cache_dir"] == want["run"]["results_dir"] + "/cache"
    assert resolved_body(full) == want
    task = OmegaConf.masked_copy(full, [k for k in full if k != "hydra"])  # a job's config: no hydra node
    monkeypatch.setattr(OmegaConf, "masked_copy", lambda *a, **k: pytest.fail("copied a config with no hydra node"))
    assert resolved_body(task) == want
