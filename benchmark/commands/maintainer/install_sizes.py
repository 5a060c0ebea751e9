"""``python -m benchmark.commands.maintainer.install_sizes``: what each install step puts in the
environment, by group of packages (the sizes docs/getting-started.md includes).

Reads the installed distributions of the running Python's ``site-packages`` folders (or the
``--site`` folders) through :mod:`importlib.metadata`, and adds up, per distribution, the bytes of
the files its ``RECORD`` lists (apparent sizes, each file once; a file the RECORD lists that is
gone counts nothing). The distributions are grouped by how they came in:

- ``torch``, ``triton``: those distributions;
- ``CUDA libraries``: every ``nvidia-*`` and ``cuda-*`` distribution (torch's CUDA runtime,
  installed on machines without a GPU too);
- ``core``: the project and what its dependencies need, followed through the installed
  distributions' own requirements (``make setup``);
- ``docs extra``: what the ``docs`` extra adds beyond the core (``make setup-docs``);
- ``test extras``: what the ``test`` extra adds beyond the core and the docs extra, the three
  groups above aside (``make setup-test``);
- ``other``: the rest (pip, setuptools, anything installed by hand).

Writes a Markdown table (group, distributions, size in GB of 10^9 bytes, the largest
distributions) under a line saying when, where and by which command it was measured::

    python -m benchmark.commands.maintainer.install_sizes --out results/published/install_sizes.md
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from collections.abc import Iterable
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

#: the groups, in the order of the table
GROUPS = ("core", "docs extra", "test extras", "torch", "triton", "CUDA libraries", "other")
#: where each group comes from, for the table's second column
WHAT = {"core": "`make setup`", "docs extra": "`make setup-docs`", "test extras": "`make setup-test`",
        "torch": "`make setup-test`", "triton": "`make setup-test` (with torch)",
        "CUDA libraries": "`make setup-test` (with torch)", "other": "none of the above"}


def normalize(name: str) -> str:
    """A distribution name as the index compares it (PEP 503): ``Mkdocs_Material`` ->
    ``mkdocs-material``."""
    return re.sub(r"[-_.]+", "-", name).lower()


@dataclass
class Dist:
    """One installed distribution: its normalised ``name``, ``size`` (bytes of the files its
    RECORD lists), ``files`` (how many of them exist) and ``requires`` (its Requires-Dist lines)."""

    name: str
    size: int
    files: int
    requires: list[str] = field(default_factory=list)


def installed(sites: Iterable[str | Path]) -> dict[str, Dist]:
    """The distributions in ``sites`` (folders holding ``*.dist-info``), by normalised name; a
    name in two folders is read from the first (as ``import`` would). A file two RECORDs list
    counts in the first only."""
    seen_files: set[str] = set()
    out: dict[str, Dist] = {}
    for d in metadata.distributions(path=[str(s) for s in sites]):
        name = normalize(d.metadata["Name"] or "")
        if not name or name in out:
            continue
        size = files = 0
        for f in d.files or []:
            p = os.path.realpath(d.locate_file(f))
            if p in seen_files:
                continue
            seen_files.add(p)
            try:
                st = os.stat(p)
            except OSError:
                continue
            size += st.st_size
            files += 1
        out[name] = Dist(name, size, files, list(d.requires or []))
    return out


def closure(dists: dict[str, Dist], root: str, extras: Iterable[str] = ()) -> set[str]:
    """The installed distributions ``root`` needs with ``extras``: its requirements whose markers
    hold here (with each requirement's own extras followed too), and theirs, recursively; a
    requirement that is not installed is left out. ``root`` itself is in the set."""
    from packaging.requirements import Requirement

    todo = [(normalize(root), frozenset(extras))]
    done: set[tuple[str, frozenset]] = set()
    names: set[str] = set()
    while todo:
        name, ext = todo.pop()
        if (name, ext) in done or name not in dists:
            continue
        done.add((name, ext))
        names.add(name)
        for line in dists[name].requires:
            req = Requirement(line)
            wanted = req.marker is None or any(req.marker.evaluate({"extra": e}) for e in ("", *ext))
            if wanted:
                todo.append((normalize(req.name), frozenset(req.extras)))
    return names


def group_of(name: str) -> str | None:
    """The group a distribution belongs to by its name alone (torch, triton, CUDA), else None."""
    if name in ("torch", "triton"):
        return name
    if name.startswith(("nvidia-", "cuda-")):
        return "CUDA libraries"
    return None


def groups(dists: dict[str, Dist], project: str = "roomseg-bench") -> dict[str, list[Dist]]:
    """The installed distributions by group (module docstring), each list largest first.

    Raises:
        ValueError: ``project`` is not installed.
    """
    if normalize(project) not in dists:
        raise ValueError(f"project {project!r}: not installed in the folders read (expected its .dist-info there)")
    core = closure(dists, project)
    docs = closure(dists, project, ["docs"]) - core
    test = closure(dists, project, ["test"]) - core - docs
    out: dict[str, list[Dist]] = {g: [] for g in GROUPS}
    for name, d in dists.items():
        g = group_of(name) or ("core" if name in core else "docs extra" if name in docs
                               else "test extras" if name in test else "other")
        out[g].append(d)
    for g in out:
        out[g].sort(key=lambda d: (-d.size, d.name))
    return out


def table(by_group: dict[str, list[Dist]], largest: int = 3) -> str:
    """The Markdown table: per group its distributions, size (GB, 10^9 bytes) and the ``largest``
    biggest (MB, 10^6 bytes); then the whole environment."""
    lines = ["| group | installed by | distributions | size GB | largest (MB) |", "|---|---|---:|---:|---|"]
    for g in GROUPS:
        ds = by_group.get(g, [])
        big = ", ".join(f"{d.name} {d.size / 1e6:.0f}" for d in ds[:largest])
        lines.append(f"| {g} | {WHAT[g]} | {len(ds)} | {sum(d.size for d in ds) / 1e9:.2f} | {big} |")
    every = [d for ds in by_group.values() for d in ds]
    lines.append(f"| **all** | | **{len(every)}** | **{sum(d.size for d in every) / 1e9:.2f}** | |")
    return "\n".join(lines)


def default_sites() -> list[str]:
    """The running Python's package folders: every ``site-packages`` / ``dist-packages`` folder on
    ``sys.path`` (a virtual environment's, and one a ``.pth`` file adds)."""
    return [p for p in sys.path if Path(p).name in ("site-packages", "dist-packages") and Path(p).is_dir()]


NOTE = ("Bytes of the files each installed distribution's RECORD lists (apparent sizes; `du` counts "
        "whole disk blocks, a little more), grouped by which install step brings the distribution in: "
        "the core is the project with what its requirements need, followed through the installed "
        "packages; an extra's group is what it adds beyond the groups above it; torch, triton and the "
        "CUDA libraries (`nvidia-*`, `cuda-*`) apart, installed by `make setup-test` on a machine "
        "without a GPU too.")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmark.commands.maintainer.install_sizes",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--site", type=Path, action="append", default=None,
                    help="a folder of installed distributions (repeatable; default: the site-packages "
                         "folders of the running Python)")
    ap.add_argument("--project", default="roomseg-bench", help="the distribution whose extras define the groups")
    ap.add_argument("--out", type=Path, default=None,
                    help="also write the table here (Markdown, with the date, machine, commit and command)")
    a = ap.parse_args(argv)
    sites = [str(s) for s in a.site] if a.site else default_sites()
    for s in sites:
        if not Path(s).is_dir():
            print(f"install_sizes: error: --site {s}: not a folder (expected a site-packages folder)", file=sys.stderr)
            return 2
    try:
        text = table(groups(installed(sites), a.project)) + "\n\n" + NOTE
    except ValueError as e:
        print(f"install_sizes: error: {e}", file=sys.stderr)
        return 2
    print(text)
    if a.out is not None:
        from benchmark.reports.published import write_measured

        write_measured(a.out, "benchmark.commands.maintainer.install_sizes", argv, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
