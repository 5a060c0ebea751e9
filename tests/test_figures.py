"""Fig. 3 / Fig. 4: the command on a shared house (and a generated one), the array functions, bad input."""

import numpy as np
import pytest
from matplotlib.image import imread

from benchmark.commands.figures import main
from benchmark.reports.figures import DPI, figure_aggregators, figure_postprocess, figure_size
from envs.maps.gridmap import GridMap
from envs.maps.scene import Scene
from envs.world.classes import class_colors

SMALLEST_SHARED = 71  # the shared house with the smallest map (fast)


def png_ok(path, map_shape, must_show=()):
    """The PNG exists, has the layout's exact pixel size, and shows the given class colours."""
    assert path.exists() and path.stat().st_size > 10_000
    img = imread(path)
    w, h = figure_size(map_shape)
    assert abs(img.shape[1] - w * DPI) <= 1 and abs(img.shape[0] - h * DPI) <= 1, img.shape
    rgb = np.round(img[..., :3] * 255).astype(int)
    colours = {tuple(c) for c in rgb.reshape(-1, 3)[::7]}
    for c in must_show:
        assert tuple(c) in colours, c


@pytest.mark.slow
def test_fig3_and_fig4_commands_on_a_shared_house(procthor_file, tmp_path, capsys):
    from envs.datasets.house_files import load_houses
    from envs.maps.scene import rasterise_house

    scene = rasterise_house(load_houses(procthor_file, SMALLEST_SHARED, SMALLEST_SHARED + 1)[0])
    present = np.unique(scene.semantic[scene.semantic >= 0])
    colours = [class_colors(scene.classes)[k] for k in present]
    res = f"run.results_dir={tmp_path / 'results'}"
    assert main(["fig3", "--house-index", str(SMALLEST_SHARED), "--out", str(tmp_path / "fig3.png"), res]) == 0
    png_ok(tmp_path / "fig3.png", scene.grid.shape, colours)
    assert main(["fig4", "--house-index", str(SMALLEST_SHARED), "--out", str(tmp_path / "fig4.png"), res]) == 0
    png_ok(tmp_path / "fig4.png", scene.grid.shape, colours)
    # the maps came from (and were left in) the runner's cache: one per configuration drawn
    assert len(list((tmp_path / "results" / "cache" / "maps").rglob("*.npz"))) == 3
    mtime = (tmp_path / "fig3.png").stat().st_mtime_ns
    assert main(["fig3", "--house-index", str(SMALLEST_SHARED), "--out", str(tmp_path / "fig3.png"), res]) == 0
    assert (tmp_path / "fig3.png").stat().st_mtime_ns >= mtime
    assert len(list((tmp_path / "results" / "cache" / "maps").rglob("*.npz"))) == 3
    assert "fig3.png" in capsys.readouterr().out


def test_fig3_command_on_a_generated_house_with_overrides(tmp_path):
    """No shared data needed: env=synthetic at 0.1 m/px, the graph KNN aggregator."""
    out = tmp_path / "f.png"
    rc = main(["fig3", "--house-index", "1", "--out", str(out), "env=synthetic", "env.resolution=0.1",
               "aggregator=graph_knn", f"run.results_dir={tmp_path}"])
    assert rc == 0
    from hydra.utils import instantiate

    from benchmark.reports.figures import compose_config

    cfg, _ = compose_config(["env=synthetic", "env.resolution=0.1"])
    env = instantiate(cfg.env)
    png_ok(out, env.scene(env.house_ids()[1]).grid.shape)


def hand_scene():
    walk = np.zeros((40, 60), bool)
    walk[2:38, 2:58] = True
    rooms = np.full(walk.shape, -1, np.int32)
    rooms[2:38, 2:30], rooms[2:38, 30:58] = 0, 1
    inst = np.where(walk, rooms, -1)
    return Scene("hand", GridMap(walk, 0.1, (0.0, 4.0)), rooms, inst, np.array([2, 5]), ["r0", "r1"])


@pytest.mark.slow
def test_figure_functions_on_arrays(tmp_path):
    s = hand_scene()
    raw = s.semantic.copy()
    raw[10:15, 10:15] = 6
    figure_postprocess(s, raw, s.semantic, tmp_path / "a" / "fig3.png")
    png_ok(tmp_path / "a" / "fig3.png", s.grid.shape, [class_colors(s.classes)[k] for k in (2, 5, 6)])
    poses = np.array([[1.0, 2.0, 0.0], [4.0, 2.0, 90.0]])
    proba = np.eye(7)[[2, 5]]
    figure_aggregators(s, poses, s.semantic, raw, tmp_path / "fig4.png", proba)
    png_ok(tmp_path / "fig4.png", s.grid.shape)
    figure_aggregators(s, np.zeros((0, 3)), s.semantic, raw, tmp_path / "empty.png")  # no views: still drawn
    png_ok(tmp_path / "empty.png", s.grid.shape)


def test_figure_size_follows_the_map_aspect():
    wide, tall = figure_size((100, 300)), figure_size((300, 100))
    assert wide[1] == tall[1] and wide[0] > tall[0]


def test_bad_input(tmp_path, capsys):
    s = hand_scene()
    with pytest.raises(ValueError, match="shape"):
        figure_postprocess(s, s.semantic[:5], s.semantic, tmp_path / "x.png")
    with pytest.raises(ValueError, match="unknown|outside"):
        figure_postprocess(s, np.full(s.grid.shape, 9), s.semantic, tmp_path / "x.png")
    with pytest.raises(ValueError, match="one per pose"):
        figure_aggregators(s, np.zeros((2, 3)), s.semantic, s.semantic, tmp_path / "x.png", np.ones((3, 7)))
    gen = ["env=synthetic", "env.n_houses=2", f"run.results_dir={tmp_path}"]  # errors go to stderr (issue 38 item 5; were on stdout)
    assert main(["fig3", "--house-index", "5", "--out", str(tmp_path / "x.png"), *gen]) == 2
    assert "out of range" in capsys.readouterr().err
    assert main(["fig3", "--house-index", "0", "--out", str(tmp_path / "x.png"), "postprocess=none", *gen]) == 2
    assert "postprocess=none" in capsys.readouterr().err
    assert main(["fig4", "--house-index", "0", "--out", str(tmp_path / "x.png"), "aggregator=graph_knn", *gen]) == 2
    assert "aggregator" in capsys.readouterr().err
    assert main(["fig4", "--house-index", "0", "--out", str(tmp_path / "x.png"), "classifier"]) == 2
    assert "key=value" in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists()


def test_segment_borders_between_touching_segments_only():
    from benchmark.reports.plotting import label_segments, segment_borders

    seg = np.array([[0, 0, 1, 1],
                    [0, 0, 1, 1],
                    [-1, -1, -1, -1],
                    [2, 2, 2, 2]])
    b = segment_borders(seg)
    # one pixel wide, left of the 0|1 line; nothing against the wall row (-1)
    assert b.tolist() == [[False, True, False, False], [False, True, False, False],
                          [False] * 4, [False] * 4]
    # labels: two regions of the same class apart are two segments, touching labels differ
    labels = np.array([[3, 3, -1, 3], [3, 5, -1, 3]])
    s = label_segments(labels)
    assert s[0, 0] == s[1, 0] and s[0, 0] != s[0, 3] and s[1, 1] not in (s[0, 0], s[0, 3]) and s[0, 2] == -1


def test_touching_rooms_of_one_class_show_a_border(tmp_path):
    from benchmark.reports.plotting import BORDER_COLOR

    s = hand_scene()
    s.instance_classes[:] = 2  # both rooms bedrooms: only the border tells them apart
    same = Scene("same", s.grid, s.rooms, s.instances, np.array([2, 2]), ["r0", "r1"])
    paths = figure_postprocess(same, same.semantic, same.semantic, tmp_path / "f.png")
    rgb = np.round(imread(paths[0])[..., :3] * 255).astype(int)
    n_border = int((rgb == np.array(BORDER_COLOR)).all(-1).sum())
    assert n_border > 50  # the ground-truth panel's line between the two rooms
    paths = figure_postprocess(same, same.semantic, same.semantic, tmp_path / "g.png")
    assert paths == [tmp_path / "g.png"]


def test_figures_in_png_pdf_and_svg(tmp_path, capsys):
    s = hand_scene()
    paths = figure_postprocess(s, s.semantic, s.semantic, tmp_path / "fig3.png", "title",
                               formats=("png", "pdf", "svg"))
    assert [p.suffix for p in paths] == [".png", ".pdf", ".svg"]
    assert paths[1].read_bytes()[:5] == b"%PDF-"
    assert b"<svg" in paths[2].read_bytes()[:2000]
    png_ok(paths[0], s.grid.shape)
    from benchmark.reports.plotting import parse_formats

    assert parse_formats("png, PDF,svg") == ("png", "pdf", "svg")
    with pytest.raises(ValueError, match="png, pdf, svg"):
        parse_formats("png,jpeg")
    assert main(["fig3", "--format", "gif", "--out", str(tmp_path / "x.png")]) == 2
    assert "expected a comma-separated list" in capsys.readouterr().err


def test_view_labels_never_overlap():
    from benchmark.reports.figures import place_labels

    rng = np.random.default_rng(0)
    anchors = np.vstack([rng.normal(50, 2, (12, 2)), [[0, 0], [99, 99]]])  # a cluster and two corners
    w, h = 6.0, 4.0
    spots = place_labels(anchors, (w, h), (0, 0, 100, 100))
    for i in range(len(spots)):
        for j in range(i):
            assert abs(spots[i, 0] - spots[j, 0]) >= w or abs(spots[i, 1] - spots[j, 1]) >= h
    assert (spots[:, 0] >= w / 2).all() and (spots[:, 0] <= 100 - w / 2).all()
    assert np.allclose(spots[-2], [w / 2, h / 2]) and np.allclose(spots[-1], [100 - w / 2, 100 - h / 2])


def test_titles_in_words():
    from benchmark.reports.figures import describe, house_title

    names = {"env": "procthor_shared", "classifier": "oracle", "aggregator": "vision_cone", "postprocess": "default"}
    assert house_title(names, "h80") == "ProcTHOR (shared val) house h80"
    assert describe(names, 0.8, 0.764) == ("oracle classifier (set to 80 % accuracy, 76 % of views right), "
                                           "vision cone, post-processed")
    names.update(classifier="objects", aggregator="graph_knn", postprocess="none")
    assert describe(names, None, float("nan")) == "objects classifier, graph KNN, no post-processing"


@pytest.mark.slow
def test_from_run_draws_the_chosen_houses(tmp_path, capsys):
    import subprocess
    import sys

    res = tmp_path / "res"
    subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "-m", "env=synthetic", "env.resolution=0.1",
                    "classifier=oracle", "aggregator=graph_knn,vision_cone", "postprocess=default",
                    "run.limit=3", "run.name=figs", f"run.results_dir={res}", "hydra.launcher.n_jobs=1"],
                   check=True, capture_output=True)
    out = tmp_path / "figs"
    assert main(["from-run", str(res / "runs" / "figs"), "--out", str(out), "--house", "synthetic-s000002",
                 "--house", "synthetic-s000000", "--format", "png,svg"]) == 0
    names = sorted(p.name for p in out.iterdir())
    # per house: Fig. 3 for each of 2 aggregators and one Fig. 4, in 2 formats
    assert len(names) == 2 * 3 * 2
    assert sum("synthetic-s000002" in n for n in names) == 6 and not any("s000001" in n for n in names)
    capsys.readouterr()
    assert main(["from-run", str(res / "runs" / "figs"), "--out", str(out), "--house", "nope"]) == 2
    assert "no job of" in capsys.readouterr().err
    default = tmp_path / "default"
    assert main(["from-run", str(res / "runs" / "figs"), "--out", str(default)]) == 0
    assert {p.name.split("_")[1] for p in default.iterdir()} == {"synthetic-s000000"}
    # a from-run killed mid-way leaves the old set whole (never old and new mixed); the next run
    # removes what the killed one left and replaces the set
    import os
    import signal
    import time

    before = {p.name: p.read_bytes() for p in out.iterdir()}
    proc = subprocess.Popen([sys.executable, "-m", "benchmark.commands.figures", "from-run", str(res / "runs" / "figs"),
                             "--out", str(out), "--jobs", "1", "--format", "png,pdf"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    prefix = f".{out.name}.tmp-"  # the killed writer's temporary set (envs.atomic.leftover_prefix)
    deadline = time.time() + 120
    while time.time() < deadline:
        tmps = [p for p in tmp_path.iterdir() if p.name.startswith(prefix)]
        if tmps and any(tmps[0].iterdir()):
            break
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert tmps and any(tmps[0].iterdir()), "the drawing finished before it could be killed"
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert main(["from-run", str(res / "runs" / "figs"), "--out", str(out), "--jobs", "1", "--format", "pdf"]) == 0
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(prefix)]  # the killed run's leftover is gone
    names = {p.name for p in out.iterdir()}
    assert sum(n.endswith(".pdf") for n in names) == 3 and set(before) <= names  # new set (first house) + old kept
    # an output folder that cannot be made: one line naming it, exit 2, no traceback
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    capsys.readouterr()
    assert main(["from-run", str(res / "runs" / "figs"), "--out", str(blocker / "figs")]) == 2
    printed = capsys.readouterr().err.strip()
    assert len(printed.splitlines()) == 1 and printed.startswith("error: cannot write") and "a_file" in printed
