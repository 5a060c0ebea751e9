"""The runner of a page's command blocks (``python -m benchmark.commands.maintainer.docs run-blocks``), and
the getting-started page run through it from a fresh copy of the working tree."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pandas as pd
import pytest

from benchmark.commands import docs

ROOT = Path(__file__).resolve().parents[1]

PAGE = """# A page

```bash
echo one
```

1. In a list:

    ```bash
    echo "two \\
      continued"
    ```

~~~bash
echo three
~~~

```python
print("python is not run")
```

````markdown
```bash
echo "inside a longer fence: an example of markdown, not a block"
```
````

```Bash
echo four
```
"""


def test_blocks_are_found_in_order_with_their_lines():
    found = docs.blocks(PAGE)
    assert [b.code for b in found] == ['echo one\n', 'echo "two \\\n  continued"\n', "echo three\n", "echo four\n"]
    lines = PAGE.splitlines()
    assert [lines[b.line - 1].strip() for b in found] == ["echo one", 'echo "two \\', "echo three", "echo four"]
    assert [b.lang for b in docs.blocks(PAGE, lang=None)] == ["bash", "bash", "bash", "python", "markdown", "bash"]


def test_continued_lines_are_one_command_and_skips_replace_whole_commands(tmp_path):
    assert docs._commands("a \\\n  b\nc\n") == ["a \\\n  b", "c"]
    script = docs.block_script(docs.Block(3, "bash", "make setup\nmake test   # all of it\nmake test-fast\n"), 1,
                               [("^make test( |$)", "CI runs it")])
    assert "echo 'skipped: make test (CI runs it)'" in script
    assert "\nmake setup\n" in script and "\nmake test-fast\n" in script


def _page(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "page.md"
    p.write_text(text, encoding="utf-8")
    return p


def _fake_venv(folder: Path) -> Path:
    """A folder laid out as a virtual environment whose ``bin`` holds a ``roomseg``; returns its ``bin``."""
    (folder / "bin").mkdir(parents=True)
    (folder / "pyvenv.cfg").write_text("home = /usr/bin\n")
    tool = folder / "bin" / "roomseg"
    tool.write_text("#!/bin/sh\necho from the venv\n")
    tool.chmod(0o755)
    return folder / "bin"


def test_each_block_runs_in_a_new_clean_shell_in_a_fresh_copy(tmp_path, capsys, monkeypatch):
    """A user opens a new shell at a section: nothing a block sets, activates or changes to
    holds for the next (only its files), and no virtual environment is on PATH, neither the
    active one nor a ``.venv`` or other environment's ``bin`` that PATH names without it."""
    active, named, other = (_fake_venv(tmp_path / "active"), _fake_venv(tmp_path / "proj" / ".venv"),
                            _fake_venv(tmp_path / "env2"))
    monkeypatch.setenv("VIRTUAL_ENV", str(active.parent))
    monkeypatch.setenv("PATH", os.pathsep.join([str(active), str(named), str(other) + "/", os.environ["PATH"]]))
    monkeypatch.setenv("PYTHONPATH", "/somewhere")
    page = _page(tmp_path, """
```bash
test -f Makefile -a -f benchmark/commands/maintainer/docs.py   # the copy holds the tree's files
test ! -e .venv -a ! -e results/runs                 # and nothing git ignores
test -z "${PYTHONPATH:-}" -a -z "${VIRTUAL_ENV:-}"   # a clean shell
! command -v roomseg                                 # no environment's tools on PATH
test "$(pwd)" != "$ROOT_OF_TREE"
GREETING=hello
export FAREWELL=bye
mkdir -p sub && cd sub
```

```bash
echo "${GREETING:-unset} ${FAREWELL:-unset} $WHO" > greeting.txt   # a new shell, in the copy's root
make test
```
""")
    work = tmp_path / "clone"
    rc = docs.run_blocks(page, workdir=work, env={"WHO": "world", "ROOT_OF_TREE": str(ROOT)},
                         skips=[("^make test( |$)", "not here")])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert (work / "greeting.txt").read_text() == "unset unset world\n"
    assert "block 1 (line 3): ok" in out and "block 2 (line 14): ok" in out and "every block ran" in out
    assert (work / "README.md").read_bytes() == (ROOT / "README.md").read_bytes()
    # a block that activates its environment has its tools; the next block, a new shell, does not
    page = _page(tmp_path, f"```bash\nsource {active.parent}/bin/activate\nroomseg\n```\n\n```bash\nroomseg\n```\n")
    (active / "activate").write_text(f'export PATH="{active}:$PATH"\n')
    assert docs.run_blocks(page) == 1
    out = capsys.readouterr().out
    assert "block 1 (line 2): ok" in out and "block 2 (line 7): FAILED (exit status 127)" in out


def test_a_failing_command_stops_the_session_naming_its_block(tmp_path, capsys):
    page = _page(tmp_path, "```bash\ntrue\n```\n\ntext\n\n```bash\necho before\nfalse\necho after > after.txt\n```\n\n"
                           "```bash\necho never > never.txt\n```\n")
    work = tmp_path / "clone"
    assert docs.run_blocks(page, workdir=work) == 1
    out = capsys.readouterr().out
    assert "block 2 (line 8): FAILED (exit status 1)" in out and "stopped" in out and "block 3" not in out
    assert not (work / "after.txt").exists() and not (work / "never.txt").exists()
    # a failing command inside a pipeline fails too (pipefail)
    page = _page(tmp_path, "```bash\nfalse | cat\n```\n")
    assert docs.run_blocks(page) == 1


def test_bad_input_is_one_line_and_exit_status_2(tmp_path, capsys):
    assert docs.main(["run-blocks", str(tmp_path / "nope.md")]) == 2
    assert "nope.md: no such file" in capsys.readouterr().err
    page = _page(tmp_path, "no blocks here\n")
    assert docs.main(["run-blocks", str(page)]) == 2
    assert "no ```bash block to run" in capsys.readouterr().err
    full = tmp_path / "full"
    full.mkdir()
    (full / "x").write_text("x")
    page = _page(tmp_path, "```bash\ntrue\n```\n")
    assert docs.main(["run-blocks", str(page), "--workdir", str(full)]) == 2
    assert "not empty" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        docs.main(["run-blocks", str(page), "--skip", "no-reason"])


@pytest.mark.slow
def test_every_block_of_getting_started_runs_from_a_fresh_copy(tmp_path, capsys):
    """The page as a user types it, from a fresh copy of the tree. ``make setup`` finds a light
    ``.venv`` over this interpreter's packages (the copy's code first); ``make test`` is skipped:
    it is this test suite (CI runs the page with a real ``make setup`` after the suite)."""
    work = tmp_path / "clone"
    rc = docs.run_blocks(ROOT / "docs" / "getting-started.md", workdir=work, env={"BENCH_HOUSES": "2"},
                         skips=[("^make test( |$)", "the test suite itself, run by CI")], venv_from=sys.executable)
    out = capsys.readouterr().out
    assert rc == 0, out
    for f in ("table3.md", "table4.md", "all.md", "report.html"):
        assert (work / "results" / "bench" / f).is_file(), f
    jobs = sorted((work / "results" / "runs" / "first").glob("*/metrics.csv"))
    assert len(jobs) == 4
    rows = pd.concat(pd.read_csv(j) for j in jobs)
    assert len(rows) == 20 and (rows["status"] == "ok").all() and set(rows["classifier"]) == {"oracle"}
    assert (work / "results" / "first" / "report.html").is_file()


@pytest.mark.slow
def test_own_robot_data_blocks_run_and_its_results_table_is_what_they_wrote(tmp_path, capsys):
    """Every block of the page (a folder of maps as an environment, roomseg-segment and its
    variants on the example building), then the page's results table against the
    ``scores.json`` each command wrote."""
    import json

    page = ROOT / "docs" / "own-robot-data.md"
    work = tmp_path / "clone"
    rc = docs.run_blocks(page, workdir=work, venv_from=sys.executable)
    out = capsys.readouterr().out
    assert rc == 0, out
    rows = [line for line in page.read_text(encoding="utf-8").splitlines() if line.startswith("| `results/example/")]
    assert len(rows) == 6
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        folder = cells[0].strip("`")
        scores = json.loads((work / folder / "scores.json").read_text())
        assert int(cells[2]) == scores["n_pred_segments"], folder
        for cell, key in zip(cells[3:7], ("iou", "precision", "recall", "accuracy")):
            got = scores.get(key)
            if cell == "–":
                assert got is None or got != got, (folder, key, got)  # no classes: NaN / null
            else:
                assert float(cell) == round(100 * got, 1), (folder, key, cell, got)
    jobs = sorted((work / "results" / "runs" / "my_maps").glob("*/metrics.csv"))
    assert len(jobs) == 3
    df = pd.concat(pd.read_csv(j) for j in jobs)
    assert (df["status"] == "ok").all() and len(df) == 3


def test_a_block_that_needs_the_environment_activates_it_itself():
    """The page check: a block runs in a new shell, so an activation in an earlier block does
    not count; a tool anywhere in a pipeline or list needs it; ``.venv/bin/...`` needs nothing."""
    page = ("```bash\nsource .venv/bin/activate   # in each new shell\nroomseg-segment map.yaml\n```\n\n"
            "```bash\nroomseg tables results/runs/first --out results/first\n"
            "cd results && python -c \"import a; print('|')\" | head\n"
            "time roomseg-bench run.limit=1 || echo \"exit status $?\"\n"
            ".venv/bin/roomseg report results/runs/first --out results/first/report.html\n"
            "echo 'python is text here; roomseg too'\n```\n\n"
            "```bash\nmake bench && source .venv/bin/activate\npytest -q\n```\n")
    probs = docs.page_problems(page)
    assert [p.split(":")[0] for p in probs] == ["line 7", "line 8", "line 9"], probs
    assert all("start its block with `source .venv/bin/activate`" in p for p in probs)


def test_every_page_and_the_readme_follow_the_convention():
    """Every block of every docs page and of the README that runs the project's tools starts
    with ``source .venv/bin/activate``: the page check finds nothing."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    problems = [f"{p.relative_to(ROOT)} {line}" for p in pages for line in docs.page_problems(p.read_text(encoding="utf-8"))]
    assert problems == []
