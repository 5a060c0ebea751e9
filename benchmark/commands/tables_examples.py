"""``python -m benchmark.commands.tables_examples``: what ``roomseg tables`` prints on the small
runs docs/reliability-tables.md describes, run here into a temporary folder: two runs of
different sizes into one run name (the older rows set aside), one run with two values of
``aggregator.k`` (a split cell), and a clean run beside corrupted ones (a split cell). The
output the page includes (``make docs-numbers``).

Each run is a job of the project's runner (:func:`benchmark.harness.runner.run`) in the folder a
``roomseg-bench -m`` sweep gives it (``R/runs/<name>/<overrides>``); the tables and the lines
on stderr are :func:`benchmark.commands.tables.main`'s own, with the folder read as ``R``.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
import tempfile
import warnings
from pathlib import Path

from benchmark.commands import cli
from benchmark.commands.errors import cli_errors, one_line

#: (title, run name, houses, overrides common to the jobs, one override list per job, tables
#: arguments), in the order written. The jobs of an example run one after the other; a job
#: named twice runs twice (a second sweep into the same folder).
EXAMPLES = (
    ("Two runs into one folder, of {a} and then {b} houses (`env=synthetic classifier=oracle "
     "aggregator=graph_knn,vision_cone run.name=x`)", "x", ("synthetic",), ["classifier=oracle"],
     [["aggregator=graph_knn"], ["aggregator=vision_cone"]], ["--table", "table4"]),
    ("Two values of `aggregator.k` on {n} shared ProcTHOR houses (`env=procthor_shared classifier=oracle "
     "aggregator.k=3,9 run.name=k`)", "k", ("procthor_shared",), ["classifier=oracle"],
     [["aggregator.k=3"], ["aggregator.k=9"]], ["--table", "table4"]),
    ("A clean run beside corrupted ones on {n} generated houses (`env=synthetic classifier=oracle "
     "corruption=clean,scan_2,pose_2 run.name=c`)", "c", ("synthetic",), ["classifier=oracle"],
     [["corruption=clean"], ["corruption=scan_2"], ["corruption=pose_2"]], ["--table", "table4"]),
)


def _job(overrides: list[str], run_name: str, cache: Path, data: Path) -> None:
    """One job of a sweep into ``R/runs/<run_name>/<its overrides>`` (the working folder's ``R``),
    reading shared data under ``data`` (absolute: the working folder is not the checkout)."""
    from benchmark.config import compose_job, job_dirname
    from benchmark.harness.runner import run

    varying = sorted(o for o in overrides if not o.startswith("run."))
    cfg, choices = compose_job([*overrides, "run.progress=false", "run.workers=1", "run.results_dir=R",
                                f"run.cache_dir={cache}", f"run.name={run_name}",
                                f"paths.data_dir={data}"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        df = run(cfg, Path("R") / "runs" / run_name / job_dirname(",".join(varying)), choices)
    if df.attrs.get("n_failed"):
        raise RuntimeError(f"{run_name}: {df.attrs['n_failed']} house(s) failed: {df['error'].dropna().iloc[0]}")


def _tables(args: list[str]) -> tuple[str, str]:
    """(stdout, stderr) of ``roomseg tables ARGS`` run here."""
    from benchmark.commands import tables

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = tables.main(args)
    if rc != 0:
        raise RuntimeError(f"tables {' '.join(args)}: exit status {rc}: {err.getvalue().strip()}")
    return out.getvalue().strip(), err.getvalue().strip()


def examples(work: Path, small: int, large: int, houses: int) -> str:
    """The Markdown of every example, run in ``work`` (an empty folder; the working folder is
    ``work`` meanwhile)."""
    from benchmark.paths import data_dir

    parts = []
    here, data = Path.cwd(), data_dir().resolve()
    os.chdir(work)
    try:
        for title, name, (env,), common, jobs, targs in EXAMPLES:
            sizes = [small, large] if name == "x" else [houses if env == "procthor_shared" else small]
            for n in sizes:
                for job in jobs:
                    _job([f"env={env}", *common, *job, f"run.limit={n}"], name, work / "cache", data)
            out, err = _tables([f"R/runs/{name}", *targs])
            parts += [f"**{title.format(a=small, b=large, n=sizes[0])}**", "", "`roomseg tables R/runs/" + name + " "
                      + " ".join(targs) + "` prints", "", out, "", "and on stderr:", "", "```", err, "```", ""]
    finally:
        os.chdir(here)
    return "\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    ap = cli.ArgumentParser(from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("--small", type=int, default=2, help="houses of the first run into one folder, and of the "
                                                          "clean and corrupted runs")
    ap.add_argument("--large", type=int, default=3, help="houses of the second run into one folder")
    ap.add_argument("--houses", type=int, default=4, help="shared ProcTHOR houses of the aggregator.k example")
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the examples to this Markdown file, headed by the command that made them "
                         "(make docs-numbers: results/published/tables_examples.md, which "
                         "docs/reliability-tables.md includes)")
    a = ap.parse_args(argv)
    try:
        if min(a.small, a.large, a.houses) < 1:
            raise ValueError(f"--small {a.small} / --large {a.large} / --houses {a.houses}: expected >= 1 each")
        with tempfile.TemporaryDirectory(prefix="roomseg-tables-examples-") as tmp:
            text = examples(Path(tmp), a.small, a.large, a.houses)
    except cli_errors() as e:
        print(f"error: {one_line(e)}", file=sys.stderr)
        return 2
    if a.out is not None:
        from benchmark.reports.published import write_published

        err = write_published(a.out, f"python -m benchmark.commands.tables_examples --small {a.small} "
                                     f"--large {a.large} --houses {a.houses} --out {a.out}", text)
        if err:
            print(f"error: {err}", file=sys.stderr)
            return 2
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
