"""The sweep report: one static HTML file with the configurations (sortable), the failures and
per house ground truth | raw | post-processed maps; opened in headless Chromium where installed."""

from __future__ import annotations

import base64
import io
import json
import re
import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from benchmark.commands.report import main

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--hide-scrollbars", "--enable-logging=stderr", "--v=0"]


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """A 2 x 2 sweep (graph KNN / vision cone x post-processing off / on) on 2 generated houses,
    the ground-truth-geometry sanity row (a segmenter: instance maps), and one hand-made job
    whose two houses failed."""
    res = tmp_path_factory.mktemp("report") / "res"
    subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "-m", "env=synthetic", "env.resolution=0.1",
                    "classifier=oracle", "aggregator=graph_knn,vision_cone", "postprocess=none,default",
                    "run.limit=2", "run.name=rep", f"run.results_dir={res}"], check=True, capture_output=True)
    run = res / "runs" / "rep"
    jobs = sorted(p.parent for p in run.rglob("metrics.csv"))
    assert len(jobs) == 4
    # a geometric sanity row (an instance map: the ground truth's own rooms) in the same run
    subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "-m", "env=synthetic", "env.resolution=0.1",
                    "segmenter=gt_geometry", "run.limit=2", "run.name=rep", f"run.results_dir={res}"],
                   check=True, capture_output=True)
    bad = run / "broken_job"
    bad.mkdir()
    for name in ("resolved_config.yaml", "summary.json"):
        shutil.copy(jobs[0] / name, bad / name)
    df = pd.read_csv(jobs[0] / "metrics.csv")
    df["status"], df["error"] = "failed", ["HouseError: wall 3 has no points", "ValueError: empty map <b>"]
    for m in ("iou", "precision", "recall", "accuracy"):
        df[m] = np.nan
    df.to_csv(bad / "metrics.csv", index=False)
    summary = json.loads((bad / "summary.json").read_text())
    summary.update(n_ok=0, n_failed=2)
    (bad / "summary.json").write_text(json.dumps(summary))
    return run, jobs


def _images(page: str) -> list[np.ndarray]:
    return [np.asarray(Image.open(io.BytesIO(base64.b64decode(m))))
            for m in re.findall(r'src="data:image/png;base64,([^"]+)"', page)]


@pytest.mark.slow
def test_report_holds_configurations_failures_and_maps(sweep, tmp_path, capsys):
    run, jobs = sweep
    out = tmp_path / "r" / "report.html"
    assert main([str(run), "--out", str(out), "--house", "synthetic-s000001"]) == 0
    page = out.read_text()
    body = page[page.index('<table class="sortable" id="configs">'):]
    body = body[:body.index("</table>")]
    assert body.count("<tr>") == 1 + 6  # header + 4 jobs + the sanity row + the broken one
    ious = [pd.read_csv(j / "metrics.csv")["iou"].dropna() * 100 for j in jobs]
    for v in ious:  # the mean, and its 95 % interval over houses beside it
        assert f">{v.mean():.2f}" in body
        if len(v) == 2 and v.iloc[0] != v.iloc[1]:  # two houses: the interval is [lower, higher]
            assert f">{v.mean():.2f}<br><small class=\"muted ci\">[{v.min():.1f},<wbr> {v.max():.1f}]</small></td>" in body
    # failures, escaped
    assert "HouseError: wall 3 has no points" in page and "empty map &lt;b&gt;" in page and "<b>" not in page
    # maps: per configuration group (2 aggregators): ground truth, raw, post-processed; then the
    # sanity row: ground truth and its rooms, drawn as an instance map
    imgs = _images(page)
    assert len(imgs) == 2 * 3 + 2
    shapes = {im.shape[:2] for im in imgs}
    assert len(shapes) == 1
    gt, rooms = imgs[-2], imgs[-1]
    from benchmark.reports.html_report import PAGE_BORDER_COLOR
    from envs.world.classes import CLASS_COLORS

    colours = {tuple(c) for c in rooms.reshape(-1, 3)} - {(0, 0, 0), PAGE_BORDER_COLOR}
    assert colours and not colours & {tuple(c) for c in CLASS_COLORS.values()}  # instance colours, not classes
    walls = (gt == 0).all(-1)
    assert ((rooms == 0).all(-1) == walls).all()  # the same rooms: black exactly where the ground truth is
    assert (rooms == PAGE_BORDER_COLOR).all(-1).sum() == (gt == PAGE_BORDER_COLOR).all(-1).sum() > 0  # and borders
    assert 'id="house-synthetic-s000001"' in page and "house-synthetic-s000000" not in page
    assert "<script>" in page and "http://" not in page and "https://" not in page  # nothing fetched
    assert main([str(run), "--out", str(out), "--house", "nope"]) == 2
    assert "no job of the run scored it" in capsys.readouterr().err


def _chromium_or_skip():
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        pytest.skip("chromium is not installed (Debian: apt-get install -y chromium)")
    return exe


def _chromium(exe, tmp_path, url, *args):
    p = subprocess.run([exe, *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'profile'}", *args, url],
                       capture_output=True, text=True, timeout=120)
    return p


def _console_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if ":CONSOLE" in line]


@pytest.mark.slow
def test_report_in_headless_chromium(sweep, tmp_path):
    exe = _chromium_or_skip()
    run, _ = sweep
    out = tmp_path / "report.html"
    assert main([str(run), "--out", str(out)]) == 0
    url = out.resolve().as_uri()
    shot = tmp_path / "shot.png"
    p = _chromium(exe, tmp_path, url, f"--screenshot={shot}", "--window-size=1400,2600")
    assert shot.exists(), p.stderr[-2000:]
    assert _console_lines(p.stderr) == []
    rgb = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    assert len({tuple(c) for c in rgb.reshape(-1, 3)[::13]}) > 50  # not blank
    from benchmark.reports.html_report import INSTANCE_COLORS
    from envs.world.classes import CLASS_COLORS

    seen = {tuple(c) for c in rgb.reshape(-1, 3)}
    assert sum(tuple(c) in seen for c in CLASS_COLORS.values()) >= 4  # the generated houses' label maps are drawn
    assert sum(tuple(c) in seen for c in INSTANCE_COLORS) >= 2  # and the sanity row's instance map
    top = rgb[:400]
    assert ((top.sum(-1) < 150).sum()) > 2000  # the heading and the table's text
    dom = _chromium(exe, tmp_path, url, "--dump-dom", "--window-size=1400,900").stdout
    assert dom.count('data-sortable="ready"') == 2  # the inline script ran (configs, failures)
    width = int(re.search(r'data-scroll-width="(\d+)"', dom).group(1))
    assert 0 < width <= 1400  # the configuration table needs no horizontal scrolling at 1400 px
    # measured by the test itself, not by the page: the table's right edge and its box's hidden
    # overflow (a box with overflow-x:auto scrolls inside, so the page's own width would not show it)
    measure = ("<script>var t = document.getElementById('configs'), w = t.parentElement;"
               "document.body.setAttribute('data-table-right', String(Math.ceil(t.getBoundingClientRect().right)));"
               "document.body.setAttribute('data-hidden', String(w.scrollWidth - w.clientWidth));</script></body>")
    measured = tmp_path / "measured.html"
    measured.write_text(out.read_text().replace("</body>", measure))
    dom = _chromium(exe, tmp_path, measured.resolve().as_uri(), "--dump-dom", "--window-size=1400,900").stdout
    right = int(re.search(r'data-table-right="(\d+)"', dom).group(1))
    hidden = int(re.search(r'data-hidden="(-?\d+)"', dom).group(1))
    assert 0 < right <= 1400 and hidden == 0, (right, hidden)  # every column shows at 1400 px
    # the sorting code sorts: IoU (column 4) descending, as a click on its header twice does
    p = _chromium(exe, tmp_path, url + "#sort=4,desc", "--dump-dom")
    assert _console_lines(p.stderr) == []
    table = p.stdout[p.stdout.index('id="configs"'):]
    table = table[:table.index("</table>")]
    values = re.findall(r'<tr><td[^>]*>(?:(?!</tr>).)*?<td class="num" data-v="([^"]*)"', table)
    assert len(values) == 6 and values[5] == ""  # the failed job has no IoU: last
    ious = [float(v) for v in values[:5]]
    assert ious == sorted(ious, reverse=True) and ious[0] > ious[-1]
    # the console check catches an error: a page that throws
    bad = tmp_path / "bad.html"
    bad.write_text("<html><body><script>throw new Error('deliberate');</script></body></html>")
    p = _chromium(exe, tmp_path, bad.resolve().as_uri(), "--dump-dom")
    assert any("deliberate" in line for line in _console_lines(p.stderr))


@pytest.mark.slow
def test_maps_on_another_grid_are_named_not_drawn(sweep, tmp_path):
    run, _ = sweep
    res = run.parent.parent
    subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "env=synthetic", "env.resolution=0.2",
                    "classifier=oracle", "aggregator=vision_cone", "run.limit=2", "run.name=coarse",
                    f"run.results_dir={res}"], check=True, capture_output=True)
    out = tmp_path / "r.html"
    assert main([str(run), str(res / "runs" / "coarse"), "--out", str(out), "--house", "synthetic-s000000"]) == 0
    page = out.read_text()
    assert "Not shown (maps on another grid than this ground truth): coarse." in page
    assert len(_images(page)) == 2 * 3 + 2  # the 0.1 m/px configurations only


def test_houses_of_every_dataset_are_drawn():
    """Without --house, the report draws N houses of every dataset of the run (those scored by
    the most jobs of that dataset), not the first N overall."""
    from benchmark.reports.html_report import pick_houses

    def frame(dataset, houses, status=None):
        return pd.DataFrame({"dataset": dataset, "house_id": houses, "status": status or ["ok"] * len(houses)})

    jobs = [(None, {}, frame("procthor", ["p0", "p1", "p2"])), (None, {}, frame("procthor", ["p0", "p1", "p2"])),
            (None, {}, frame("synthetic", ["s0", "s1", "s2"], ["failed", "ok", "ok"])),
            (None, {}, frame("synthetic", ["s0", "s1", "s2"]))]
    assert pick_houses(jobs, None, 2) == ["p0", "p1", "s1", "s2"]  # s0 failed once: scored by fewer jobs
    assert pick_houses(jobs, None, 1) == ["p0", "s1"]
    assert pick_houses(jobs, ["s0"], 2) == ["s0"]
    with pytest.raises(ValueError, match="no job of the run scored it"):
        pick_houses(jobs, ["x"], 2)
