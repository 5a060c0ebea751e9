"""The robustness benchmark end to end (issue 26): ``experiment=robustness`` composes and runs
on 2 houses with 2 severities per family (a cut-down method list), and the robustness command
writes its tables (Markdown, CSV, LaTeX) and a colour-blind safe figure per family."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
LEVELS = "clean,scan_1,scan_2,pose_1,pose_2,explore_1,explore_2,classifier_1,classifier_2,realistic_1,realistic_2"


@pytest.mark.slow
def test_robustness_experiment_runs_and_summarises(tmp_path):
    results = tmp_path / "R"
    sweep = subprocess.run(
        [sys.executable, "-m", "benchmark.commands.bench", "experiment=robustness", "env=synthetic", "run.limit=2",
         "env.resolution=0.1", f"run.results_dir={results}", f"hydra.sweeper.params.corruption='{LEVELS}'",
         "hydra.sweeper.params.aggregator='vision_cone,graph_knn'", "hydra.sweeper.params.classifier=oracle",
         "hydra.sweeper.grids.0.segmenter='voronoi,one_room'", f"hydra.sweeper.grids.0.corruption='{LEVELS}'",
         "run.save_maps=true"],  # the experiment keeps none (test below); the report's maps need them
        cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=900)
    assert sweep.returncode == 0, sweep.stderr[-2000:]
    assert "44 jobs, 88 rows, 0 failed" in sweep.stdout
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.robustness", str(results / "runs" / "robustness"),
                        "--out", str(out)], cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    for metric in ("iou", "matched_iou", "pq"):
        t = pd.read_csv(out / f"robustness_synthetic_{metric}.csv", index_col="method")
        assert set(t.index) == {"voronoi", "one_room", "oracle@0.8+vision_cone +post", "oracle@0.8+graph_knn +post"}
        ce = [c for c in t.columns if c.startswith("CE ") and not c.endswith((" lo", " hi"))]
        if metric == "iou":
            assert ce == [] and "mCE" not in t  # the paper's IoU rewards shrinking maps: no mCE on it
        else:  # CE relative to a method every family degrades (Voronoi is untouched by pose, labels, views)
            assert {"mCE", "mCE lo", "mCE hi", "rel mCE", "CE realistic"} <= set(t.columns)
            assert (t[["clean lo", "clean hi"]].notna()).all().all()
        assert (out / f"robustness_synthetic_{metric}.tex").read_text().startswith(r"\begin{table*}")  # wide: every column with its interval
    # geometry ignores poses and labels: its score is the clean one there; under exploration it
    # gets the explorer's own map, like every method
    t = pd.read_csv(out / "robustness_synthetic_iou.csv", index_col="method")
    for fam in ("pose", "classifier"):
        assert t.loc["voronoi", fam] == pytest.approx(t.loc["voronoi", "clean"])
    assert t.loc["voronoi", "explore"] != pytest.approx(t.loc["voronoi", "clean"])
    assert t.loc["oracle@0.8+vision_cone +post", "drop classifier"] > 0
    for fam in ("scan", "pose", "explore", "classifier", "realistic"):
        for ext in ("png", "pdf"):
            assert (out / "figures" / f"robustness_synthetic_iou_{fam}.{ext}").stat().st_size > 1000
    md = (out / "robustness.md").read_text()
    assert "relative to a method every family degrades" in md and "| scan | 2 | mapping=scan; mapping.route explore; mapping.max_range 8.0;" in md
    assert "## How many houses" in md and "Reference: " in md
    assert "2 houses per cell." in md
    # the sweep report has a robustness section: the matched IoU table (the same numbers) and a figure per family
    from benchmark.reports.html_report import build_report

    page = build_report([results / "runs" / "robustness"])
    # the page leads with the robustness summary; the configurations follow, with the robot
    # condition and severity in columns of their own and selects that filter by them
    assert page.index('id="robustness"') < page.index('id="configurations"') < page.index('id="configs"')
    configs = page[page.index('id="config-filters"'):]
    configs = configs[:configs.index("</table>")]
    assert ">robot condition</th>" in configs and '<th class="num">severity</th>' in configs
    for words in ("scan map", "views-only pose noise, perfect map (ablation)", "exploration budget", "classifier noise",
                  "realistic (all combined)"):
        assert f">{words}</option>" in configs and f"<td>{words}</td>" in configs
    assert configs.count('data-condition="scan" data-severity="2"') == 4  # 4 methods at scan severity 2
    assert configs.count("<tr data-condition=") == 44 and "44 of 44 configurations" in configs
    section = page[page.index('id="robustness"'):page.index('id="configurations"')]
    assert section.count("<img ") == 5 and "IoU vs severity: scan map" in section
    t = pd.read_csv(out / "robustness_synthetic_matched_iou.csv", index_col="method")
    row = section[section.index("<td>voronoi</td>"):]
    assert f'>{t.loc["voronoi", "clean"]:.1f}<br><small class="muted">[' in row[:row.index("</tr>")]
    assert section.count("<tr><td>") == 4  # one row per method
    # its maps are the clean condition's: one group per method, not one per condition
    assert page.count("<figcaption>ground truth</figcaption>") == 2 * 4  # 2 houses x 4 methods


def test_the_robustness_sweep_keeps_no_label_maps_unless_asked():
    """888 jobs x 200 houses of label maps are gigabytes the tables never read: the experiment
    sets run.save_maps false; run.save_maps=true (as above) keeps them for the report and figures."""
    from benchmark.config import compose_job

    cfg, _ = compose_job(["experiment=robustness", "hydra.mode=RUN"])
    assert cfg.run.save_maps is False
    cfg, _ = compose_job(["experiment=robustness", "hydra.mode=RUN", "run.save_maps=true"])
    assert cfg.run.save_maps is True
