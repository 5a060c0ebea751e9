"""``python -m benchmark.commands.maintainer.sweep_table``: run a sweep into a temporary folder and write
one of its tables as a Markdown file headed by the command (``make docs-numbers``: the leaderboard
and sensitivity tables the docs include).

    python -m benchmark.commands.maintainer.sweep_table experiment=sensitivity env=synthetic run.limit=5 \\
        --table sensitivity --out results/published/sensitivity.md
    python -m benchmark.commands.maintainer.sweep_table experiment=leaderboard run.limit=5 \\
        --rose2-with env=procthor_shared --rose2-with env.start=75 --table table5 --out results/published/leaderboard.md

The overrides go to ``roomseg-bench`` as typed (with ``run.results_dir`` a fresh temporary
folder, removed afterwards: the models and caches are made anew, as on a fresh clone); the
table is ``python -m benchmark.commands.tables RUN --table NAME``'s, printed and written to
``--out``. ``--rose2-with OVERRIDE`` (repeatable): with a ROSE2 checkout (``--rose2`` or
``$ROOMSEG_ROSE2``, after ``make rose2-env``) one more run of ``segmenter=rose2`` with those
overrides (and the sweep's ``run.*`` ones) into the same run, as ``make leaderboard ROSE2=...``
does; the file then says which ROSE2 commit made its row, or that it has none.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

from benchmark.commands import cli

PROG = "python -m benchmark.commands.maintainer.sweep_table"


def main(argv: list[str] | None = None) -> int:
    from benchmark.reports.tables import TABLES

    ap = cli.ArgumentParser(prog=PROG, from_root=True, description=__doc__.split("\n\n")[0])
    ap.add_argument("overrides", nargs="+", help="roomseg-bench overrides, e.g. experiment=sensitivity run.limit=5")
    ap.add_argument("--table", required=True, choices=sorted(TABLES), help="the table to write")
    ap.add_argument("--out", type=Path, required=True, help="the Markdown file (e.g. results/published/NAME.md)")
    ap.add_argument("--rose2-with", action="append", default=[], metavar="OVERRIDE",
                    help="with a ROSE2 checkout, one more run of segmenter=rose2 with this override (repeatable)")
    ap.add_argument("--rose2", default=os.environ.get("ROOMSEG_ROSE2"),
                    help="the ROSE2 checkout for --rose2-with (default $ROOMSEG_ROSE2)")
    a = ap.parse_args(argv)
    bad = [o for o in a.overrides if "=" not in o or o.startswith(("run.results_dir=", "hydra.run.dir="))]
    if bad:
        print(f"error: override {bad[0]!r}: expected key=value (run.results_dir is the command's own temporary "
              f"folder)", file=sys.stderr)
        return 2
    tmp = Path(tempfile.mkdtemp(prefix="sweep_table-"))
    try:
        return _run(a, tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _bench(overrides: list[str]) -> int:
    """``roomseg-bench OVERRIDES`` in a subprocess under :func:`benchmark.guarded.run_guarded` (its
    whole process group killed when this command dies), the end of its output on this command's
    stderr; its exit status."""
    from benchmark.guarded import run_guarded

    done = run_guarded([sys.executable, "-m", "benchmark.commands.bench", *overrides])
    sys.stderr.write(done.stdout + done.stderr)
    return done.returncode


def _run(a, tmp: Path) -> int:  # noqa: ANN001 - the parsed arguments
    from benchmark.commands.tables import _runs
    from benchmark.reports.published import write_published
    from benchmark.reports.tables import load_rows, render

    rc = _bench([*a.overrides, f"run.results_dir={tmp}"])
    if rc != 0:
        print(f"error: roomseg-bench {' '.join(a.overrides)} exited with {rc} (its lines above)", file=sys.stderr)
        return rc
    names = sorted(p.name for p in (tmp / "runs").iterdir() if p.is_dir())
    if len(names) != 1:
        print(f"error: the sweep wrote {len(names)} runs ({names}); expected one", file=sys.stderr)
        return 2
    name = names[0]
    rose2_words = None
    if a.rose2_with and a.rose2:
        run_overrides = [o for o in a.overrides if o.startswith("run.")]
        rc = _bench([*a.rose2_with, "segmenter=rose2", f"segmenter.checkout={a.rose2}", *run_overrides,
                     f"run.name={name}", f"run.results_dir={tmp}", f"hydra.run.dir={tmp / 'runs' / name / 'rose2'}",
                     "run.allow_failures=true"])
        if rc != 0:
            print(f"error: the ROSE² run exited with {rc} (its lines above)", file=sys.stderr)
            return rc
    if a.rose2_with:
        from benchmark.commands.selros import rose2_line

        rose2_words = rose2_line(a.rose2)
    files = _runs([tmp / "runs" / name])[name]
    text = render(files, [a.table], None, rows=load_rows(files))
    if rose2_words:
        text = text.rstrip("\n") + "\n\n" + rose2_words + "\n"
    print(text)
    command = " ".join([PROG, *a.overrides, *(f"--rose2-with {o}" for o in a.rose2_with),
                        f"--table {a.table}", f"--out {a.out}"])
    err = write_published(a.out, command, text)
    if err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
