"""Results you can trust (issue 15): no overwrite, content keys, checked cache reads, failures
retried, config checked first, exit status, sweep summary, whole table sets; and the lazy
pipeline (issue 14 item 5): a cached job builds no stage, class order checked, fitted
objects classifier cached by its training set."""

from __future__ import annotations

import gzip
import json
import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hydra import compose, initialize_config_dir

from benchmark.harness.checks import ConfigError, check_config
from benchmark.harness.pipeline import StageError
from benchmark.harness.runner import CONF_DIR, build_pipeline, run
from benchmark.harness.store import Job, claim_job_dir, read_metrics
from benchmark.harness.typed import check_targets

ROOT = Path(__file__).resolve().parents[1]
FAST = ["viewpoints.spacing=1.0", "env.resolution=0.1", "env.start=0"]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def _lines(procthor_file: Path, n: int) -> list[dict]:
    out = []
    with gzip.open(procthor_file, "rt") as f:
        for i, line in enumerate(f):
            if i >= n:
                break
            out.append(json.loads(line))
    return out


def _write(path: Path, houses: list[dict]) -> Path:
    path.write_text("".join(json.dumps(h) + "\n" for h in houses))
    return path


def _compose(tmp_path: Path, houses: Path, *overrides: str, results: str = "results"):
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=[
            "env=procthor_shared", f"env.path={houses}", "classifier=oracle", "classifier.accuracy=0.8",
            f"run.results_dir={tmp_path / results}", "run.progress=false", *FAST, *overrides,
        ], return_hydra_config=True)
    choices = {k: str(v) for k, v in cfg.hydra.runtime.choices.items() if not k.startswith("hydra")}
    return cfg, choices


def _mtimes(cache: Path, stage: str) -> dict[str, int]:
    return {p.name: p.stat().st_mtime_ns for p in (cache / stage).rglob("*") if p.is_file()
            and not p.name.endswith(".lock")}


def _bench(*args: str, timeout: int = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "benchmark.commands.bench", *args], cwd=ROOT, env=ENV,
                          capture_output=True, text=True, timeout=timeout)


# ---------------------------------------------------------------- content keys
def test_edited_house_recomputes_that_house_only_and_matches_a_fresh_cache(tmp_path, procthor_file):
    houses = _lines(procthor_file, 2)
    path = _write(tmp_path / "houses.jsonl", houses)
    cfg, ch = _compose(tmp_path, path)
    before = run(cfg, tmp_path / "o1", ch)
    cache = tmp_path / "results" / "cache"
    scores = _mtimes(cache, "scores")
    # edit house 1: its first room becomes a kitchen (another class, so the scores must move)
    rooms = houses[1]["rooms"]
    rooms[0]["roomType"] = "Kitchen" if rooms[0]["roomType"] != "Kitchen" else "Bedroom"
    _write(path, houses)
    cfg, ch = _compose(tmp_path, path)
    after = run(cfg, tmp_path / "o1", ch)
    now = _mtimes(cache, "scores")
    assert all(now[k] == scores[k] for k in scores)  # nothing rewritten ...
    new = sorted(set(now) - set(scores))  # ... and one new entry, the edited house's
    assert len(new) == 1 and new[0].startswith(before.loc[1, "house_id"] + "@")
    assert after.loc[0, "iou"] == before.loc[0, "iou"]
    assert after.loc[1, "accuracy"] != before.loc[1, "accuracy"]
    # the same configuration on a fresh cache gives exactly the served values
    cfg, ch = _compose(tmp_path, path, results="fresh")
    fresh = run(cfg, tmp_path / "o2", ch)
    metric_cols = ["iou", "precision", "recall", "accuracy", "n_views"]
    pd.testing.assert_frame_equal(after[metric_cols], fresh[metric_cols])


def test_input_file_named_in_a_stage_config_is_part_of_the_entry(tmp_path, procthor_file):
    from benchmark.harness.cache import config_inputs, file_fingerprint

    f = tmp_path / "poses" / "h1.csv"
    f.parent.mkdir()
    f.write_text("x,z,yaw\n1,2,0\n")
    node = {"path": str(tmp_path / "poses" / "{house_id}.csv"), "model": "facebook/dinov2-large", "k": 5}
    got = config_inputs(node, "h1")
    assert list(got) == ["path"] and got["path"] == file_fingerprint(f)
    assert config_inputs(node, "h2") == {}  # no such file: the stage reports it when it runs
    f.write_text("x,z,yaw\n1,2,90\n")
    assert config_inputs(node, "h1")["path"] != got["path"]


def _config_inputs_reference(node, house_id):
    """config_inputs as it was written before its leaves were listed once per pipeline: one
    walk of the tree per call (shares no code with benchmark.harness.cache)."""
    import os
    from pathlib import Path as P

    from benchmark.harness.cache import file_fingerprint

    out = {}

    def walk(v, key):
        if isinstance(v, dict):
            for k, x in v.items():
                walk(x, f"{key}.{k}" if key else str(k))
        elif isinstance(v, list | tuple):
            for i, x in enumerate(v):
                walk(x, f"{key}[{i}]")
        elif isinstance(v, str) and v not in (".", "..") and ("/" in v or os.sep in v or P(v).suffix != ""):
            s = v.replace("{house_id}", str(house_id)) if house_id is not None else v
            if P(s).expanduser().exists():
                out[key] = file_fingerprint(P(s).expanduser())

    walk(node, "")
    return dict(sorted(out.items()))


def test_a_pipeline_lists_a_config_s_paths_once_and_checks_the_files_for_every_house(tmp_path, monkeypatch):
    """Pipeline._inputs_of (the path-like strings of a stage config listed once, the files they
    name fingerprinted per house) gives config_inputs' answer for every house, also after a file
    is rewritten, created or removed between houses; and config_inputs itself equals the walk
    it replaced, on a tree with lists, tuples, {house_id} paths, folders, model ids, numbers and a
    dotted key that repeats a nested one."""
    from benchmark.harness import cache as cache_mod
    from benchmark.harness.cache import config_inputs
    from benchmark.harness.pipeline import Pipeline

    d = tmp_path / "in"
    (d / "w").mkdir(parents=True)
    for name, text in {"h1.csv": "a", "h2.csv": "b", "shared.yaml": "s", "w/m.bin": "m"}.items():
        (d / name).write_text(text)
    node = {"poses": str(d / "{house_id}.csv"), "model": "facebook/dinov2-large", "k": 5, "ratio": 0.5,
            "files": [str(d / "shared.yaml"), {"deep": (str(d / "w"), "plain", str(d / "none.txt"))}],
            "a": {"b": str(d / "shared.yaml")}, "a.b": str(d / "h1.csv"), "dot": ".", "rel": "x.csv"}
    pipe = Pipeline(env=None, cache_dir=tmp_path / "c", keys={}, names={}, metric_params=None,
                    inputs={"aggregator": node, "label_noise": None})
    walks = []
    real = cache_mod.path_leaves
    monkeypatch.setattr("benchmark.harness.pipeline.path_leaves", lambda n: walks.append(1) or real(n))
    for step, hid in enumerate(["h1", "h2", "h3", "h1", "h2"]):
        if step == 2:
            (d / "shared.yaml").write_text("changed")
            (d / "h3.csv").write_text("new")
        if step == 4:
            (d / "h2.csv").unlink()
        want = _config_inputs_reference(node, hid)
        assert pipe._inputs_of("aggregator", hid) == want == config_inputs(node, hid)
    assert pipe._inputs_of("label_noise", "h1") == {} == _config_inputs_reference(None, "h1")
    assert len(walks) == 2  # one listing per group, not one per house
    assert set(_config_inputs_reference(node, "h1")) == {"poses", "files[0]", "files[1].deep[0]", "a.b"}


# ---------------------------------------------------------------- checked cache reads
@pytest.mark.slow
def test_bad_cache_entries_are_recomputed_with_a_warning_naming_the_file(tmp_path, procthor_file, caplog):
    path = _write(tmp_path / "houses.jsonl", _lines(procthor_file, 3))
    cfg, ch = _compose(tmp_path, path)
    good = run(cfg, tmp_path / "o", ch)
    pipe = build_pipeline(cfg, ch)
    ids = list(good["house_id"])
    # house 0: truncated score JSON; house 1: "{}" score JSON and a classify npz with pickled
    # objects; house 2: off-map poses in the render (its checksum catches the edit) and a
    # classify npz that is not a zip
    s0, s1 = pipe.entry("score", ids[0]), pipe.entry("score", ids[1])
    s0.write_text(s0.read_text()[:40])
    s1.write_text("{}")
    c1, c2 = pipe.entry("classify", ids[1]), pipe.entry("classify", ids[2])
    np.savez(c1, poses=np.zeros((2, 3)), proba=np.array([{"a": 1}, {"b": 2}], dtype=object),
             n_refused=np.array(0))
    c2.write_bytes(b"not a zip file at all")
    pipe.entry("score", ids[2]).unlink()
    poses_csv = pipe.entry("render", ids[2]) / "poses.csv"
    lines = poses_csv.read_text().splitlines()
    i, x, z, *rest = lines[1].split(",")
    lines[1] = ",".join([i, repr(float(x) + 1000.0), z, *rest])
    poses_csv.write_text("\n".join(lines) + "\n")
    with caplog.at_level(logging.WARNING, logger="roomseg-bench"):
        again = run(cfg, tmp_path / "o", ch)
    cols = ["house_id", "status", "iou", "precision", "recall", "accuracy", "n_views"]
    pd.testing.assert_frame_equal(again[cols], good[cols])
    warned = "\n".join(r.getMessage() for r in caplog.records if r.levelno == logging.WARNING)
    for f in (s0, s1, c1, c2, pipe.entry("render", ids[2])):
        assert str(f) in warned, f
    assert "does not match the render's checksum" in warned and "not a readable .npz" in warned
    # every warning is one line
    assert all("\n" not in r.getMessage() for r in caplog.records)


# ---------------------------------------------------------------- failures are retried
def test_failed_house_is_retried_after_the_fix_unless_failures_are_cached(tmp_path, procthor_file):
    houses = _lines(procthor_file, 2)
    good_type = houses[1]["rooms"][0]["roomType"]
    houses[1]["rooms"][0]["roomType"] = "Garage"
    path = _write(tmp_path / "houses.jsonl", houses)
    cfg, ch = _compose(tmp_path, path)
    df = run(cfg, tmp_path / "o", ch)
    assert df["status"].tolist() == ["ok", "failed"] and df.attrs["n_failed"] == 1
    cache = tmp_path / "results" / "cache"
    assert len(list((cache / "failures").rglob("*.json"))) == 1  # the failure is logged ...
    assert len(list((cache / "scores").rglob("*.json"))) == 1  # ... and not cached as a result
    logged = json.loads(next((cache / "failures").rglob("*.json")).read_text())["entry"]
    assert "Garage" in logged["error"] and logged["failed_at"]
    # the old behaviour on request: the logged failure is served
    cfg, ch = _compose(tmp_path, path, "run.cache_failures=true")
    assert run(cfg, tmp_path / "o", ch)["status"].tolist() == ["ok", "failed"]
    # fix the house: the next run retries it by default
    houses[1]["rooms"][0]["roomType"] = good_type
    _write(path, houses)
    cfg, ch = _compose(tmp_path, path)
    assert run(cfg, tmp_path / "o", ch)["status"].tolist() == ["ok", "ok"]


# ---------------------------------------------------------------- nothing overwrites
def test_two_single_runs_with_different_settings_keep_both_results(tmp_path, procthor_file):
    path = _write(tmp_path / "houses.jsonl", _lines(procthor_file, 1))
    out = tmp_path / "runs" / "default"
    cfg, ch = _compose(tmp_path, path, "aggregator=vision_cone")
    a = run(cfg, out, ch)
    first = (out / "metrics.csv").read_bytes()
    cfg, ch = _compose(tmp_path, path, "aggregator=graph_knn")
    b = run(cfg, out, ch)
    assert (out / "metrics.csv").read_bytes() == first  # untouched
    moved = Path(b.attrs["job_dir"])
    assert moved != out and moved.name.startswith("default~")
    assert pd.read_csv(moved / "metrics.csv")["aggregator"].tolist() == ["graph_knn"]
    assert a.attrs["job_dir"] == str(out)
    # the same settings again write into their own folder, not a third one
    cfg, ch = _compose(tmp_path, path, "aggregator=graph_knn")
    assert run(cfg, out, ch).attrs["job_dir"] == str(moved)
    assert sorted(p.name for p in out.parent.iterdir() if p.is_dir()) == ["default", moved.name]


def test_claim_names_what_differs(tmp_path):
    d = tmp_path / "job"
    assert claim_job_dir(d, "k1" * 8, {"aggregator._target_": "A", "env.path": "/a"}) == (d, "")
    folder, note = claim_job_dir(d, "k2" * 8, {"aggregator._target_": "A", "env.path": "/b"})
    assert folder == tmp_path / "job~k2k2k2k2"
    assert "env.path: /a -> /b" in note and "aggregator" not in note
    assert Job(d).identity()["key"] == "k1" * 8 and Job(folder).identity()["key"] == "k2" * 8


def test_a_job_has_one_identity_wherever_the_shared_data_sits(tmp_path, monkeypatch):
    """Two checkouts whose shared data sit in different places give a job the same key (the
    folder names a sweep prints are the same on every machine); a folder written under the
    earlier key, over the resolved paths, stays the job's own."""
    from benchmark.config import compose_job
    from benchmark.harness.runner import job_identity

    keys, earlier = [], []
    for root in ("../shared/data", "/one/shared/data", "/two/data/"):
        monkeypatch.setenv("ROOMSEG_SHARED_DATA", root)
        cfg, _ = compose_job(["env=procthor_shared"])
        key, settings = job_identity(cfg, ["a"])
        keys.append(key)
        earlier.append(job_identity(cfg, ["a"], from_data_root=False)[0])
        assert settings["env.path"].endswith("/procthor/procthor-10k-uniform-hard-val.jsonl.gz")
        assert settings["env.path"].startswith("${paths.data_dir}/"), settings["env.path"]
    assert len(set(keys)) == 1 and len(set(earlier)) == 3
    monkeypatch.setenv("ROOMSEG_SHARED_DATA", "/one/data")
    other, _ = compose_job(["env=procthor_shared", "env.path=/elsewhere/houses.jsonl.gz"])
    assert job_identity(other, ["a"])[0] != keys[0]  # a file outside the data root is named as it is
    d = tmp_path / "job"
    claim_job_dir(d, earlier[1], {"env.path": "/one/shared/data/procthor/x"})
    assert claim_job_dir(d, keys[0], {"env.path": "${paths.data_dir}/procthor/x"}, aliases=(earlier[1],)) == (d, "")
    assert Job(d).identity()["key"] == earlier[1]
    assert claim_job_dir(d, keys[0], {"env.path": "${paths.data_dir}/procthor/x"})[0] == tmp_path / f"job~{keys[0][:8]}"


@pytest.mark.slow
def test_multirun_over_two_house_files_writes_two_jobs_and_a_sweep_summary(tmp_path, procthor_file):
    houses = _lines(procthor_file, 2)
    a, b = _write(tmp_path / "a.jsonl", houses[:1]), _write(tmp_path / "b.jsonl", houses[1:])
    res = tmp_path / "results"
    out = _bench("-m", "env=procthor_shared", f"env.path={a},{b}", "classifier=oracle", f"run.results_dir={res}",
                 "run.name=two", "run.progress=false", "hydra/launcher=basic", *FAST)
    assert out.returncode == 0, out.stderr[-2000:]
    jobs = sorted(p.parent for p in (res / "runs" / "two").rglob("metrics.csv"))
    assert len(jobs) == 2
    got = sorted(pd.read_csv(j / "metrics.csv")["house_id"].iloc[0] for j in jobs)
    assert got == ["a-00000", "b-00000"]  # ids: file name and line
    table = pd.read_csv(res / "runs" / "two" / "sweep_summary.csv")
    assert len(table) == 2 and table["ok"].tolist() == [1, 1] and table["failed"].tolist() == [0, 0]
    assert "2 jobs, 2 rows, 0 failed" in out.stdout


# ---------------------------------------------------------------- config first, exit status
GRAPH_KNN, VISION_CONE = "benchmark.aggregators.graph_knn.GraphKNN", "benchmark.aggregators.vision_cone.VisionCone"


def _check(cfg):
    """The runner's two checks of a composed config: the run keys (checks.py), then the stages'
    types and ranges (typed.py, from each ``_target_``'s annotations)."""
    check_config(cfg)
    check_targets(cfg)


@pytest.mark.parametrize("key,value,match", [
    ("aggregator", {"_target_": GRAPH_KNN, "k": 0}, "aggregator.k=0: expected an integer >= 1"),
    ("env", {"_target_": "envs.datasets.synthetic.SyntheticEnv", "resolution": -0.05},
     "env.resolution=-0.05: expected a number > 0"),
    ("aggregator", {"_target_": VISION_CONE, "fov": 400.0}, "aggregator.fov=400.0: expected an angle in (0, 360] degrees"),
    ("classifier", {"_target_": "benchmark.classifiers.oracle.OracleClassifier", "accuracy": 1.5},
     "classifier.accuracy=1.5: expected a number in [0, 1]"),
    ("run", {"limit": "abc"}, "run.limit='abc': expected an integer >= 1, or null"),
    ("run", {"force": ["bogus"]}, "run.force=['bogus']: unknown stage(s) ['bogus']"),
    ("postprocess", {"_target_": "benchmark.postprocess.PostProcess", "window": 4},
     "postprocess.window=4: expected an odd integer >= 1"),
])
def test_config_rules_name_key_value_and_rule(key, value, match):
    with pytest.raises(ConfigError) as e:
        _check({key: value})
    assert match in str(e.value) and "\n" not in str(e.value)
    _check({"aggregator": {"_target_": VISION_CONE, "fov": 90.0}, "run": {"limit": None, "force": ["score"]},
            "env": {"_target_": "envs.datasets.synthetic.SyntheticEnv", "resolution": 0.05}})  # good values pass


def test_zero_houses_is_an_error(tmp_path, procthor_file):
    path = _write(tmp_path / "houses.jsonl", _lines(procthor_file, 1))
    cfg, ch = _compose(tmp_path, path, "env.start=1")
    with pytest.raises(ConfigError, match="no house selected"):
        run(cfg, tmp_path / "o", ch)


@pytest.mark.slow
def test_bad_config_exits_2_with_one_line_and_all_failed_run_exits_1(tmp_path, procthor_file):
    out = _bench("aggregator.k=0", f"run.results_dir={tmp_path / 'r'}", "run.progress=false")
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == ["roomseg-bench: error: aggregator.k=0: expected an integer >= 1"]
    houses = _lines(procthor_file, 2)
    for h in houses:
        h["rooms"][0]["roomType"] = "Garage"
    path = _write(tmp_path / "bad.jsonl", houses)
    args = ["env=procthor_shared", f"env.path={path}", "classifier=oracle", f"run.results_dir={tmp_path / 'r'}",
            "run.progress=false", *FAST]
    out = _bench(*args)
    assert out.returncode == 1, out.stderr[-2000:]
    assert "2 house(s) failed in 1 job(s)" in out.stderr.strip().splitlines()[-1]
    assert len(pd.read_csv(tmp_path / "r" / "runs" / "default" / "metrics.csv")) == 2  # rows written first
    assert _bench(*args, "run.allow_failures=true").returncode == 0


def test_unwritable_cache_folder_is_one_config_error(tmp_path, procthor_file):
    path = _write(tmp_path / "houses.jsonl", _lines(procthor_file, 1))
    (tmp_path / "file").write_text("")
    cfg, ch = _compose(tmp_path, path, f"run.cache_dir={tmp_path / 'file' / 'cache'}")
    with pytest.raises(ConfigError, match=r"run.cache_dir: cannot write in .*file/cache"):
        run(cfg, tmp_path / "o", ch)


# ---------------------------------------------------------------- lazy stages, classes, fitted model
def test_fully_cached_job_builds_no_stage_and_class_order_is_checked(tmp_path, procthor_file):
    path = _write(tmp_path / "houses.jsonl", _lines(procthor_file, 1))
    cfg, ch = _compose(tmp_path, path)
    run(cfg, tmp_path / "o", ch)
    first = Job(tmp_path / "o").summary()["stages_built"]
    assert {"viewpoints", "renderer", "classifier", "aggregator"} <= set(first)
    run(cfg, tmp_path / "o", ch)
    assert Job(tmp_path / "o").summary()["stages_built"] == []
    swapped = "[bathroom,balcony,bedroom,corridor,dining_room,kitchen,living_room]"
    cfg, ch = _compose(tmp_path, path, f"classifier.classes={swapped}", "run.force=[classify]")
    with pytest.raises(StageError, match=r"classes \['bathroom', 'balcony'.*environment has \['balcony', 'bathroom'"):
        run(cfg, tmp_path / "o3", ch)


def test_objects_classifier_fit_save_load_and_training_key(tmp_path):
    from benchmark.classifiers.objects import ObjectsClassifier
    from envs.render.observation import Observation

    clf = ObjectsClassifier(train_synthetic=[100000, 100004]).fit()
    obs = [Observation(pose=(0.0, 0.0, 0.0), objects=[(t, 0.1)]) for t in (clf.types[0], "Bed", "Toilet")]
    p = clf.predict_proba(obs)
    saved = clf.save(tmp_path / "m.npz")
    other = ObjectsClassifier(train_synthetic=[100000, 100004]).load(saved)
    np.testing.assert_array_equal(other.predict_proba(obs), p)
    assert other.training_key() == clf.training_key()
    assert ObjectsClassifier(train_synthetic=[100000, 100005]).training_key() != clf.training_key()
    with pytest.raises(ValueError, match="m.npz: fitted for other classes or another training set"):
        ObjectsClassifier(train_synthetic=[100000, 100005]).load(saved)
    (tmp_path / "bad.npz").write_bytes(b"xx")
    with pytest.raises(ValueError, match="bad.npz: not a readable .npz"):
        other.load(tmp_path / "bad.npz")


# ---------------------------------------------------------------- metrics files
def test_truncated_or_malformed_metrics_file_is_refused_naming_it(tmp_path):
    f = tmp_path / "metrics.csv"
    (tmp_path / "summary.json").write_text(json.dumps({"n_houses": 2}))  # a runner job's folder
    f.write_text("house_id,status,iou\nh1,ok,0.5\nh2,ok,0.")
    with pytest.raises(ValueError, match=r"metrics.csv: truncated"):
        read_metrics(f)
    f.write_text("house_id,status,iou\nh1,ok,0.5\nh2,maybe,0.4\n")
    with pytest.raises(ValueError, match=r"metrics.csv: malformed row 3"):
        read_metrics(f)
    f.write_text("house_id,status,iou\nh1,ok,0.5\n")
    with pytest.raises(ValueError, match=r"metrics.csv: 1 rows but summary.json says 2 houses"):
        read_metrics(f)


# ---------------------------------------------------------------- tables: by run, whole sets
def _fake_job(folder: Path, run_name: str, aggregator: str, ious: list[float]) -> None:
    """A finished runner job made by hand (known means)."""
    folder.mkdir(parents=True)
    n = len(ious)
    pd.DataFrame({"house_id": [f"h{i}" for i in range(n)], "dataset": "synthetic", "classifier": "oracle",
                  "aggregator": aggregator, "postprocess": "default", "segmenter": "", "status": "ok", "error": "",
                  "iou": ious, "accuracy": ious}).to_csv(folder / "metrics.csv", index=False)
    (folder / "summary.json").write_text(json.dumps({"n_houses": n}))
    (folder / "resolved_config.yaml").write_text(f"run:\n  name: {run_name}\n")


def _tables(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "benchmark.commands.tables", *args], cwd=ROOT, env=ENV,
                          capture_output=True, text=True, timeout=120)


def test_tables_group_by_run_and_say_what_they_read(tmp_path):
    runs = tmp_path / "runs"
    _fake_job(runs / "sweep" / "aggregator=graph_knn", "sweep", "graph_knn", [0.5, 0.7])
    _fake_job(runs / "sweep" / "aggregator=vision_cone", "sweep", "vision_cone", [0.2, 0.4])
    _fake_job(runs / "default", "default", "graph_knn", [0.1])
    out = _tables(str(runs), "--out", str(tmp_path / "t"), "--table", "table4")
    assert out.returncode == 0, out.stderr
    assert "read run 'sweep': 2 metrics file(s), 4 rows" in out.stderr
    assert "read run 'default': 1 metrics file(s), 1 rows" in out.stderr
    assert "## Run sweep" in out.stdout and "## Run default" in out.stdout
    sweep = pd.read_csv(tmp_path / "t" / "sweep" / "table4.csv")
    assert sweep.set_index("aggregator")["iou_mean"].to_dict() == pytest.approx({"graph_knn": 0.6, "vision_cone": 0.3})
    alone = pd.read_csv(tmp_path / "t" / "default" / "table4.csv")
    assert alone["iou_mean"].tolist() == pytest.approx([0.1]) and alone["n"].tolist() == [1]
    # a truncated metrics file is refused, naming it, and the old outputs stay whole
    before = {p.relative_to(tmp_path / "t"): p.read_bytes() for p in (tmp_path / "t").rglob("*") if p.is_file()}
    bad = runs / "default" / "metrics.csv"
    bad.write_bytes(bad.read_bytes()[:-3])
    out = _tables(str(runs), "--out", str(tmp_path / "t"), "--table", "table4")
    assert out.returncode == 2 and out.stderr.strip().splitlines()[-1] == f"error: {bad}: truncated (the last line has no newline)"
    after = {p.relative_to(tmp_path / "t"): p.read_bytes() for p in (tmp_path / "t").rglob("*") if p.is_file()}
    assert after == before


@pytest.mark.slow
def test_killed_tables_leave_the_old_set_or_the_new_one(tmp_path):
    import signal
    import time

    runs = tmp_path / "runs"
    rng = np.random.default_rng(0)
    for j in range(40):
        _fake_job(runs / "big" / f"job{j:02d}", "big", f"agg{j % 8}", list(rng.random(30).round(4)))
    args = [str(runs), "--table", "table4", "--table", "table3", "--table", "all", "--out"]
    ref = _tables(*args, str(tmp_path / "ref"))
    assert ref.returncode == 0, ref.stderr
    want = {p.relative_to(tmp_path / "ref"): p.read_bytes() for p in (tmp_path / "ref").rglob("*") if p.is_file()}
    out = tmp_path / "out"
    t0 = time.perf_counter()
    _tables(*args, str(out))
    full = time.perf_counter() - t0
    states, killed = set(), 0
    for k in range(12):
        if k % 2:
            import shutil

            shutil.rmtree(out, ignore_errors=True)  # half of the kills hit a first write
        proc = subprocess.Popen([sys.executable, "-m", "benchmark.commands.tables", *args, str(out)], cwd=ROOT,
                                env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(full * (0.3 + 0.7 * k / 11))
        proc.send_signal(signal.SIGKILL)
        killed += proc.wait() == -signal.SIGKILL
        if out.exists():
            got = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
            assert got == want, f"kill {k}: a partial set"
            states.add("whole")
        else:
            states.add("absent")
    assert killed >= 6  # most runs really were killed before they finished


def test_house_content_follows_the_house_and_the_env_input_files(tmp_path):
    from benchmark.harness.pipeline import house_content
    from envs.world.house import House

    ann = tmp_path / "labels.png"
    ann.write_bytes(b"one")

    class Env:
        name = "fake"
        data = {"rooms": [1]}

        def house(self, hid):
            if hid == "bad":
                raise ValueError("house 'bad': rooms: missing")
            return House(hid, self.data)

        def input_files(self, hid):
            return [ann]

    env = Env()
    first = house_content(env, "h")
    assert house_content(env, "h") == first  # stable
    ann.write_bytes(b"two")
    second = house_content(env, "h")
    assert second != first  # an edited annotation file
    env.data = {"rooms": [2]}
    assert house_content(env, "h") not in (first, second)  # an edited house
    # a malformed house gets the hash of its error (its failure is logged under it)
    assert house_content(env, "bad") == house_content(env, "bad") != house_content(env, "h")
