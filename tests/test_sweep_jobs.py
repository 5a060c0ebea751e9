"""issue 38 item 1: a sweep whose jobs did not all finish is named, with its missing jobs, by the
tables, the report and the robustness summary (they read 2 of 4 jobs silently before), and a
robot-condition family with a severity missing for every method is left out of the summary,
named (the old check compared methods with each other, so it passed)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from benchmark.reports.sweep_jobs import expected_jobs, missing_jobs, partial_sweep_lines

MULTIRUN = """hydra:
  overrides:
    task:
    - env=synthetic
    - run.limit=2
  sweeper:
    params:
      corruption: clean,scan_1,scan_2
      aggregator: vision_cone
    grids:
    - segmenter: voronoi
      corruption: clean,scan_1,scan_2
"""


def _sweep(root: Path, skip: tuple[str, ...] = ()) -> Path:
    """A hand-made robustness sweep on two houses: 6 jobs (vision cone and Voronoi x clean,
    scan_1, scan_2), each a finished job folder unless its corruption is in ``skip`` (then it
    keeps its folder and config, but no metrics: stopped, or its file removed)."""
    sweep = root / "runs" / "robustness"
    sweep.mkdir(parents=True)
    (sweep / "multirun.yaml").write_text(MULTIRUN)
    for method in ("aggregator=vision_cone", "segmenter=voronoi"):
        for corruption in ("clean", "scan_1", "scan_2"):
            job = sweep / f"{method},corruption={corruption}"
            (job / ".hydra").mkdir(parents=True)
            (job / ".hydra" / "overrides.yaml").write_text(
                f"- {method}\n- corruption={corruption}\n- env=synthetic\n- run.limit=2\n")
            (job / "resolved_config.yaml").write_text("run: {name: robustness}\n")
            (job / "summary.json").write_text(json.dumps({"n_houses": 2, "names": {}, "keys": {}, "contents": {}}))
            if corruption in skip:
                continue
            fam, sev = (corruption.split("_") + ["0"])[:2] if corruption != "clean" else ("clean", "0")
            seg = method.endswith("voronoi")
            pd.DataFrame({"house_id": ["h1", "h2"], "dataset": "synthetic", "classifier": "" if seg else "oracle",
                          "aggregator": "" if seg else "vision_cone", "postprocess": "default",
                          "segmenter": "voronoi" if seg else "", "corruption": fam, "severity": int(sev),
                          "status": "ok", "iou": [0.5, 0.6], "matched_iou": [0.4, 0.5], "pq": [0.3, 0.4],
                          "precision": 0.5, "recall": 0.5}).to_csv(job / "metrics.csv", index=False)
    return sweep


def test_expected_jobs_come_from_the_sweep_description(tmp_path):
    sweep = _sweep(tmp_path)
    jobs = expected_jobs(sweep)
    assert len(jobs) == 6 and ("aggregator=vision_cone", "corruption=scan_2", "env=synthetic", "run.limit=2") in jobs
    assert missing_jobs(sweep) == (6, [])
    assert partial_sweep_lines([sweep]) == []
    assert expected_jobs(tmp_path) is None  # no multirun.yaml: nothing to compare with


@pytest.mark.slow
def test_unfinished_jobs_are_named_by_tables_report_and_robustness(tmp_path, capsys):
    sweep = _sweep(tmp_path, skip=("scan_2",))
    (line,) = partial_sweep_lines([sweep])
    assert line == (f"sweep {sweep.resolve()}: 4 of 6 jobs finished; missing: aggregator=vision_cone, "
                    "corruption=scan_2; corruption=scan_2, segmenter=voronoi (their rows are in no table: rerun "
                    "the sweep to finish them)")
    from benchmark.commands.tables import main as tables

    assert tables([str(sweep), "--table", "all"]) == 0
    out, err = capsys.readouterr()
    assert "4 of 6 jobs finished" in err and "Note: sweep" in out and "4 of 6 jobs finished" in out
    from benchmark.reports.html_report import build_report

    assert '<p class="err">Partial sweep: sweep ' in build_report([sweep])
    from benchmark.commands.robustness import main as robustness

    assert robustness([str(sweep)]) == 0
    out, err = capsys.readouterr()
    assert "4 of 6 jobs finished" in err and "**Partial sweep**" in out
    # scan_2, the top severity, is gone for every method: the scan family is left out, named
    assert "scan map left out of the summary: severity 2 has no rows for any method" in out
    assert "| scan |" not in out.split("## Severities")[0]


@pytest.mark.slow
def test_a_severity_missing_for_all_methods_in_a_published_copy_is_caught_from_the_rows(tmp_path, capsys):
    """No multirun.yaml (a published copy): a gap in the middle of a family is still caught."""
    sweep = _sweep(tmp_path)
    (sweep / "multirun.yaml").unlink()
    for job in sweep.glob("*scan_1"):
        df = pd.read_csv(job / "metrics.csv")
        df["severity"] = 3  # the family now holds severities 2 and 3 only
        df.to_csv(job / "metrics.csv", index=False)
    from benchmark.commands.robustness import main as robustness

    assert robustness([str(sweep)]) == 0
    out = capsys.readouterr().out
    assert "scan map left out of the summary: severity 1 has no rows for any method" in out


def test_overrides_files_read_as_omegaconf_reads_them(tmp_path):
    """A finished job's overrides are the strings Hydra wrote (read with PyYAML's safe loader,
    libyaml's: the same as OmegaConf.load on values that quote, hold paths, spaces, braces,
    numbers and non-ASCII); a file that is no YAML list counts as missing."""
    from omegaconf import OmegaConf

    from benchmark.config import yaml_text
    from benchmark.reports.sweep_jobs import _finished

    sweep = _sweep(tmp_path)
    tricky = ["corruption=clean", "env=synthetic", "run.label='a b: c'", "run.houses=[h1,h2]", "run.limit=2",
              "paths.data_dir=/data/ünï code", "+x={a: 1}", "y=1e-5", "z=true", "w=\"q\"", "~run.force"]
    job = sweep / "aggregator=vision_cone,corruption=clean"
    (job / ".hydra" / "overrides.yaml").write_text(yaml_text(OmegaConf.to_container(OmegaConf.create(tricky))),
                                                   encoding="utf-8")
    bad = sweep / "aggregator=vision_cone,corruption=scan_1"
    (bad / ".hydra" / "overrides.yaml").write_text("a: 1\n")
    got = _finished(sweep)
    want = {tuple(sorted(str(x) for x in OmegaConf.load(f))) for f in sweep.glob("*/.hydra/overrides.yaml")
            if f.parent.parent != bad}
    assert got == want and tuple(sorted(tricky)) in got and len(got) == 5
