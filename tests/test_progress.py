"""Per-job progress: a bar only on a terminal with no job beside it; labels in words."""

from __future__ import annotations

import io

from benchmark.harness.progress import house_progress, job_label


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_job_label_in_words():
    names = {"env": "synthetic", "classifier": "oracle", "aggregator": "vision_cone", "postprocess": "default",
             "segmenter": ""}
    assert job_label(names, 0.8) == "synthetic · oracle 80% · vision cone · post"
    assert job_label({"env": "procthor_shared", "segmenter": "voronoi"}) == "procthor_shared · voronoi"
    assert len(job_label(names, 0.8, width=20)) == 20


def test_bar_only_on_a_terminal_for_a_job_running_alone():
    assert house_progress("x", stream=io.StringIO(), workers=1) is None      # a log file: no bar
    assert house_progress("x", stream=_Tty(), workers=2) is None             # parallel workers: no bar
    assert house_progress("x", enabled=False, stream=_Tty(), workers=1) is None
    tty = _Tty()
    wrap = house_progress("synthetic · objects", stream=tty, workers=1)
    assert list(wrap(range(3))) == [0, 1, 2]
    out = tty.getvalue()
    assert "synthetic · objects" in out and "3/3" in out
    assert out.count("\n") == 1  # one line per job, left on screen


def test_bar_over_a_stream_of_finished_houses_knows_its_total():
    """A pool's houses arrive as they finish (a generator without a length): the bar is
    given the job's house count and ends at n/n."""
    tty = _Tty()
    wrap = house_progress("synthetic · oracle", stream=tty, workers=1)
    assert list(wrap((h for h in "abcd"), total=4)) == list("abcd")
    assert "4/4" in tty.getvalue()
