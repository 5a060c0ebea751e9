"""The scaling benchmark command: its memory probe against processes of known size, and a
tiny run that prints the table (rows identical across worker counts). No timed assertions."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest
from procs import NEEDS_PROC, wait_for

from benchmark.commands.maintainer.scaling import (
    PeakMemory,
    _descendants_by_children,
    _proc_table,
    descendants,
    main,
    tree_memory,
)

ROOT = Path(__file__).resolve().parents[1]


@NEEDS_PROC
def test_tree_memory_sums_a_process_tree_of_known_size(tmp_path):
    """A parent and its forked child, each touching 150 MB of its own: the tree's PSS is at
    least 300 MB and counts both processes; a shared 150 MB block (touched before the fork)
    is counted once in PSS and twice in RSS."""
    code = textwrap.dedent(f"""\
        import os, time
        shared = bytearray(150 * 2**20)          # touched (zeroed) by the parent, shared after fork
        if os.fork() == 0:
            own = bytearray(150 * 2**20)
            open({str(tmp_path / 'child')!r}, 'w').write('ready')
            time.sleep(60)
            os._exit(0)
        own = bytearray(150 * 2**20)
        open({str(tmp_path / 'parent')!r}, 'w').write('ready')
        time.sleep(60)
        """)
    p = subprocess.Popen([sys.executable, "-c", code])
    try:
        assert wait_for(lambda: (tmp_path / "child").exists() and (tmp_path / "parent").exists(), timeout=60)
        pss, rss, n = tree_memory(p.pid)
        assert n == 2 and len(descendants(p.pid)) == 2
        # the tree from the children files is the tree from every process's parent
        kids = [c for c, parent in _proc_table().items() if parent == p.pid]
        assert len(kids) == 1 and sorted(_descendants_by_children(p.pid)) == sorted([p.pid, *kids])
        mb = 2**20
        assert 450 * mb <= pss < 600 * mb, pss / mb  # own 150 x 2 + shared 150 once (+ two interpreters)
        assert rss - pss > 120 * mb, (rss / mb, pss / mb)  # the shared block counted in both RSS
    finally:
        for pid in descendants(p.pid)[::-1]:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        p.wait()


@NEEDS_PROC
def test_the_memory_sampler_runs_at_the_lowest_priority():
    """The sampler thread is niced to 19 (its reads of smaps_rollup cost CPU the measured run
    would otherwise lose); the process's own priority is left as it was."""
    import threading

    before = os.getpriority(os.PRIO_PROCESS, 0)
    peak = PeakMemory(os.getpid(), every=0.05)
    try:
        assert wait_for(lambda: peak.procs >= 1, timeout=30)
        tid = peak._thread.native_id
        fields = Path(f"/proc/self/task/{tid}/stat").read_text().rsplit(")", 1)[1].split()
        assert int(fields[16]) == 19  # field 19 of stat: nice
        assert os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) == before
    finally:
        peak.stop()
    assert peak.pss > 0 and peak.rss >= peak.pss


@pytest.mark.slow
def test_a_tiny_scaling_run_prints_the_table(tmp_path, capsys):
    out = tmp_path / "scaling.md"
    # (the sampler at normal priority: at nice 19 a busy machine may starve it through a 3-house run)
    code = main(["--houses", "3", "--workers", "1", "2", "--work", str(tmp_path / "w"), "--out", str(out), "--sample-nice", "0",
                 "env.resolution=0.1", "viewpoints.spacing=1.0"])
    printed = capsys.readouterr().out
    assert code == 0, printed
    table = pd.read_csv(out.with_suffix(".csv"))
    assert table["workers"].tolist() == [1, 2] and (table["houses"] == 3).all()
    assert (table["rows identical"] == "yes").all() and (table["computed"] == 3).all()
    assert (table["wall s"] > 0).all() and (table["render ms"] > 0).all() and (table["score ms"] > 0).all()
    if sys.platform.startswith("linux"):
        assert table["processes"].tolist() == [1, 3]  # the driver; the driver and its 2 workers
        assert (table["peak PSS MB"] > 50).all()
    text = out.read_text()
    assert "rows identical" in printed and "peak PSS MB" in text
    # the file says when, where and by which command (docs include it as it is: results/published/scaling.md)
    first = text.splitlines()[0]
    assert first.startswith("Measured on ") and " cores" in first and "--houses 3 --workers 1 2" in first


def test_perf_writes_its_tables_with_where_and_when(tmp_path, capsys):
    """make perf-publish's file: the tables under a line with the date, machine, commit and command
    (the docs include it as it is)."""
    from benchmark.commands.maintainer.perf import main as perf

    out = tmp_path / "perf.md"
    args = ["--houses", "0", "--robot-houses", "0", "--synthetic", "1", "--resolutions", "0.1",
            "--cone-ref-views", "3", "--out", str(out)]
    assert perf(args) == 0
    text = out.read_text()
    first = text.splitlines()[0]
    assert first.startswith("Measured on ") and " cores" in first and "--synthetic 1 --resolutions 0.1" in first
    assert "graph KNN ms" in text and "KNN identical" in text
    # the cone's floor: its votes are the same pairs, so the row says identical
    row = [ln for ln in text.splitlines() if ln.startswith("| synthetic")][0].split("|")
    head = [h.strip() for h in text.splitlines()[2].split("|")]
    assert row[head.index("floor identical")].strip() == "True" and float(row[head.index("cone / floor")]) > 0
    assert "Medians over houses" in text and "graph KNN ms" in capsys.readouterr().out


def test_perf_times_a_ratios_two_sides_in_turn():
    """The cone and its floor are timed one call each per round, the order reversed every other
    round, and each side keeps its best round: on a clock that runs slow in the middle rounds,
    both sides keep a round from the fast ones."""
    import benchmark.commands.maintainer.perf as perf

    clock, calls = [0.0], []
    cost = {"a": [5, 9, 9, 9, 3], "b": [2, 9, 9, 9, 6]}  # seconds per call, round by round

    def side(name):
        def fn(x):
            calls.append((name, x))
            clock[0] += cost[name][sum(1 for c in calls if c[0] == name) - 1]
        return fn

    best = perf._timed_together([(side("a"), 1), (side("b"), 2)], repeat=5, clock=lambda: clock[0])
    assert best == [3.0, 2.0]
    assert [c[0] for c in calls] == ["a", "b", "b", "a", "a", "b", "b", "a", "a", "b"]
    assert all(x == (1 if name == "a" else 2) for name, x in calls)


@pytest.mark.slow
def test_perf_segment_memory_measures_each_size_in_its_own_process(tmp_path):
    """make perf's large-map rows: roomseg-segment run on two example buildings, each peak
    is the child's own (at least the size of its map arrays, far below the parent's), the
    marginal bytes per pixel and the 16000^2 extrapolation on the last row."""
    from benchmark.commands.maintainer.perf import run_segment_memory

    df = run_segment_memory([2, 4], tmp_path)
    assert list(df["pixels"]) == [420 ** 2, 820 ** 2]  # 10 m rooms at 0.05 m/px, 0.1 m outer walls
    assert (df["peak RSS MB"] > 50).all() and df["peak RSS MB"].iloc[1] > df["peak RSS MB"].iloc[0]
    last = df.iloc[-1]
    assert last["B/px (marginal)"] > 1 and last["16000^2 px extrapolated GB"] > last["peak RSS MB"] / 1024
    assert (tmp_path / "rooms4" / "segmented" / "labels.png").exists()


def test_perf_segment_memory_note_says_measured_or_extrapolated():
    """The large-map caption: measured when a row reaches 16000^2 px (its peak in GB), else
    extrapolated (and says how to measure it)."""
    import pandas as pd

    from benchmark.commands.maintainer.perf import segment_memory_note

    big = pd.DataFrame({"pixels": [64320400, 256640400], "peak RSS MB": [1532.0, 5294.2]})
    assert segment_memory_note(big).endswith("measured at 256640400 px: 5.55 GB.")
    small = pd.DataFrame({"pixels": [16160400, 64320400], "peak RSS MB": [659.0, 1532.0],
                          "16000^2 px extrapolated GB": [float("nan"), 5.3]})
    assert "extrapolated from the two largest maps, not run at that size" in segment_memory_note(small)
