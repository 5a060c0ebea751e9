"""The Hydra app ``roomseg-bench`` (or ``python -m benchmark.commands.bench``).

    roomseg-bench                                   # defaults from conf/config.yaml
    roomseg-bench aggregator=vision_cone run.limit=5
    roomseg-bench -m aggregator=graph_knn,vision_cone postprocess=none,default
    roomseg-bench experiment=table4                 # a paper table's sweep

Exit status: 0 when every house of every job succeeded; 1 when any house failed (after
every row is written; ``run.allow_failures=true`` exits 0) or a worker process was killed (a
sweep worker, or one of the processes running a job's houses, ``run.workers``);
2 when nothing ran: a bad setting, a config that does not compose, an unwritable folder, no
house selected, or a stage that cannot be built; 130 when interrupted (Ctrl-C stops every
worker at once). Errors are one line on stderr.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig

from benchmark.harness import sweep
from benchmark.harness.checks import check_run_overrides
from benchmark.harness.executor import WorkerDied
from benchmark.harness.pipeline import StageError
from benchmark.harness.runner import CONF_DIR, ConfigError, run

PROG = "roomseg-bench"


@hydra.main(version_base="1.3", config_path=CONF_DIR, config_name="config")
def app(cfg: DictConfig) -> float:
    """One job: run the configuration, record its failed houses. Returns its mean IoU."""
    out_dir = Path(HydraConfig.get().runtime.output_dir)
    sweep.clear_error(out_dir)
    try:
        df = run(cfg, out_dir)
    except (ConfigError, StageError) as e:  # nothing ran: one line, and exit status 2 at the end
        sweep.record_error(_one_line(e), out_dir)
        return float("nan")
    except WorkerDied as e:  # a house worker died: one line, exit status 1 (a multirun's launcher ends the sweep)
        if HydraConfig.get().mode == RunMode.MULTIRUN:
            raise
        sweep.record_died(_one_line(e))
        return float("nan")
    sweep.record(df.attrs.get("n_failed", 0), bool(cfg.run.get("allow_failures", False)))
    ok = df[df["status"] == "ok"] if "status" in df else df
    return float(ok["iou"].mean()) if "iou" in ok and len(ok) else float("nan")


def _one_line(e: BaseException) -> str:
    return " ".join(str(e).split()) or type(e).__name__


def main() -> int:
    """Run the app; turn known errors into one line and the outcome into the exit status."""
    from concurrent.futures.process import BrokenProcessPool

    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    os.environ["HYDRA_FULL_ERROR"] = "1"  # errors reach this function instead of Hydra's printer
    try:
        check_run_overrides(sys.argv[1:])  # run.<typo> or +run.<typo>: refused before Hydra writes anything
        app()
    except (ConfigError, StageError) as e:
        print(f"{PROG}: error: {_one_line(e)}", file=sys.stderr)
        return 2
    except (HydraException, OmegaConfBaseException) as e:
        print(f"{PROG}: config error: {_one_line(e).split(' full_key:')[0]}", file=sys.stderr)
        return 2
    except BrokenProcessPool as e:  # a sweep worker was killed (the local launcher says which sweep)
        print(f"{PROG}: error: {_one_line(e)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted; the houses already scored are cached, so the same command "
              f"goes on from there", file=sys.stderr)
        return 130
    except OSError as e:
        where = e.filename or ""
        print(f"{PROG}: error: cannot write {where} ({e.strerror or e})", file=sys.stderr)
        return 2
    out = sweep.OUTCOME
    if out["died"]:
        print(f"{PROG}: error: {out['died'][0]}", file=sys.stderr)
        return 1
    if out["errors"]:
        for msg in dict.fromkeys(out["errors"]):
            print(f"{PROG}: error: {msg}", file=sys.stderr)
        return 2
    if out["n_failed"] and not out["allow_failures"]:
        print(f"{PROG}: {out['n_failed']} house(s) failed in {out['jobs']} job(s) (see the failed rows of "
              f"metrics.csv); run.allow_failures=true exits 0", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
