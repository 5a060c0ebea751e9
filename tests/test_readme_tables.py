"""README results blocks: written by `make readme-tables` from the committed published runs;
the test fails when the README says anything else (a number changed by hand included)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from benchmark.reports import readme_tables as rt

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_readme_blocks_are_what_make_readme_tables_writes():
    found = {}
    for f in rt.BLOCK_FILES:  # the README, and the docs pages that hold the blocks too long for it
        found.update(rt.blocks_in((ROOT / f).read_text(encoding="utf-8")))
        changed = rt.check(ROOT / f, ROOT)
        assert changed == [], (f"{f}: block(s) {changed} differ from the published runs in results/published/: "
                               "run `make readme-tables` (after `make bench-publish` for fresh numbers)")
    assert set(rt.BLOCKS) == set(found)  # every block is written somewhere
    readme = rt.blocks_in((ROOT / "README.md").read_text(encoding="utf-8"))
    assert {"bench-timing", "bench-table4", "robustness-timing", "robustness-power"} <= set(readme)


@pytest.mark.slow
def test_a_number_changed_by_hand_is_caught():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    body = rt.blocks_in(text)["bench-table4"]
    i = next(k for k, ch in enumerate(body) if ch.isdigit() and body[k - 1] == " ")
    edited = body[:i] + str((int(body[i]) + 1) % 10) + body[i + 1:]
    new_text = text.replace(body, edited, 1)
    assert new_text != text
    fixed, changed = rt.update_text(new_text, ROOT)
    assert changed == ["bench-table4"]
    assert fixed == text  # writing the blocks restores the published numbers


def _hand_run(root: Path) -> Path:
    run = root / "runs" / "demo"
    for agg, iou in (("graph_knn", (0.2, 0.4)), ("vision_cone", (0.6, 0.8))):
        d = run / f"aggregator={agg}"
        d.mkdir(parents=True)
        pd.DataFrame({"house_id": ["a", "b"], "dataset": "synthetic", "classifier": "oracle", "oracle_accuracy": 0.8,
                      "aggregator": agg, "postprocess": "default", "segmenter": "", "status": "ok", "error": "",
                      "iou": iou, "accuracy": (0.5, 0.7), "t_score": (0.01, 0.02)}).to_csv(d / "metrics.csv",
                                                                                       index=False)
        (d / "summary.json").write_text(json.dumps({"n_houses": 2, "names": {}}))
        (d / "resolved_config.yaml").write_text("run: {name: demo}\n")
    return run


def test_publish_then_write_a_block(tmp_path, monkeypatch):
    run = _hand_run(tmp_path)
    (tmp_path / "time.txt").write_text("Command exited with non-zero status 0\n61.27 349184\n")
    dest = rt.publish(run, "bench", tmp_path, tmp_path / "time.txt")
    assert dest == tmp_path / "results" / "published" / "bench"
    cols = pd.read_csv(dest / "aggregator=graph_knn" / "metrics.csv").columns
    assert "t_score" not in cols and "iou" in cols
    prov = json.loads((dest / "provenance.json").read_text())
    assert prov["wall_s"] == 61.3 and prov["peak_rss_mb"] == 341 and "cores" in prov["machine"]
    readme = tmp_path / "README.md"
    readme.write_text("intro\n<!-- BEGIN generated: bench-table4 (do not edit) -->\nold\n"
                      "<!-- END generated: bench-table4 -->\nmiddle\n"
                      "<!-- BEGIN generated: bench-timing -->\n<!-- END generated: bench-timing -->\nend\n")
    readme.chmod(0o644)
    assert rt.check(readme, tmp_path) == ["bench-table4", "bench-timing"]
    assert rt.write(readme, tmp_path) == ["bench-table4", "bench-timing"]
    assert rt.check(readme, tmp_path) == []
    assert readme.stat().st_mode & 0o777 == 0o644
    text = readme.read_text()
    # mean [95 % interval]: two houses 20 points apart give [lower, higher]
    assert "| oracle     | graph KNN   | 30.00 [20.00, 40.00] | 60.00 [50.00, 70.00] |" in text
    assert "| oracle     | vision cone | 70.00 [60.00, 80.00] | 60.00 [50.00, 70.00] |" in text
    assert "Mean [95 % interval] over houses (95 % intervals: percentile bootstrap over houses" in text
    assert "**61 s wall, 341 MB peak RSS**" in text and text.startswith("intro\n") and text.endswith("end\n")


def test_publish_records_the_numba_compile_step_of_a_fresh_clone(tmp_path):
    """With make setup's compile step timed into an empty numba cache (make bench-publish), the
    timing block says the run was timed as on a fresh clone and how long the compile took; a
    malformed compile-time file is one error naming it."""
    run = _hand_run(tmp_path)
    (tmp_path / "time.txt").write_text("19.6 349184\n")
    (tmp_path / "compile.txt").write_text("10.4 250000\n")
    dest = rt.publish(run, "bench", tmp_path, tmp_path / "time.txt", compile_time_file=tmp_path / "compile.txt")
    assert json.loads((dest / "provenance.json").read_text())["numba_compile_s"] == 10.4
    readme = tmp_path / "README.md"
    readme.write_text("<!-- BEGIN generated: bench-timing -->\n<!-- END generated: bench-timing -->\n")
    rt.write(readme, tmp_path)
    text = readme.read_text()
    assert "**20 s wall, 341 MB peak RSS**" in text
    assert "numba's cache empty before `make setup`, whose kernel compile step took 10 s" in text
    (tmp_path / "bad.txt").write_text("oops\n")
    with pytest.raises(ValueError, match="bad.txt: expected GNU time"):
        rt.publish(run, "bench", tmp_path, tmp_path / "time.txt", compile_time_file=tmp_path / "bad.txt")


def _timing_runs(folder: Path, runs: list[tuple]) -> Path:
    """Scripted timing files as make bench-publish writes them: per run (compile s, empty (wall s,
    KiB, 1-min load), filled (wall s, KiB, 1-min load)) a folder 1/, 2/, ..."""
    for i, (comp, empty, filled) in enumerate(runs, 1):
        d = folder / str(i)
        d.mkdir(parents=True)
        (d / "compile.txt").write_text(f"{comp} 250000\n")
        for case, (wall, kib, load) in (("empty", empty), ("filled", filled)):
            (d / f"{case}.txt").write_text(f"Command exited with non-zero status 0\n{wall} {kib}\n")
            (d / f"{case}.load").write_text(f"{load} 1.50 1.20 3/512 4242\n")
    return folder


def test_the_bench_timing_is_the_median_of_fresh_runs_with_range_and_load(tmp_path):
    """make bench-publish times several fresh-clone runs (empty, then filled cache) and the
    block says each case's median wall time, peak RSS and load with their ranges."""
    run = _hand_run(tmp_path)
    timing = _timing_runs(tmp_path / "timing", [
        (17.2, (29.4, 339968, 2.04), (20.1, 307200, 2.31)),
        (16.1, (26.0, 330000, 1.62), (19.0, 300000, 1.90)),
        (18.9, (33.3, 350000, 2.40), (22.4, 310000, 2.02))])
    dest = rt.publish(run, "bench", tmp_path, timings_dir=timing)
    prov = json.loads((dest / "provenance.json").read_text())
    assert prov["timings"]["runs"] == 3 and prov["timings"]["empty"]["wall_s"] == [29.4, 26.0, 33.3]
    assert prov["timings"]["filled"]["load_1min"] == [2.31, 1.9, 2.02]
    prov.update(date_utc="2026-11-29", machine="AMD EPYC, 2 cores, 24 GiB, Linux 6.18", commit="abc1234")
    line = rt.timings_line(prov)
    assert line == (
        "Measured with `/usr/bin/time` on 2026-11-29 on AMD EPYC, 2 cores, 24 GiB, Linux 6.18 at commit abc1234: "
        "`make bench` (2 configurations) as on a fresh clone, 3 times (numba's cache empty, then `make setup`'s "
        "kernel compile step: 17 s (16-19 s)), each time twice: **from an empty cache 29 s (26-33 s) wall**, "
        "332 MB (322-342 MB) peak RSS, load 2.0 (1.6-2.4); **again, its cache filled, 20 s (19-22 s) wall**, "
        "300 MB (293-303 MB) peak RSS, load 2.0 (1.9-2.3). Medians over the 3 runs, their ranges in parentheses; "
        "load: the 1-minute load average as the run ended, its own workers included.\n")
    readme = tmp_path / "README.md"
    readme.write_text("<!-- BEGIN generated: bench-timing -->\n<!-- END generated: bench-timing -->\n")
    assert rt.write(readme, tmp_path) == ["bench-timing"]
    assert "**from an empty cache 29 s (26-33 s) wall**" in readme.read_text()
    # one run: no ranges
    one = _timing_runs(tmp_path / "one", [(12.0, (15.0, 339968, 1.4), (9.6, 307200, 1.2))])
    line = rt.timings_line({**prov, "timings": rt.read_timings(one)})
    assert "once (numba's cache empty, then `make setup`'s kernel compile step: 12 s)" in line
    assert "**from an empty cache 15 s wall**, 332 MB peak RSS, load 1.4;" in line and "One run; load" in line


def test_bad_timing_files_are_one_line_naming_the_file(tmp_path, capsys, monkeypatch):
    run = _hand_run(tmp_path)
    timing = _timing_runs(tmp_path / "timing", [(17.2, (29.4, 339968, 2.0), (20.1, 307200, 2.3))] * 2)
    (timing / "2" / "filled.txt").unlink()
    with pytest.raises(ValueError, match=r"timing/2/filled.txt: expected GNU time"):
        rt.read_timings(timing)
    (timing / "2" / "filled.txt").write_text("20.1 307200\n")
    (timing / "1" / "empty.load").write_text("busy\n")
    with pytest.raises(ValueError, match=r"timing/1/empty.load: expected a copy of /proc/loadavg"):
        rt.read_timings(timing)
    (tmp_path / "none").mkdir()
    with pytest.raises(ValueError, match="no run folders in it"):
        rt.read_timings(tmp_path / "none")
    from benchmark.commands.maintainer.readme_tables import main

    monkeypatch.chdir(tmp_path)  # publish writes under the current folder's results/published
    assert main(["publish", str(run), "--name", "bench", "--timings", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no run folders in it" in err[0]
    assert not (tmp_path / "results" / "published").exists()  # nothing written


def test_bad_markers_and_missing_inputs(tmp_path):
    with pytest.raises(ValueError, match="no '<!-- END generated: bench-table4 -->'"):
        rt.blocks_in("<!-- BEGIN generated: bench-table4 -->\nx\n")
    with pytest.raises(ValueError, match="not one of"):
        rt.update_text("<!-- BEGIN generated: nope -->\nx\n<!-- END generated: nope -->\n", tmp_path)
    with pytest.raises(FileNotFoundError, match="publish the run first"):
        rt.update_text("<!-- BEGIN generated: bench-table3 -->\n<!-- END generated: bench-table3 -->\n", tmp_path)
    from benchmark.commands.maintainer.readme_tables import main

    readme = tmp_path / "R.md"
    readme.write_text("<!-- BEGIN generated: bench-table3 -->\n<!-- END generated: bench-table3 -->\n")
    assert main(["check", "--readme", str(readme)]) in (1, 2)


def test_robustness_sentences_follow_the_paired_intervals():
    """Every "ahead" in the published block has a paired interval that excludes zero and every
    "tied" one that holds it; "change places at severity s" only follows a lead of the other side
    the intervals support; known verdicts of the published run (ProcTHOR: exploration
    tied at the short budgets with no change of places; classifier noise flips at 5); no mCE on
    the paper's IoU; the power report names the houses each dataset's header counts per cell."""
    import re

    block = rt.blocks_in((ROOT / "docs" / "robustness.md").read_text(encoding="utf-8"))["robustness"]
    procthor, synthetic = block.split("**synthetic**")
    steps = re.findall(r"(\d): (view-based ahead|geometric ahead|tied) ([+-]\d+\.\d) \[([+-]\d+\.\d), ([+-]\d+\.\d)\]",
                       block)
    assert len(steps) > 60
    for _, word, _, lo, hi in steps:
        lo, hi = float(lo), float(hi)
        assert (word == "tied") == (lo <= 0 <= hi) and (word != "view-based ahead" or lo > 0)
        assert word != "geometric ahead" or hi < 0
    for line in block.splitlines():
        flip = re.search(r"they change places at severity (\d)", line)
        if flip:
            words = dict((int(k), w) for k, w, *_ in re.findall(
                r"(\d): (view-based ahead|geometric ahead|tied) ([+-]\d+\.\d) \[([+-]\d+\.\d), ([+-]\d+\.\d)\]", line))
            s_flip = int(flip.group(1))
            before = [w for k, w in words.items() if k < s_flip and w != "tied"]
            assert before and words[s_flip] != "tied" and before[-1] != words[s_flip]
    explore = next(x for x in procthor.splitlines() if x.startswith("- exploration budget:"))
    assert "3: tied -0.8 [" in explore and "no change of places that the intervals support" in explore
    classifier = next(x for x in procthor.splitlines() if x.startswith("- classifier noise:"))
    assert "they change places at severity 5" in classifier
    assert "paper IoU" not in block  # the views-only ablation is shown apart, after the means
    assert "| mCE | rel mCE | views-only pose noise, perfect map (ablation) | realistic (apart) |" in block
    n_procthor = int(re.search(r"\((\d+) houses per cell", procthor).group(1))
    n_synthetic = int(re.search(r"\((\d+) houses per cell", synthetic).group(1))
    assert n_procthor >= 100 and n_synthetic >= 100
    lines = block.splitlines()
    assert any(x.startswith("- ProcTHOR:") and f"With its {n_procthor} houses this run detects" in x for x in lines)
    assert any(x.startswith("- synthetic:") and f"With its {n_synthetic} houses this run detects" in x for x in lines)
    power = rt.blocks_in((ROOT / "README.md").read_text(encoding="utf-8"))["robustness-power"]
    assert f"With its {n_procthor} houses this run detects" in power and "| mCE |" not in power  # the README: power only
