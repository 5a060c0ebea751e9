"""``python -m benchmark.commands.data``: the datasets the harness knows, and their download.

    python -m benchmark.commands.data list [--verify] [--root DIR]
    python -m benchmark.commands.data fetch NAME [NAME ...] [--root DIR]

``list`` shows each dataset (the shared ProcTHOR houses, the SeLRoS release, ProcTHOR-10k through
``prior``, ArchitecTHOR through ``ai2thor``): its public source, licence, size, target folder
and whether it is present. ``list --verify`` also hashes every file of the datasets that are
present, says per dataset how many files it checked, and exits 1 when one is damaged or
partial. ``fetch`` downloads one on a machine with internet access, with a progress bar,
resumable, checked against the size and SHA-256 in ``envs/datasets/catalogue.yaml`` and moved
into place only once complete (envs.datasets.download). The data root is
``$ROOMSEG_SHARED_DATA`` (default ``../shared/data``), or ``--root`` (before or after the
subcommand). Exit 0 when done, 1 when ``--verify`` finds damage, 2 on a bad name or a failed
download (one line naming the file and why).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from benchmark.commands import cli
from benchmark.harness.hints import fetch_command
from envs.datasets.download import (
    CATALOGUE,
    DownloadError,
    fetch_files,
    fetch_with_package,
    load_catalogue,
    status,
)


def _size(ds) -> str:
    if ds.kind != "files":
        return ds.size_note or "–"
    n = ds.size
    return f"{n / 2**20:.1f} MiB" if n >= 2**20 else f"{n / 2**10:.0f} KiB"


def _list(root: Path, catalogue: Path, verify: bool) -> int:
    cat = load_catalogue(catalogue)
    print(f"data root: {root} (ROOMSEG_SHARED_DATA, or --root)\n")
    bad = []
    for ds in cat.values():
        where = root / ds.folder if ds.kind == "files" else "(the package's own cache)"
        files = f", {len(ds.files)} file{'' if len(ds.files) == 1 else 's'}" if ds.kind == "files" else ""
        state = status(ds, root, verify)
        line = f"{ds.name}: {ds.title}\n  status:  {state}\n"
        if verify and ds.kind == "files":
            if state == "present":
                line += f"  verify:  {len(ds.files)} of {len(ds.files)} files match their size and SHA-256\n"
            elif state != "absent":
                line += f"  verify:  FAILED: {state}; fetch it again: {fetch_command(ds.name, root)}\n"
                bad.append(f"{ds.name} ({state})")
            else:
                line += "  verify:  nothing to verify (absent)\n"
        print(f"{line}  folder:  {where}\n"
              f"  size:    {_size(ds)}{files}\n  source:  {ds.source}\n  licence: {ds.licence}\n"
              f"  used by: {ds.used_by}\n")
    if verify:
        checked = [ds for ds in cat.values() if ds.kind == "files" and status(ds, root) != "absent"]
        if bad:
            print(f"error: damaged or partial: {', '.join(bad)}", file=sys.stderr)
            return 1
        print("verified: every dataset present matches the catalogue's sizes and SHA-256" if checked
              else "verified: no dataset is present under the data root")
    print(f"get one (needs internet access): {fetch_command('NAME', root)}")
    return 0


def _fetch(names: Sequence[str], root: Path, catalogue: Path, progress: bool, timeout: float) -> int:
    cat = load_catalogue(catalogue)
    bad = [n for n in names if n not in cat]
    if bad:
        print(f"error: no dataset {bad[0]!r}; known: {', '.join(cat)}", file=sys.stderr)
        return 2
    for name in names:
        ds = cat[name]
        try:
            if ds.kind == "files":
                folder, fetched = fetch_files(ds, root, progress=progress, timeout=timeout)
                word = "fetched and verified" if fetched else "already present, verified"
                print(f"{name}: {word}: {folder} ({len(ds.files)} files, {_size(ds)})")
            else:
                print(f"{name}: in {fetch_with_package(ds)}")
        except DownloadError as e:
            print(f"error: {e}", file=sys.stderr)
            return 2
        except OSError as e:  # a full disk, a read-only folder
            from benchmark.harness.write_errors import cannot_write

            print(f"error: {name}: {cannot_write(e, root)}", file=sys.stderr)
            return 2
    return 0


def parser() -> argparse.ArgumentParser:
    """The command line of ``data`` (``--root`` before or after the subcommand)."""
    root_help = "data root (default $ROOMSEG_SHARED_DATA or ../shared/data)"
    ap = cli.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", type=Path, default=None, help=root_help)
    ap.add_argument("--catalogue", type=Path, default=CATALOGUE, help=argparse.SUPPRESS)  # tests: a local server's
    sub = ap.add_subparsers(dest="cmd", required=True)
    # --root after the subcommand too (data fetch NAME --root DIR, as hints type it); SUPPRESS
    # keeps a --root given before the subcommand when none follows it
    ls = sub.add_parser("list", help="the datasets, their sources, licences, sizes and whether they are present")
    ls.add_argument("--root", type=Path, default=argparse.SUPPRESS, help=root_help)
    ls.add_argument("--verify", action="store_true",
                    help="also check every file's SHA-256 (slower); exit 1 when one is damaged or missing")
    f = sub.add_parser("fetch", help="download datasets (resumable, checksummed, moved into place when complete)")
    f.add_argument("--root", type=Path, default=argparse.SUPPRESS, help=root_help)
    f.add_argument("names", nargs="+", metavar="NAME")
    f.add_argument("--no-progress", action="store_true", help="no progress bar")
    f.add_argument("--timeout", type=float, default=60.0, help="seconds to wait for the server (default 60)")
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    from benchmark.paths import data_dir

    a = parser().parse_args(argv)
    if a.root is None and not data_dir().is_absolute():  # ../shared/data: relative to the checkout's root
        from benchmark.harness.hints import outside_root

        where = outside_root("python -m benchmark.commands.data")
        if where is not None:
            print(where.replace("): cd", ", or give --root DIR): cd"), file=sys.stderr)
            return 2
    root = a.root or data_dir()
    try:
        if a.cmd == "list":
            return _list(root, a.catalogue, a.verify)
        return _fetch(a.names, root, a.catalogue, not a.no_progress, a.timeout)
    except ValueError as e:  # a malformed catalogue
        print(f"error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
