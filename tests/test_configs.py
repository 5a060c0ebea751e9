"""Every option of every config group composes, resolves, names an importable ``_target_``
and (where that needs no simulator, weights or user files) instantiates; every experiment's
sweep names options that exist. Groups and options are read from ``conf/``, so a new option
is covered the moment its YAML file exists.
"""

from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.utils import get_class, get_method, instantiate
from omegaconf import DictConfig, ListConfig, OmegaConf

from benchmark.harness.typed import check_typed
from benchmark.paths import CONF_DIR, procthor_houses

CONF = Path(CONF_DIR)
#: groups of the bench app (conf/config.yaml's defaults list); other folders are groups of other apps.
GROUPS = sorted(p.name for p in CONF.iterdir() if p.is_dir() and p.name not in ("hydra", "scoring"))
OPTIONS = [(g, p.stem) for g in GROUPS for p in sorted((CONF / g).glob("*.yaml"))]

#: options that cannot be built here, and why (their ``_target_`` is still imported).
NOT_INSTANTIATED = {
    ("env", "procthor"): "loads ProcTHOR-10k with prior (network, git-lfs)",
    ("env", "maps"): "needs a folder of the user's maps (tests/test_maps_env.py builds one)",
    ("classifier", "cnn"): "needs a trained checkpoint",
    ("classifier", "dinov2"): "needs DINOv2 weights from the hub and a trained head",
    ("classifier", "vlm"): "needs Qwen2.5-VL weights from the hub",
    ("classifier", "labels"): "needs the user's per-view label file",
    ("segmenter", "rose2"): "needs a ROSE2 checkout (tests/test_rose2.py builds it on a stand-in package)",
    ("renderer", "images"): "needs the user's image folder",
    ("viewpoints", "file"): "needs the user's pose file",
}
NEEDS_SHARED = {("env", "procthor_shared"), ("classifier", "objects_procthor")}


def _bench_defaults() -> set[str]:
    cfg = OmegaConf.load(CONF / "config.yaml")
    out = set()
    for d in cfg.defaults:
        if isinstance(d, (dict, DictConfig)):
            for k in d:
                out.add(str(k).split(" ")[-1].split("/")[0])
    return out


def _compose(overrides: list[str], hydra_cfg: bool = False):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return compose("config", overrides=overrides, return_hydra_config=hydra_cfg)


def _targets(node) -> list[str]:
    out = []
    if isinstance(node, (dict, DictConfig)):
        for k, v in node.items():
            if k == "_target_":
                out.append(str(v))
            else:
                out += _targets(v)
    elif isinstance(node, (list, ListConfig)):
        for v in node:
            out += _targets(v)
    return out


def _locate(target: str):
    try:
        return get_class(target)
    except Exception:
        return get_method(target)


def test_groups_are_discovered():
    assert {"env", "viewpoints", "renderer", "classifier", "aggregator", "postprocess", "segmenter",
            "metrics", "experiment", "paths"} <= set(GROUPS)
    assert len(OPTIONS) >= 30


@pytest.mark.parametrize("group,option", [o for o in OPTIONS if o[0] not in ("experiment", "corruption")],
                         ids=lambda v: str(v))
def test_every_option_composes_resolves_and_builds(group, option, tmp_path, monkeypatch, request):
    monkeypatch.setenv("ROOMSEG_ARCHITECTHOR_ANNOTATIONS", str(tmp_path))
    prefix = "" if group in _bench_defaults() else "+"
    cfg = _compose([f"{prefix}{group}={option}"])
    node = cfg[group]
    plain = OmegaConf.to_container(node, resolve=True)  # every interpolation resolves
    check_typed(OmegaConf.to_container(cfg, resolve=True))  # every key is a parameter, of its type
    targets = _targets(plain)
    for t in targets:
        assert callable(_locate(t)), f"conf/{group}/{option}.yaml: _target_ {t} is not importable"
    if group in ("paths", "experiment") or not targets:
        return
    if (group, option) in NOT_INSTANTIATED:
        return
    if (group, option) in NEEDS_SHARED and not procthor_houses().exists():
        pytest.skip(f"shared data not found at {procthor_houses()}")
    if group == "classifier" and option.startswith("objects"):
        request.applymarker(pytest.mark.slow)
    if group == "segmenter" and option.startswith("ipa_"):
        # without a build the option is refused at construction in one line naming it and the
        # command that builds it (the same on every machine: an empty folder stands for no build)
        from hydra.errors import InstantiationException
        with pytest.raises(InstantiationException, match=rf"segmenter={option}: no ipa_room_segmentation build.*make ipa-env"):
            instantiate(node, env_dir=str(tmp_path / "no-ipa-env"))
        from benchmark.segmenters.ipa import ipa_build
        try:
            ipa_build(None)
        except (FileNotFoundError, ValueError):
            return  # no build on this machine (CI): construction is covered by the refusal above
    obj = instantiate(node)
    assert obj is not None and type(obj).__name__ == targets[0].rsplit(".", 1)[-1]


@pytest.mark.parametrize("option", [o for g, o in OPTIONS if g == "experiment"])
def test_every_experiment_sweeps_existing_options(option):
    cfg = _compose([f"experiment={option}"], hydra_cfg=True)
    grids = [cfg.hydra.sweeper.get("params") or {}, *(cfg.hydra.sweeper.get("grids") or [])]
    for key, values in [kv for grid in grids for kv in grid.items()]:
        if "." in key:  # a value sweep (e.g. classifier.accuracy), not a group
            continue
        for v in str(values).split(","):
            v = v.strip()
            assert (CONF / key / f"{v}.yaml").exists(), f"experiment={option}: {key}={v} is not an option of conf/{key}/"
        # the job of every combination composes
        first = str(values).split(",")[0].strip()
        job = _compose([f"experiment={option}", f"{key}={first}"])
        check_typed(OmegaConf.to_container(job, resolve=True))


def test_unknown_option_is_an_error_listing_the_options():
    from hydra.errors import ConfigCompositionException, MissingConfigException

    with pytest.raises((ConfigCompositionException, MissingConfigException), match="graph_knn"):
        _compose(["aggregator=nope"])


@pytest.mark.parametrize("option", [o for g, o in OPTIONS if g == "corruption"])
def test_every_corruption_level_composes_names_itself_and_builds(option):
    """Each severity file (conf/corruption, package _global_) composes, says its family and
    severity in ``robot`` as its name does, and every stage it sets is built."""
    cfg = _compose([f"corruption={option}"])
    check_typed(OmegaConf.to_container(cfg, resolve=True))
    family, _, level = option.rpartition("_")
    if option == "clean":
        family, level = "clean", "0"
    assert cfg.robot.corruption == family and cfg.robot.severity == int(level)
    for group in ("mapping", "pose_error", "label_noise", "viewpoints"):
        node = cfg.get(group)
        if node is not None:
            assert type(instantiate(node)).__name__ == node._target_.rsplit(".", 1)[-1]
    if option != "clean":
        assert any(cfg.get(g) is not None for g in ("mapping", "pose_error", "label_noise")) or \
            cfg.viewpoints._target_.endswith("Frontier")


ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_help_lists_only_the_groups_the_app_accepts():
    """``roomseg-bench --help`` lists the bench app's groups with their options, not the scoring
    app's ``external`` group (conf/scoring/), which the bench app refuses."""
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "--help"], cwd=ROOT, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0
    groups = {line.split(":")[0] for line in r.stdout.splitlines() if ": " in line and not line.startswith(" ")}
    assert {"aggregator", "classifier", "corruption", "mapping", "segmenter", "viewpoints"} <= groups
    assert not any("external" in g or g.startswith("scoring") for g in groups)
    segmenters = ", ".join(sorted(p.stem for p in (CONF / "segmenter").glob("*.yaml")))  # every option, sorted
    assert f"segmenter: {segmenters}" in r.stdout and "ipa_vrf" in segmenters
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "external=selros"], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2  # the group it does not list is one it refuses


@pytest.mark.parametrize("option", sorted(p.stem for p in (CONF / "scoring" / "external").glob("*.yaml")))
def test_every_scoring_preset_composes_with_the_shared_groups(option):
    """The scoring app's own folder (conf/scoring) finds the shared groups (paths, metrics) in
    conf/ through the search path; each external preset composes and names its target."""
    from benchmark.config import compose

    cfg = compose("score", [f"external={option}"])
    assert cfg.external._target_ == "benchmark.baselines.external.ExternalMethod"
    assert cfg.metrics._target_ == "benchmark.metrics.MetricParams" and "selros" in str(cfg.paths.selros_dir)
