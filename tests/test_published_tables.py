"""The writers of the tables the docs include (results/published/, make docs-numbers): the
objects-accuracy command's training sets and interval, the sweep-table command's refusals, and
the published file's header. The files themselves are checked against their commands in
tests/test_docs_numbers.py (slow)."""

from __future__ import annotations

import numpy as np
import pytest

from benchmark.commands import objects_accuracy
from benchmark.commands.maintainer import sweep_table
from benchmark.reports.published import write_published


def test_a_training_set_is_shared_houses_or_generated_seeds():
    t = objects_accuracy.training_set("0:75")
    assert (t.houses, t.seeds) == ((0, 75), None)
    assert t.words() == "shared ProcTHOR houses 0-74"
    g = objects_accuracy.training_set("generated:100000:100200")
    assert (g.houses, g.seeds) == (None, (100000, 100200))
    assert g.words() == "200 generated houses (seeds 100000-100199)"
    old = objects_accuracy.training_set("0:0", synthetic=(5, 7))  # the old --train 0:0 --synthetic 5 7
    assert (old.houses, old.seeds) == (None, (5, 7))
    both = objects_accuracy.training_set("0:10", synthetic=(5, 7))
    assert both.words() == "shared ProcTHOR houses 0-9 + 2 generated houses (seeds 5-6)"
    for bad, words in (("0:x", "expected a range A:B"), ("5:2", "0 <= A <= B"), ("0:0", "at least one house"),
                       ("generated:3:3", "at least one seed"), ("generated:3", "expected a range A:B")):
        with pytest.raises(ValueError, match=words):
            objects_accuracy.training_set(bad)


def test_a_bad_training_set_is_one_line(capsys):
    assert objects_accuracy.main(["--train", "0:x"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: --train '0:x': expected a range A:B of whole numbers"]


def test_the_pooled_accuracy_and_its_interval_over_houses():
    # every house at 50 %: the interval is the point
    assert objects_accuracy._pooled_with_interval(np.array([5, 10]), np.array([10, 20])) == "50.0 [50.0, 50.0]"
    # one house: no interval (it would be made up)
    assert objects_accuracy._pooled_with_interval(np.array([3]), np.array([4])) == "75.0"
    # pooled over views, not a mean of house shares: (0 + 30) / (10 + 30) = 75 %; the interval
    # holds the two extremes a resample can give (0 % with house 1 alone, 100 % with house 2 alone)
    text = objects_accuracy._pooled_with_interval(np.array([0, 30]), np.array([10, 30]))
    mean, lo, hi = (float(v) for v in text.replace("[", "").replace(",", "").replace("]", "").split())
    assert mean == 75.0 and 0.0 <= lo < mean < hi <= 100.0


def test_the_sweep_table_command_refuses_a_results_dir_of_its_own(tmp_path, capsys):
    out = tmp_path / "t.md"
    assert sweep_table.main(["experiment=sensitivity", "run.results_dir=/elsewhere", "--table", "sensitivity",
                             "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'run.results_dir=/elsewhere'" in err[0]
    assert not out.exists()
    with pytest.raises(SystemExit) as e:
        sweep_table.main(["experiment=sensitivity", "--table", "table9", "--out", str(out)])
    assert e.value.code == 2


def test_a_published_file_is_the_header_then_the_text(tmp_path):
    out = tmp_path / "x.md"
    assert write_published(out, "python -m benchmark.commands.x --out x.md", "| a |\n|---|\n\n") is None
    assert out.read_text(encoding="utf-8") == "Written by `python -m benchmark.commands.x --out x.md`.\n\n| a |\n|---|\n"
    (tmp_path / "a_file").write_text("", encoding="utf-8")
    err = write_published(tmp_path / "a_file" / "x.md", "c", "t")  # a folder that is a file
    assert err is not None and err.startswith("cannot write ") and "a_file" in err  # the path that failed
