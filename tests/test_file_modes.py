"""Files written atomically get the mode an ordinary new file gets (issue #24): 0o666 less
the umask (0644 with umask 022, 0664 with 002), folders 0o777 less the umask; they used to
keep ``mkstemp``'s private 0600 after the rename. Checked under two umasks, for every
atomic writer and for the ``tables`` command's outputs."""

from __future__ import annotations

import os
import stat

import numpy as np
import pandas as pd
import pytest

from benchmark.commands.tables import main as tables_main
from benchmark.harness.cache import atomic_write_json, write_entry
from envs.atomic import atomic_folder, atomic_write_bytes, atomic_write_text
from envs.maps.label_png import write_label_png
from envs.npz import save_npz
from envs.render.cache import write_observations
from envs.render.observation import Observation


@pytest.fixture(params=[0o022, 0o002])
def umask(request):
    old = os.umask(request.param)
    try:
        yield request.param
    finally:
        os.umask(old)


def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def test_every_atomic_writer_gives_an_ordinary_file_mode(tmp_path, umask):
    file_mode, dir_mode = 0o666 & ~umask, 0o777 & ~umask
    atomic_write_bytes(tmp_path / "a.bin", b"x")
    atomic_write_text(tmp_path / "a.txt", "x")
    atomic_write_json(tmp_path / "a.json", {"a": 1})
    write_entry(tmp_path / "e.json", {"iou": 0.5})
    save_npz(tmp_path / "a.npz", a=np.zeros(3))
    write_label_png(tmp_path / "labels.png", np.zeros((4, 5), int), ["kitchen"])
    with atomic_folder(tmp_path / "set") as tmp:
        (tmp / "x.md").write_text("x")
        atomic_write_text(tmp / "y.csv", "y\n")
    write_observations(tmp_path / "render", [Observation(pose=(0.0, 0.0, 0.0), objects=[("Bed", 0.5)])])
    files = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert len(files) >= 10
    assert {p.name: oct(_mode(p)) for p in files} == {p.name: oct(file_mode) for p in files}
    for d in (tmp_path / "set", tmp_path / "render"):
        assert oct(_mode(d)) == oct(dir_mode), d
    atomic_write_text(tmp_path / "a.txt", "replaced")  # replacing keeps the ordinary mode
    assert _mode(tmp_path / "a.txt") == file_mode


def test_tables_outputs_and_metrics_files_are_not_private(tmp_path, umask, capsys):
    run = tmp_path / "runs" / "x"
    run.mkdir(parents=True)
    df = pd.DataFrame({"house_id": ["h0", "h1"], "dataset": "synthetic", "classifier": "oracle",
                       "aggregator": "graph_knn", "postprocess": "default", "segmenter": "", "status": "ok",
                       "error": "", "iou": [0.5, 0.7], "accuracy": [0.5, 0.7]})
    atomic_write_text(run / "metrics.csv", df.to_csv(index=False))  # how the runner writes it
    assert tables_main([str(tmp_path / "runs"), "--table", "table4", "--out", str(tmp_path / "t")]) == 0
    capsys.readouterr()
    written = [run / "metrics.csv", *sorted((tmp_path / "t").iterdir())]
    assert [p.name for p in written] == ["metrics.csv", "table4.csv", "table4.md", "table4.tex"]
    assert [oct(_mode(p)) for p in written] == [oct(0o666 & ~umask)] * 4
    assert oct(_mode(tmp_path / "t")) == oct(0o777 & ~umask)
