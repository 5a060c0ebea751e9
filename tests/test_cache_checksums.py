"""Trust at the edges (issue 24 items 1, 3 and 7): every cache entry carries a checksum of its
content and is verified when read; a damaged entry is named in one line and recomputed; a
score row vouches for its saved label maps; file names built from ids are bounded and safe."""

from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from benchmark.config import compose_job
from benchmark.harness.cache import read_entry, write_entry
from benchmark.harness.runner import build_pipeline, run
from benchmark.harness.store import MAX_NAME, entry_name, safe_name
from envs.npz import ChecksumError, load_npz, save_npz

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}
METRICS = ["house_id", "status", "iou", "precision", "recall", "accuracy", "matched_iou", "n_views"]


def _cfg(tmp_path: Path, *overrides: str):
    return compose_job(["env=synthetic", "env.resolution=0.1", "classifier=oracle", "run.limit=3",
                        "viewpoints.spacing=1.0", f"run.results_dir={tmp_path / 'R'}", "run.progress=false",
                        *overrides])


def _flip_iou_digit(path: Path) -> None:
    """Flip one bit of the first digit after ``"iou": 0.`` in a score entry (as a bad disk would)."""
    raw = bytearray(path.read_bytes())
    i = raw.index(b'"iou": 0.') + len(b'"iou": 0.')
    raw[i] ^= 0x01  # '3' <-> '2', '5' <-> '4', ...: still a valid number
    path.write_bytes(bytes(raw))


# ------------------------------------------------------------------ the two formats
def test_npz_checksum_refuses_changed_content_and_old_files(tmp_path):
    p = tmp_path / "a.npz"
    save_npz(p, x=np.arange(6).reshape(2, 3), s=np.array(["a", "b"]))
    got = load_npz(p)
    assert set(got) == {"x", "s"} and got["x"].tolist() == [[0, 1, 2], [3, 4, 5]]
    np.savez(p, x=np.arange(6).reshape(2, 3) + 1, s=np.array(["a", "b"]))  # a valid zip, other content
    with pytest.raises(ChecksumError, match="no checksum"):
        load_npz(p)
    z = dict(np.load(tmp_path / "a.npz"))
    save_npz(p, **z)
    raw = p.read_bytes().replace(b"__sha256__", b"__sha256__")  # untouched: reads
    p.write_bytes(raw)
    assert load_npz(p)["x"][1, 2] == 6
    p.write_text("{}")
    with pytest.raises(ChecksumError, match="not a readable .npz"):
        load_npz(p)


def test_npz_checksum_catches_a_member_rewritten_with_a_valid_crc(tmp_path):
    """A member replaced by another valid array (zip CRC right) with the old checksum kept."""
    import zipfile

    p = tmp_path / "a.npz"
    save_npz(p, proba=np.array([[0.25, 0.75]]))
    with zipfile.ZipFile(p) as zf:
        members = {n: zf.read(n) for n in zf.namelist()}
    import io

    buf = io.BytesIO()
    np.lib.format.write_array(buf, np.array([[0.75, 0.25]]))
    members["proba.npy"] = buf.getvalue()
    with zipfile.ZipFile(p, "w") as zf:
        for n, b in members.items():
            zf.writestr(n, b)
    with pytest.raises(ChecksumError, match="does not match its checksum"):
        load_npz(p)


def test_json_entry_checksum_and_vouched_files(tmp_path):
    side = tmp_path / "maps.npz"
    save_npz(side, raw=np.zeros((2, 2), np.int16))
    e = tmp_path / "scores" / "h.json"
    write_entry(e, {"iou": 0.3518, "n": np.int64(3)}, {"maps": side})
    assert read_entry(e, require=("maps",)) == {"iou": 0.3518, "n": 3}
    _flip_iou_digit(e)
    with pytest.raises(ChecksumError, match="does not match its checksum"):
        read_entry(e)
    write_entry(e, {"iou": 0.3518}, {"maps": side})
    side.write_text("{}")
    with pytest.raises(ChecksumError, match="maps file .* changed"):
        read_entry(e)
    side.unlink()
    with pytest.raises(ChecksumError, match="missing"):
        read_entry(e)
    write_entry(e, {"iou": 0.3518})
    with pytest.raises(ChecksumError, match="no maps file"):
        read_entry(e, require=("maps",))
    e.write_text(json.dumps({"iou": 0.3518}))  # an entry of an older version
    with pytest.raises(ChecksumError, match="no checksum"):
        read_entry(e)


# ------------------------------------------------------------------ through the runner
def test_a_flipped_bit_in_a_score_entry_is_named_and_recomputed(tmp_path, caplog):
    """Issue 24 item 1: one flipped bit in a cached score changed the mean IoU, exit 0."""
    cfg, ch = _cfg(tmp_path)
    good = run(cfg, tmp_path / "job", ch)
    entry = sorted((tmp_path / "R" / "cache" / "scores").rglob("synthetic-s000000@*.json"))[0]
    _flip_iou_digit(entry)
    with caplog.at_level(logging.WARNING, logger="roomseg-bench"):
        again = run(cfg, tmp_path / "job", ch)
    pd.testing.assert_frame_equal(again[METRICS], good[METRICS])
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert any(str(entry) in w and "checksum" in w for w in warned), warned
    assert all("\n" not in w for w in warned)
    assert read_entry(entry)["iou"] == good["iou"].iloc[0]  # repaired on disk


def test_every_entry_kind_is_verified_on_read(tmp_path, caplog):
    """Render files, classifications, aggregations, saved maps and the fitted model: each
    rewritten with well-formed but other content is refused and recomputed."""
    cfg, ch = _cfg(tmp_path, "classifier=objects", "classifier.train_synthetic=[100000,100003]")
    good = run(cfg, tmp_path / "job", ch)
    pipe = build_pipeline(cfg, ch)
    h0, h1, h2 = good["house_id"]
    for p in (pipe.entry("score", h0), pipe.entry("score", h1), pipe.entry("score", h2)):
        p.unlink()  # rows must be recomputed from the damaged entries below
    # a classification with its classes' columns swapped (still probabilities)
    c = load_npz(pipe.entry("classify", h0))
    np.savez(pipe.entry("classify", h0), poses=c["poses"], proba=c["proba"][:, ::-1], n_refused=c["n_refused"])
    # an aggregation with every label moved by one class (still in range)
    a = load_npz(pipe.entry("aggregate", h1))["raw"]
    np.savez(pipe.entry("aggregate", h1), raw=np.where(a >= 0, (a + 1) % 7, a).astype(np.int16))
    # a render whose first view lists another object (still valid JSON); its classification is
    # removed so that the render must be read
    obs = pipe.entry("render", h2) / "observations.jsonl"
    text = obs.read_text()
    i = text.index('[["') + 3
    obs.write_text(text[:i] + "Toilet" + text[text.index('"', i):])
    assert obs.read_text() != text
    pipe.entry("classify", h2).unlink()
    # the fitted objects classifier, its counts doubled
    model = next((tmp_path / "R" / "cache" / "models").rglob("*.npz"))
    m = load_npz(model)
    np.savez(model, **{**m, "counts": m["counts"] * 2})
    build_pipeline.__globals__["_ENVS"].clear()
    with caplog.at_level(logging.WARNING, logger="roomseg-bench"):
        again = run(cfg, tmp_path / "job", ch)
    pd.testing.assert_frame_equal(again[METRICS], good[METRICS])
    warned = "\n".join(r.getMessage() for r in caplog.records if r.levelno == logging.WARNING)
    for f in (pipe.entry("classify", h0), pipe.entry("aggregate", h1), obs.parent, model):
        assert str(f) in warned, f
    assert "observations.jsonl: content does not match the render's checksum" in warned


def test_entries_that_exist_are_read_without_their_lock(tmp_path, monkeypatch, caplog):
    """Entries are renamed into place whole, so the stages read one that exists without taking
    its lock (a lock file made and removed per read); an entry being made, or a damaged one,
    still goes through the lock (where the damage is named and the entry made again)."""
    import contextlib

    from benchmark.harness import pipeline

    cfg, ch = _cfg(tmp_path, "run.workers=1")  # the locks are taken in this process
    good = run(cfg, tmp_path / "job", ch)
    pipe = build_pipeline(cfg, ch)
    h0, h1, h2 = good["house_id"]
    for h in (h0, h1, h2):
        pipe.entry("score", h).unlink()  # the rows are made again from the stages' entries
    c = load_npz(pipe.entry("classify", h1))
    np.savez(pipe.entry("classify", h1), poses=c["poses"], proba=c["proba"][:, ::-1], n_refused=c["n_refused"])
    taken = []
    real = pipeline.locked

    @contextlib.contextmanager
    def recording(path, *a, **k):
        taken.append(Path(path))
        with real(path, *a, **k):
            yield

    monkeypatch.setattr(pipeline, "locked", recording)
    with caplog.at_level(logging.WARNING, logger="roomseg-bench"):
        again = run(cfg, tmp_path / "job", ch)
    pd.testing.assert_frame_equal(again[METRICS], good[METRICS])
    made = {pipe.entry("score", h) for h in (h0, h1, h2)} | {pipe.entry("classify", h1)}
    assert set(taken) == made, sorted(map(str, set(taken) ^ made))
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warned) == 1 and str(pipe.entry("classify", h1)) in warned[0]


@pytest.mark.slow
def test_a_corrupt_saved_maps_entry_is_repaired_and_report_and_figures_work(tmp_path, caplog):
    """Issue 24 item 7: a maps entry replaced by ``{}`` was never repaired (rerun exit 0, then
    ``report`` and ``figures from-run`` exit 2)."""
    results = tmp_path / "R"
    cmd = [sys.executable, "-m", "benchmark.commands.bench", "env=synthetic", "env.resolution=0.1",
           "classifier=oracle", "run.limit=2", "viewpoints.spacing=1.0", f"run.results_dir={results}",
           "run.progress=false"]
    assert subprocess.run(cmd, cwd=ROOT, env=ENV, capture_output=True, text=True).returncode == 0
    maps = sorted((results / "cache" / "maps").rglob("*.npz"))
    assert len(maps) == 2
    maps[0].write_text("{}")
    r = subprocess.run(cmd, cwd=ROOT, env=ENV, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    said = r.stdout + r.stderr
    assert str(maps[0]) in said and "changed" in said  # named in one line ...
    assert load_npz(maps[0])["post"].ndim == 2  # ... and recomputed
    run_dir = results / "runs" / "default"
    rep = subprocess.run([sys.executable, "-m", "benchmark.commands.report", str(run_dir), "--out",
                          str(tmp_path / "report.html")], cwd=ROOT, env=ENV, capture_output=True, text=True)
    assert rep.returncode == 0, rep.stderr
    fig = subprocess.run([sys.executable, "-m", "benchmark.commands.figures", "from-run", str(run_dir), "--out",
                          str(tmp_path / "figs")], cwd=ROOT, env=ENV, capture_output=True, text=True)
    assert fig.returncode == 0, fig.stderr


# ------------------------------------------------------------------ names from ids
def test_names_from_ids_are_bounded_safe_and_distinct():
    assert safe_name("synthetic-s000000") == "synthetic-s000000"
    long_id = "x" * 240
    assert len(safe_name(long_id)) <= MAX_NAME and safe_name(long_id).startswith("x" * 40 + "~")
    assert safe_name("a b") != safe_name("a_b") and safe_name("a_b") == "a_b"
    assert safe_name("../etc") not in ("..", ".") and "/" not in safe_name("../etc")
    assert not safe_name(".").startswith(".") and not safe_name("..").startswith(".")
    assert safe_name("küche") != safe_name("k_che") and safe_name("") != ""
    assert len(entry_name(long_id, "f" * 16)) <= MAX_NAME + 13


@pytest.mark.slow
def test_a_long_house_id_no_longer_aborts_the_run(tmp_path, procthor_file):
    """Issue 24 item 3: a 240-character id in the middle of three houses made the run exit 2
    with no metrics.csv (ENAMETOOLONG in the cache)."""
    import gzip

    with gzip.open(procthor_file, "rt") as f:
        houses = [json.loads(next(f)) for _ in range(3)]
    houses[1]["id"] = "h" * 240
    folder = tmp_path / "houses"
    folder.mkdir()
    for i, h in enumerate(houses):
        (folder / f"{i}.json").write_text(json.dumps(h))
    r = subprocess.run([sys.executable, "-m", "benchmark.commands.bench", "env=procthor_shared",
                        f"env.path={folder}", "classifier=oracle", "env.resolution=0.1", "viewpoints.spacing=1.0",
                        f"run.results_dir={tmp_path / 'R'}", "run.progress=false"],
                       cwd=ROOT, env=ENV, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    df = pd.read_csv(tmp_path / "R" / "runs" / "default" / "metrics.csv")
    assert df["house_id"].tolist()[1] == "h" * 240 and (df["status"] == "ok").all()


def test_a_row_served_from_the_cache_carries_this_runs_label(tmp_path):
    """``run.label`` is free text, not part of any cache key: a row served from the cache must
    carry the label of the run that serves it, not of the run that computed it."""
    cfg, ch = _cfg(tmp_path, "run.label=first")
    assert set(run(cfg, tmp_path / "a", ch)["label"]) == {"first"}
    cfg, ch = _cfg(tmp_path, "run.label=second")
    again = run(cfg, tmp_path / "b", ch)
    assert set(again["label"]) == {"second"} and again.attrs["n_failed"] == 0


def test_results_are_flushed_to_disk_cache_entries_are_not(tmp_path, monkeypatch):
    """Results are fsynced before the rename (whole after a power failure); cache entries skip it,
    as their checksum catches a torn one on read (and the harness computes it again)."""
    import os

    import numpy as np

    from benchmark.harness.cache import atomic_save_npz, read_entry, write_entry
    from envs.atomic import atomic_write_text
    from envs.npz import load_npz

    calls = []
    real = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (calls.append(fd), real(fd))[1])
    atomic_write_text(tmp_path / "metrics.csv", "house_id,iou\nh,0.5\n")
    assert len(calls) == 1
    write_entry(tmp_path / "e.json", {"iou": 0.5})
    atomic_save_npz(tmp_path / "m.npz", raw=np.arange(4))
    assert len(calls) == 1
    assert read_entry(tmp_path / "e.json") == {"iou": 0.5}
    assert load_npz(tmp_path / "m.npz")["raw"].tolist() == [0, 1, 2, 3]


def test_a_classification_that_disagrees_with_its_render_is_recomputed(tmp_path, caplog):
    """A well-formed classification entry (valid checksum) whose poses or view count disagree
    with the house's render is refused by name and recomputed, to the same rows."""
    cfg, ch = _cfg(tmp_path, "run.workers=1")
    good = run(cfg, tmp_path / "job", ch)
    pipe = build_pipeline(cfg, ch)
    h0, h1 = good["house_id"][:2]
    for h in (h0, h1):
        pipe.entry("score", h).unlink()
        pipe.entry("aggregate", h).unlink()
    c = load_npz(pipe.entry("classify", h0))
    save_npz(pipe.entry("classify", h0), poses=c["poses"] + [0.5, 0.0, 0.0], proba=c["proba"], n_refused=c["n_refused"])
    c = load_npz(pipe.entry("classify", h1))
    save_npz(pipe.entry("classify", h1), poses=c["poses"][1:], proba=c["proba"][1:], n_refused=c["n_refused"])
    with caplog.at_level(logging.WARNING, logger="roomseg-bench"):
        again = run(cfg, tmp_path / "job", ch)
    pd.testing.assert_frame_equal(again[METRICS], good[METRICS])
    warned = "\n".join(r.getMessage() for r in caplog.records if r.levelno == logging.WARNING)
    assert f"{pipe.entry('classify', h0)}: bad cache entry, recomputing it (BadEntry: poses differ from the render's)" in warned
    assert "refused views, but the render has" in warned and str(pipe.entry("classify", h1)) in warned


def test_a_process_reads_each_classification_once_and_a_rewritten_one_again(tmp_path, monkeypatch):
    """Every method of every robot condition on one render and classifier uses the same classify
    entry: a process keeps it as read (read-only) and each job checks it again; an entry
    written anew is read anew, and the rows are those of a process that kept nothing."""
    from benchmark.harness import pipeline as pl
    from envs.atomic import atomic_write_bytes

    monkeypatch.setattr(pl, "_CLASSIFIED_MEMO", pl.ByteLRU())
    reads: list[str] = []
    real = pl.load_npz
    monkeypatch.setattr(pl, "load_npz", lambda p: (reads.append(str(p)) if "/classify/" in str(p) else None) or real(p))
    base = ["run.workers=1", "aggregator=vision_cone"]
    cfg, ch = _cfg(tmp_path, *base)
    run(cfg, tmp_path / "cone", ch)  # computes the classifications (nothing read)
    pipe = build_pipeline(cfg, ch)
    ids = [pipe.entry("classify", h) for h in pipe.env.house_ids()[:3]]
    assert reads == []
    cfg, ch = _cfg(tmp_path, "run.workers=1", "aggregator=graph_knn")
    knn = run(cfg, tmp_path / "knn", ch)
    assert sorted(reads) == sorted(map(str, ids))  # read once each ...
    reads.clear()
    cfg, ch = _cfg(tmp_path, "run.workers=1", "aggregator=euclidean_knn")
    run(cfg, tmp_path / "eu", ch)
    assert reads == []  # ... and kept
    assert all(not a.flags.writeable for z in pl._CLASSIFIED_MEMO.values() for a in z.values())
    atomic_write_bytes(ids[1], ids[1].read_bytes())  # the same bytes, another file
    cfg, ch = _cfg(tmp_path, "run.workers=1", "aggregator=graph_knn", "run.force=[score]")
    again = run(cfg, tmp_path / "knn", ch)
    assert reads == [str(ids[1])]
    monkeypatch.setattr(pl, "_CLASSIFIED_MEMO", pl.ByteLRU())
    cfg, ch = _cfg(tmp_path, "run.workers=1", "aggregator=graph_knn", "run.force=[score]")
    alone = run(cfg, tmp_path / "knn", ch)
    pd.testing.assert_frame_equal(knn[METRICS], again[METRICS])
    pd.testing.assert_frame_equal(knn[METRICS], alone[METRICS])


def test_json_entries_are_one_line_and_indented_ones_of_earlier_versions_still_read(tmp_path):
    """A score entry is written on one line (json's C encoder); the checksum is over the
    canonical content, so an entry an earlier version wrote indented reads the same, and a
    changed value in either is refused."""
    e = tmp_path / "scores" / "h.json"
    row = {"iou": 0.3518, "n": np.int64(3), "nan": float("nan"), "name": "kitchen ünï", "t": [1, 2.5]}
    write_entry(e, row)
    text = e.read_text(encoding="utf-8")
    assert "\n" not in text.strip()
    raw = json.loads(text)
    old = tmp_path / "scores" / "old.json"
    old.write_text(json.dumps(raw, indent=1, sort_keys=True, allow_nan=True), encoding="utf-8")  # as before
    got = read_entry(e)
    assert read_entry(old) == got and got["n"] == 3 and got["name"] == "kitchen ünï" and np.isnan(got["nan"])
    for f in (e, old):
        f.write_text(f.read_text(encoding="utf-8").replace("0.3518", "0.3519"), encoding="utf-8")
        with pytest.raises(ChecksumError, match="does not match its checksum"):
            read_entry(f)
