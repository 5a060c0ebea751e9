"""``python -m benchmark.commands.maintainer.grid_profile``: where a sweep's time went, per
condition family and stage.

Reads a finished sweep folder (``results/runs/robustness``): each job's ``summary.json``
(its wall time), ``job.json`` (its condition and dataset) and ``timings.csv`` (per house, the
seconds of each stage the pipeline timed: ``t_scene`` builds the house, ``t_slam`` solves the
SLAM estimate a robot's map is built at, ``t_map`` builds that map, ``t_viewpoints``,
``t_render``, ``t_classify``, ``t_transform`` (the view transforms a method's views go
through: pose error, label noise), ``t_aggregate``, ``t_postprocess``, ``t_score``). For each dataset and condition family (``scan``, ``slam``, ``explore``, ...) it
prints one row:

- jobs and house-runs (computed / read from the results cache);
- job-seconds: the sum of the jobs' wall times, and its share of the sweep's total;
- per stage, seconds summed over the houses computed;
- ``in houses, untimed s``: time inside the houses computed that no stage timer covers, summed:
  cache entries read, checked and written (the score row, the raw label map, the classification,
  the map and its estimate, their locks and content keys), the row's view-accuracy, coverage and
  map columns, the ground truth brought to a SLAM map's frame;
- ``outside houses s``: job wall time not spent inside a house (composing the job, loading the
  houses, writing and checking rows), summed over jobs.

Job-seconds are wall seconds of one job each; with W workers the sweep's wall time is about
their sum over W. A row ``all`` closes each dataset. With ``--time`` (GNU time's ``-f "%e %M"``
of the whole command, ``--command`` naming it) the table is preceded by the command's wall time
and peak memory, the machine, the houses per dataset and the 5-minute load average at its end
(its own workers included; ``make robustness-timing-publish``); with ``--rerun-time`` (GNU time's
``-f "%e %M %U %S"`` of the sweep run again at once on the cache it filled) a line on the jobs'
fixed cost follows it. Exit status 2 when the folder holds no job or a time file is unreadable.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import pandas as pd

from benchmark.commands import cli

#: stages in pipeline order (others follow alphabetically)
STAGES = ("t_scene", "t_slam", "t_map", "t_viewpoints", "t_coverage", "t_render", "t_render_load", "t_classify",
          "t_transform", "t_aggregate", "t_postprocess", "t_segment", "t_score")


def job_rows(sweep: Path) -> pd.DataFrame:
    """One row per job of ``sweep`` that finished: ``dataset``, ``family``, ``wall_s``,
    ``computed``, ``cached``, ``houses_s`` (seconds inside houses) and one column per stage
    (seconds summed over the houses computed).

    Raises:
        FileNotFoundError: no finished job under ``sweep``.
        ValueError: one line naming a job's malformed ``summary.json`` or config."""
    from benchmark.harness.store import find_jobs

    rows = []
    for job in find_jobs([sweep]):
        s, settings = job.summary(), job.settings() or {}
        t = pd.read_csv(job.timings_path) if job.timings_path.is_file() else pd.DataFrame()
        fresh = t[~t["cached"].astype(bool)] if len(t) else t
        row = {"dataset": settings.get("env.name", "?"), "family": settings.get("robot.corruption", "clean"),
               "wall_s": float(s.get("wall_time_s", 0.0)), "computed": len(fresh), "cached": len(t) - len(fresh),
               "houses_s": float(t["house_s"].sum()) if len(t) else 0.0}
        stage_cols = [c for c in t.columns if c.startswith("t_")]
        for c in stage_cols:
            row[c] = float(fresh[c].sum())
        # inside computed houses but in no timed stage (view transforms, cache reads)
        row["untimed_s"] = (float(fresh["house_s"].sum()) - float(fresh[stage_cols].fillna(0).to_numpy().sum())
                            if len(fresh) else 0.0)
        rows.append(row)
    return pd.DataFrame(rows)


def profile(jobs: pd.DataFrame) -> pd.DataFrame:
    """Per dataset and family (and ``all`` per dataset): the table the command prints."""
    stages = [c for c in STAGES if c in jobs] + sorted(c for c in jobs if c.startswith("t_") and c not in STAGES)
    total = jobs["wall_s"].sum()
    out = []
    for dataset, d in jobs.groupby("dataset", sort=True):
        groups = sorted(d.groupby("family"), key=lambda kv: -kv[1]["wall_s"].sum())
        for family, g in [*groups, ("all", d)]:
            row = {"dataset": dataset, "family": family, "jobs": len(g), "houses computed": int(g["computed"].sum()),
                   "houses cached": int(g["cached"].sum()), "job s": g["wall_s"].sum(),
                   "share %": 100 * g["wall_s"].sum() / total if total else 0.0}
            for c in stages:
                row[f"{c[2:]} s"] = g[c].fillna(0).sum()
            row["in houses, untimed s"] = g["untimed_s"].sum()
            row["outside houses s"] = (g["wall_s"] - g["houses_s"]).sum()
            out.append(row)
    return pd.DataFrame(out)


def timing_line(jobs: pd.DataFrame, time_file: Path, command: str, compile_time_file: Path | None = None) -> str:
    """The measured line that heads a timed profile: date, machine, commit, the command's wall
    time and peak RSS (``time_file``: GNU time's ``-f "%e %M"``), its jobs and houses per dataset,
    the 5-minute load average now (the run just ended: its own workers included), and the numba
    compile step's time (``compile_time_file``) when given.

    Raises:
        ValueError: an unreadable time file (one line naming it)."""
    import os

    from benchmark.reports.readme_tables import gnu_time, head_commit, machine

    wall, rss_kb = gnu_time(time_file)
    houses = (jobs["computed"] + jobs["cached"]).groupby(jobs["dataset"]).max()
    per = ", ".join(f"{d} {int(n)}" for d, n in houses.items())
    load = (f"; 5-minute load average {os.getloadavg()[1]:.1f} at its end, its own workers included"
            if hasattr(os, "getloadavg") else "")
    numba = (f"; as on a fresh clone: numba's cache empty before the kernel compile step, which took "
             f"{gnu_time(compile_time_file)[0]:.0f} s" if compile_time_file is not None else "")
    commit = head_commit(Path(__file__).resolve().parents[3])
    return (f"Measured with `/usr/bin/time` on {time.strftime('%Y-%m-%d', time.gmtime())} on {machine()}"
            f"{f' at commit {commit}' if commit else ''}: `{command}` took **{wall:.0f} s wall "
            f"({wall / 60:.1f} min), {rss_kb / 1024:.0f} MB peak RSS** ({len(jobs)} jobs; houses per dataset: {per}; "
            f"from an empty cache{load}{numba}).")


def rerun_line(jobs: pd.DataFrame, rerun_file: Path) -> str:
    """The line on the jobs' fixed cost: the sweep run again at once on the cache it filled
    (``rerun_file``: GNU time's ``-f "%e %M %U %S"``), every row read from that cache, so what it
    takes is what each job costs besides its houses' work: Hydra composing its config and
    setting it up, the job's own set-up and result files (no stage column holds it; the
    ``outside houses`` column only the part inside the app).

    Raises:
        ValueError: an unreadable time file (one line naming it)."""
    from benchmark.reports.readme_tables import gnu_time_cpu

    wall, _, cpu = gnu_time_cpu(rerun_file)
    return (f"Run again at once on the cache it filled (every row read back from it: what its {len(jobs)} jobs cost "
            f"besides their houses' work, composing, setting up, reading the rows back and writing the results), "
            f"the same sweep took {wall:.0f} s wall and {cpu:.0f} CPU-s: about {cpu / max(len(jobs), 1):.2f} "
            f"CPU-s a job.")


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(description=__doc__.split("\n\n")[0].split(": ", 1)[1],
                            epilog="e.g. python -m benchmark.commands.maintainer.grid_profile results/runs/robustness")
    ap.add_argument("sweep", type=Path, help="a sweep's folder (results/runs/<name>)")
    ap.add_argument("--out", type=Path, default=None, help="also write the table here (Markdown)")
    ap.add_argument("--time", type=Path, default=None,
                    help="GNU time's '%%e %%M' output of the command that ran the sweep: its wall time heads the table")
    ap.add_argument("--compile-time", type=Path, default=None,
                    help="GNU time's output of the numba compile step run before it (with --time)")
    ap.add_argument("--command", default="make robustness", help="the timed command, as the heading names it")
    ap.add_argument("--rerun-time", type=Path, default=None,
                    help="GNU time's '%%e %%M %%U %%S' output of the sweep run again at once on the cache it filled "
                         "(with --time): a line on the jobs' fixed cost follows the heading")
    a = ap.parse_args(argv)
    try:
        jobs = job_rows(a.sweep)
    except FileNotFoundError:
        print(f"grid_profile: error: {a.sweep}: no finished job (expected a sweep folder with <job>/summary.json)",
              file=sys.stderr)
        return 2
    except ValueError as e:  # a malformed summary.json or config: one line naming it
        print(f"grid_profile: error: {e}", file=sys.stderr)
        return 2
    try:
        head = "" if a.time is None else timing_line(jobs, a.time, a.command, a.compile_time) + "\n\n"
        if a.time is not None and a.rerun_time is not None:
            head += rerun_line(jobs, a.rerun_time) + "\n\n"
    except ValueError as e:
        print(f"grid_profile: error: {e}", file=sys.stderr)
        return 2
    table = profile(jobs)
    md = table.to_markdown(index=False, floatfmt=".1f")
    note = (f"\n{len(jobs)} jobs, {jobs['wall_s'].sum():.0f} job-seconds. Stage columns: seconds summed over the "
            f"houses computed (timings.csv); 'in houses, untimed': inside the houses computed but in no timed stage; "
            f"'outside houses': job wall time not inside a house.")
    print(head + md)
    print(note)
    if a.out is not None:
        from benchmark.harness.cache import atomic_write_text

        atomic_write_text(a.out, f"Profile of the sweep in `{a.sweep}` by `python -m benchmark.commands.maintainer.grid_profile "
                                 f"{a.sweep} --out {a.out}`."
                                 f"\n\n{head}{md}\n{note}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
