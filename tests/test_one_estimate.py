"""Map and views on ONE SLAM estimate (issue 58): under `slam_k`, the robot's map is built at the
front end's estimate made from the scans its scan plane hits, and the views the method receives
must take that same estimate, not one made again from other scans. Counted: the front end runs
once per house, and the views' error is that estimate's."""

import numpy as np

from benchmark.conditions import slam as slam_module


def test_the_views_take_the_estimate_the_map_was_built_at(tmp_path, monkeypatch):
    from benchmark.config import compose_job
    from benchmark.harness.runner import run

    made = []
    original = slam_module.OdometrySlam._estimate

    def counted(self, grid, poses, house_id, spacing, obstacles=None):
        made.append((house_id, obstacles is None))
        return original(self, grid, poses, house_id, spacing, obstacles)

    monkeypatch.setattr(slam_module.OdometrySlam, "_estimate", counted)
    cfg, ch = compose_job(["env=synthetic", "env.resolution=0.1", "env.n_houses=2", "classifier=oracle",
                           "aggregator=vision_cone", "run.progress=false", f"run.results_dir={tmp_path / 'R'}",
                           "corruption=slam_2", "run.workers=1"])
    df = run(cfg, tmp_path / "R" / "jobs" / "r", ch)
    assert (df["status"] == "ok").all() and len(df) == 2
    # one estimate a house, made from the scan plane's scans (the map's), none from the route grid
    assert sorted(h for h, _ in made) == sorted(df["house_id"])
    assert not any(none for _, none in made)
    assert np.isfinite(df["ate_rmse_m"].astype(float)).all() and (df["ate_rmse_m"].astype(float) > 0).all()
