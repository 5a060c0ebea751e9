"""``python -m benchmark.commands.data`` (issue 29): the catalogue lists what the harness knows,
and a fetch served by a local HTTP server on 127.0.0.1 is verified, resumable and atomic: a good
file lands; a wrong checksum and a truncated transfer leave nothing that looks complete; the
next run resumes a truncated file from where it stopped (an HTTP Range request)."""

from __future__ import annotations

import hashlib
import http.server
import json
import threading
from pathlib import Path

import pytest

from benchmark.commands.data import main
from envs.datasets.download import CATALOGUE, load_catalogue, status

A = bytes(range(256)) * 400  # 102400 bytes
B = b"a second file\n" * 10


class Server:
    """Serves ``files`` (URL path -> bytes) with Range support; ``mode`` ``truncate`` sends
    the full Content-Length but closes after ``cut`` bytes; ``ignore_range`` answers 200."""

    def __init__(self, files):
        self.files, self.mode, self.cut, self.ranges = dict(files), "ok", 0, []
        outer = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self):  # noqa: N802
                body = outer.files.get(self.path)
                if body is None:
                    self.send_error(404)
                    return
                rng = self.headers.get("Range")
                outer.ranges.append(rng)
                start = int(rng.split("=")[1].split("-")[0]) if rng and outer.mode != "ignore_range" else 0
                self.send_response(206 if start else 200)
                if start:
                    self.send_header("Content-Range", f"bytes {start}-{len(body) - 1}/{len(body)}")
                self.send_header("Content-Length", str(len(body) - start))
                self.end_headers()
                part = body[start:]
                if outer.mode == "truncate":
                    part = part[:outer.cut]
                self.wfile.write(part)
                self.wfile.flush()
                if outer.mode == "truncate":
                    self.close_connection = True

            def log_message(self, *args):
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/"
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()

    def close(self):
        self.httpd.shutdown()
        self.httpd.server_close()


@pytest.fixture()
def server():
    s = Server({"/rel/a.bin": A, "/b.txt": B})
    yield s
    s.close()


def catalogue(tmp_path: Path, url: str, sha_a: str | None = None) -> Path:
    sha_a = sha_a or hashlib.sha256(A).hexdigest()
    p = tmp_path / "catalogue.yaml"
    p.write_text(f"""toy:
  title: a toy dataset
  kind: files
  folder: toy
  source: {url}
  licence: MIT
  used_by: this test
  base_url: {url}rel/
  files:
    - {{path: sub/a.bin, url: a.bin, size: {len(A)}, sha256: "{sha_a}"}}
    - {{path: b.txt, url: ../b.txt, size: {len(B)}, sha256: "{hashlib.sha256(B).hexdigest()}"}}
""")
    return p


def run(tmp_path, cat, *args):
    return main(["--root", str(tmp_path / "data"), "--catalogue", str(cat), *args])


def test_a_good_fetch_lands_whole_and_verified(server, tmp_path, capsys):
    cat = catalogue(tmp_path, server.url)
    assert run(tmp_path, cat, "list") == 0
    assert "status:  absent" in capsys.readouterr().out
    assert run(tmp_path, cat, "fetch", "toy", "--no-progress") == 0
    assert "toy: fetched and verified" in capsys.readouterr().out
    folder = tmp_path / "data" / "toy"
    assert (folder / "sub" / "a.bin").read_bytes() == A and (folder / "b.txt").read_bytes() == B
    assert sorted(p.name for p in (tmp_path / "data").iterdir()) == ["toy"]  # no staging left
    assert run(tmp_path, cat, "list", "--verify") == 0 and "status:  present" in capsys.readouterr().out
    n = len(server.ranges)
    assert run(tmp_path, cat, "fetch", "toy", "--no-progress") == 0  # present: nothing downloaded again
    assert "already present, verified" in capsys.readouterr().out and len(server.ranges) == n
    # a damaged file is found by --verify and fetched again
    (folder / "b.txt").write_bytes(B[::-1])
    assert run(tmp_path, cat, "list", "--verify") == 1
    cap = capsys.readouterr()
    assert "damaged (b.txt" in cap.out and "verify:  FAILED" in cap.out and "toy" in cap.err
    assert run(tmp_path, cat, "fetch", "toy", "--no-progress") == 0
    assert (folder / "b.txt").read_bytes() == B and len(server.ranges) == n + 1  # only the damaged file


def test_a_wrong_checksum_leaves_nothing(server, tmp_path, capsys):
    cat = catalogue(tmp_path, server.url, sha_a="0" * 64)
    assert run(tmp_path, cat, "fetch", "toy", "--no-progress") == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "a.bin" in err and "expected" in err and "0" * 64 in err
    assert not (tmp_path / "data" / "toy").exists()
    assert not list((tmp_path / "data").rglob("*.part"))  # the bad file is removed, not kept for a resume
    assert status(load_catalogue(cat)["toy"], tmp_path / "data") == "absent"


def test_a_truncated_transfer_resumes(server, tmp_path, capsys):
    cat = catalogue(tmp_path, server.url)
    server.mode, server.cut = "truncate", 40000
    assert run(tmp_path, cat, "fetch", "toy", "--no-progress") == 2
    err = capsys.readouterr().err
    assert "a.bin" in err and "40000 of 102400 bytes" in err and "resume" in err
    assert not (tmp_path / "data" / "toy").exists()  # nothing that looks complete
    parts = list((tmp_path / "data").rglob("a.bin.part"))
    assert len(parts) == 1 and parts[0].stat().st_size == 40000
    server.mode = "ok"
    assert run(tmp_path, cat, "fetch", "toy", "--no-progress") == 0
    assert server.ranges[-2:] == ["bytes=40000-", None]  # a.bin resumed, b.txt from the start
    assert (tmp_path / "data" / "toy" / "sub" / "a.bin").read_bytes() == A


def test_a_server_that_ignores_range_starts_over(server, tmp_path, capsys):
    cat = catalogue(tmp_path, server.url)
    server.mode, server.cut = "truncate", 1000
    assert run(tmp_path, cat, "fetch", "toy", "--no-progress") == 2
    server.mode = "ignore_range"
    assert run(tmp_path, cat, "fetch", "toy", "--no-progress") == 0
    assert (tmp_path / "data" / "toy" / "sub" / "a.bin").read_bytes() == A  # not the prefix twice


def test_bad_names_and_no_server(tmp_path, capsys):
    cat = catalogue(tmp_path, "http://127.0.0.1:9/")  # the discard port: nothing listens
    assert run(tmp_path, cat, "fetch", "nope") == 2
    assert "no dataset 'nope'; known: toy" in capsys.readouterr().err
    assert run(tmp_path, cat, "fetch", "toy", "--no-progress", "--timeout", "5") == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "127.0.0.1:9" in err
    bad = tmp_path / "bad.yaml"
    bad.write_text("toy:\n  title: t\n  kind: zip\n  source: s\n  licence: l\n  used_by: u\n")
    assert run(tmp_path, bad, "list") == 2 and "kind 'zip'" in capsys.readouterr().err


def test_the_catalogue_matches_the_shared_data():
    """Every file the catalogue lists for the shared data has that size and checksum in the copy
    the tests use (skipped where the shared data is absent)."""
    from tests.conftest import SHARED_DATA

    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data not found at {SHARED_DATA}")
    cat = load_catalogue(CATALOGUE)
    assert {"procthor_shared", "selros", "procthor_10k", "architecthor"} <= set(cat)
    for name in ("procthor_shared", "selros"):
        assert status(cat[name], SHARED_DATA, verify=True) == "present", name
    on_disk = {p.relative_to(SHARED_DATA / "selros").as_posix() for p in (SHARED_DATA / "selros").rglob("*")
               if p.is_file()}
    assert on_disk == {f.path for f in cat["selros"].files}


def test_commands_say_how_to_get_absent_data(tmp_path, capsys):
    """make bench says in one line that the shared houses are absent and how to get them; table5
    says where the SeLRoS release should be and how to fetch it (exit 2)."""
    import shutil
    import subprocess

    from benchmark.commands.selros import main as table5

    assert table5(["--data", str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err
    assert "data fetch selros" in err and str(tmp_path / "nowhere") in err
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    root = Path(__file__).resolve().parents[1]
    dry = subprocess.run(["make", "-n", "bench", f"SHARED={tmp_path / 'nowhere'}"], cwd=root, capture_output=True,
                         text=True).stdout
    hint = [line for line in dry.splitlines() if "data fetch procthor_shared" in line]
    assert len(hint) == 1 and "env=synthetic " in dry
    (tmp_path / "here" / "procthor").mkdir(parents=True)
    (tmp_path / "here" / "procthor" / "x.jsonl.gz").write_bytes(b"")
    dry = subprocess.run(["make", "-n", "bench", f"SHARED={tmp_path / 'here'}"], cwd=root, capture_output=True,
                         text=True).stdout
    assert "data fetch" not in dry and "env=synthetic,procthor_shared" in dry


def test_root_after_the_subcommand_and_verify_says_what_it_checked(server, tmp_path, capsys):
    """``data fetch NAME --root DIR`` (as hints type it) works like ``data --root DIR fetch NAME``;
    ``list --verify`` prints what it verified (not what ``list`` prints) and exits 1 on damage."""
    cat = catalogue(tmp_path, server.url)
    root = tmp_path / "elsewhere"
    assert main(["--catalogue", str(cat), "fetch", "toy", "--root", str(root), "--no-progress"]) == 0
    assert (root / "toy" / "b.txt").read_bytes() == B
    assert main(["--catalogue", str(cat), "list", "--root", str(root)]) == 0
    plain = capsys.readouterr().out
    assert main(["--catalogue", str(cat), "list", "--verify", "--root", str(root)]) == 0
    verified = capsys.readouterr().out
    assert verified != plain and "verify:  2 of 2 files match" in verified and "verify:" not in plain
    (root / "toy" / "sub" / "a.bin").write_bytes(A[:-1] + b"x")  # same size, other bytes
    assert main(["--catalogue", str(cat), "list", "--root", str(root)]) == 0  # sizes only: not seen
    assert main(["--catalogue", str(cat), "list", "--verify", "--root", str(root)]) == 1
    cap = capsys.readouterr()
    assert "damaged (sub/a.bin" in cap.out and len(cap.err.strip().splitlines()) == 1
    (root / "toy" / "b.txt").unlink()
    assert main(["--catalogue", str(cat), "list", "--verify", "--root", str(root)]) == 1  # partial
    assert "partial (1 of 2 files)" in capsys.readouterr().out


def test_an_absent_dataset_is_one_line_with_a_fetch_command_that_parses(tmp_path, capsys, monkeypatch):
    """``env=procthor_shared`` with the houses absent: one line naming the file and the command
    that fetches them, exit 2, nothing written; the command in the hint parses as typed."""
    import shlex

    from benchmark.commands import bench
    from benchmark.commands.data import parser

    monkeypatch.setenv("ROOMSEG_SHARED_DATA", str(tmp_path / "nowhere"))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("sys.argv", ["roomseg-bench", "env=procthor_shared", "run.limit=1",
                                     f"run.results_dir={tmp_path / 'res'}", "run.name=t"])
    assert bench.main() == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert "procthor-10k-uniform-hard-val.jsonl.gz is absent" in err[0] and "data fetch procthor_shared" in err[0]
    assert not list((tmp_path / "res").rglob("metrics.csv"))
    words = shlex.split(err[0].split("get it with: ")[1])
    assert words[1:3] == ["-m", "benchmark.commands.data"]
    a = parser().parse_args(words[3:])  # exits 2 on an unrecognized argument
    assert a.cmd == "fetch" and a.names == ["procthor_shared"] and a.root == tmp_path / "nowhere"


# ---------------------------------------------------------------- the catalogue checks its own fields (issue 38, item 6)
@pytest.mark.parametrize("folder", ["../../outside", "..", "/tmp/abs", "a/b", ".hidden", "a\\b", ""])
def test_a_folder_outside_the_data_root_is_refused_before_any_fetch(server, tmp_path, capsys, folder):
    # before: folder ../../outside fetched the data outside the root and left a stray folder in it
    cat = catalogue(tmp_path, server.url)
    cat.write_text(cat.read_text().replace("  folder: toy\n", f"  folder: {json.dumps(folder)}\n"))
    (tmp_path / "deep" / "er").mkdir(parents=True)
    root = tmp_path / "deep" / "er" / "data"
    before = sorted(p for p in tmp_path.rglob("*"))
    for args in (["fetch", "toy", "--no-progress"], ["list"]):
        assert main(["--root", str(root), "--catalogue", str(cat), *args]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and str(cat) in err and "dataset 'toy'" in err, err
        assert ("folder" in err and "needs folder" in err) if folder == "" else f"folder {folder!r}" in err, err
    assert sorted(p for p in tmp_path.rglob("*")) == before  # nothing fetched, no stray folder anywhere


@pytest.mark.parametrize("text,what", [("- toy\n- other\n", "expected a mapping of dataset names to entries, got a list"),
                                       ("toy: just a string\n", "dataset 'toy': expected a mapping of fields, got a string"),
                                       ("just a string\n", "got a string")])
def test_a_catalogue_of_the_wrong_shape_is_one_line(tmp_path, capsys, text, what):
    # before: a catalogue that is a YAML list was an AttributeError traceback
    cat = tmp_path / "catalogue.yaml"
    cat.write_text(text)
    assert main(["--root", str(tmp_path / "data"), "--catalogue", str(cat), "list"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(cat) in err and what in err, err
