"""``roomseg``: one command-line tool, with a subcommand for each thing a user does.

    roomseg bench [overrides]            # the benchmark (Hydra app; same as roomseg-bench)
    roomseg segment map=... out=...      # your own map (same as roomseg-segment)
    roomseg tables RUN --out DIR         # the paper's tables from a run
    roomseg <command> --help             # each command's own options

``roomseg --help`` lists the commands. Each runs the module that has always run it
(``python -m benchmark.commands.<name>`` still works, and on a terminal says what replaced it);
the maintainers' tools (``benchmark/commands/maintainer/``: docs, perf, scaling, README tables,
GPU check, VLM timing) are left out of this list: ``make help`` names them.
"""

from __future__ import annotations

import runpy
import sys
from collections.abc import Sequence

#: subcommand -> (module under benchmark.commands, one line for the list). In the order a user
#: meets them.
COMMANDS: dict[str, tuple[str, str]] = {
    "bench": ("bench", "run the benchmark: one configuration or a sweep (-m), per-house metrics"),
    "segment": ("segment", "segment your own occupancy map from poses and labels or images, or a robot's bag"),
    "bag-info": ("bag_info", "what a ROS 1 / ROS 2 bag holds, and what roomseg segment bag= would use"),
    "tables": ("tables", "the paper's tables (Markdown, CSV, LaTeX) from a finished run"),
    "report": ("report", "a run as one HTML page: tables, maps, configuration"),
    "figures": ("figures", "the paper's figures for a house, or from a run's saved maps"),
    "robustness": ("robustness", "the robustness benchmark's tables and figures from its run"),
    "baselines": ("baselines", "Table V on the SeLRoS maps; score other methods' maps"),
    "score": ("baselines_score", "score a folder of another method's output maps"),
    "data": ("data", "the datasets the harness knows: list, verify, fetch"),
    "doctor": ("doctor", "what is installed, what is missing, and what to do"),
    "evaluate": ("evaluate", "a classifier's per-view accuracy (Table I) on an image folder"),
    "train": ("train", "train the CNN or the DINOv2 head on an image folder"),
    "confusion": ("view_confusion", "a classifier's confusion on rendered views (for the oracle's noise)"),
    "coverage": ("robot_coverage", "what each viewpoint strategy covers of the houses"),
    "houses": ("house_stats", "statistics of the houses of an environment"),
    "draw-house": ("draw_house", "draw one house: floor plan, rooms, doors, furniture"),
    "annotations": ("annotations", "import ArchitecTHOR room annotations"),
    "map-stats": ("map_stats", "an occupancy map's statistics (walls, speckle, clutter), beside real laser maps"),
    "compile": ("compile_kernels", "compile the numba kernels into numba's cache (make setup runs it)"),
}


def usage() -> str:
    width = max(map(len, COMMANDS))
    lines = ["usage: roomseg <command> [args ...]   (roomseg <command> --help: its options)", "", "commands:"]
    lines += [f"  {name:<{width}}  {what}" for name, (_, what) in COMMANDS.items()]
    lines += ["", "Docs: docs/index.md. Exit statuses: docs/reliability.md."]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``roomseg <command> [args]``; returns the command's exit status (2: unknown command)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if argv is None:  # the console script: Ctrl-C is one line from the start (benchmark/commands/cli.py)
        from benchmark.commands.cli import handle_interrupts

        handle_interrupts()
    if not args or args[0] in ("-h", "--help", "help"):
        print(usage())
        return 0 if args else 2
    name, rest = args[0], args[1:]
    if name not in COMMANDS:
        import difflib

        best = difflib.get_close_matches(name, list(COMMANDS), n=1)
        hint = f"; did you mean {best[0]!r}?" if best else ""
        print(f"roomseg: error: unknown command {name!r}{hint} (roomseg --help lists them)", file=sys.stderr)
        return 2
    module = f"benchmark.commands.{COMMANDS[name][0]}"
    saved = sys.argv
    sys.argv = [f"roomseg {name}", *rest]  # argparse's prog, Hydra's arguments
    try:
        runpy.run_module(module, run_name="__main__", alter_sys=False)
    except SystemExit as e:
        code = e.code
        if code is None:
            return 0
        if isinstance(code, int):
            return code
        print(code, file=sys.stderr)
        return 1
    finally:
        sys.argv = saved
    return 0


if __name__ == "__main__":
    sys.exit(main())
