"""A render cache made elsewhere (a GPU box with AI2-THOR) is swept here without the simulator:
image classifier on the cached frames, refused views left out."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from hydra import compose, initialize_config_dir  # noqa: E402
from hydra.utils import instantiate  # noqa: E402

from benchmark.harness.runner import CONF_DIR, build_pipeline, run  # noqa: E402
from envs.render.cache import write_observations  # noqa: E402
from envs.render.observation import Observation  # noqa: E402


def test_sweep_from_a_copied_ai2thor_render_cache(tmp_path):
    from benchmark.classifiers.cnn import build_resnet
    from benchmark.classifiers.torch_common import save_checkpoint

    classes = ["balcony", "bathroom", "bedroom", "corridor", "dining_room", "kitchen", "living_room"]
    torch.manual_seed(0)
    save_checkpoint(tmp_path / "cnn.pt", build_resnet("resnet18", 7, pretrained=False), classes)
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=[
            "env=synthetic", "env.n_houses=1", "env.resolution=0.1", "renderer=ai2thor", "classifier=cnn",
            f"classifier.checkpoint={tmp_path / 'cnn.pt'}", "classifier.arch=resnet18", "classifier.pretrained=false",
            "classifier.image_size=32", "classifier.device=cpu", "aggregator=graph_knn", "postprocess=none",
            f"run.results_dir={tmp_path / 'results'}", "run.progress=false"], return_hydra_config=True)
    choices = {k: str(v) for k, v in cfg.hydra.runtime.choices.items() if not k.startswith("hydra")}
    env = instantiate(cfg.env)
    hid = env.house_ids()[0]
    poses = instantiate(cfg.viewpoints).generate(env.scene(hid))
    rng = np.random.default_rng(0)
    obs = [Observation(pose=tuple(p), image=rng.integers(0, 256, (32, 32, 3), dtype=np.uint8),
                       objects=[("Sofa", 0.2)]) for p in poses]
    obs[3] = Observation(pose=tuple(poses[3]), meta={"refused": True, "error": "not reachable"})
    folder = build_pipeline(cfg, choices).entry("render", hid)  # where the run store keeps this house's render
    assert folder.is_relative_to(tmp_path / "results" / "cache" / "render")
    write_observations(folder, obs)  # "copied from the GPU box"
    df = run(cfg, tmp_path / "out", choices)  # ai2thor is never started: the render is cached
    row = df.iloc[0]
    assert row["status"] == "ok", row["error"]
    assert row["n_views"] == len(poses) - 1 and row["n_refused"] == 1
    assert row["renderer"] == "ai2thor" and row["classifier"] == "cnn"
    assert 0.0 <= row["iou"] <= 1.0
