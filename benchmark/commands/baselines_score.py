"""``python -m benchmark.commands.baselines_score``: score another method's output maps against
ground truth, a Hydra app over the ``external`` group (conf/scoring/score.yaml).

    python -m benchmark.commands.baselines_score external=selros
    python -m benchmark.commands.baselines_score -m external=selros,vrf metrics.connectivity=8
    python -m benchmark.commands.baselines_score external=rose2 external.pred_dir=/path 'external.pred_pattern={id}.png'

Each job prints a Table V-style summary with the sanity rows (``sanity=false`` leaves them out)
and writes ``metrics.csv`` and ``table5.md`` to its output folder
(``results/scores/<method>``; in a multirun ``results/scores/<method>/<overrides>``). The exit status
is 0 when every map was scored, 1 when a map failed (listed), 2 on a bad setting.
"""

from __future__ import annotations

import sys
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.utils import instantiate
from omegaconf import DictConfig

from benchmark.paths import CONF_DIR


def run(cfg: DictConfig, out: Path | None) -> int:
    """Score ``cfg.external`` with ``cfg.metrics``; write to ``out``. Returns 0 when every map
    was scored, 1 when some failed (listed), 2 on a bad setting (one line)."""
    from benchmark.baselines.external import report

    try:
        method = instantiate(cfg.external)
        params = instantiate(cfg.metrics)
        df = method.score(params, sanity=bool(cfg.sanity), grid_size=float(cfg.grid_size))
    except Exception as e:
        # Hydra wraps a target's own error (a bad setting) in InstantiationException
        cause = e.__cause__ if type(e).__name__ == "InstantiationException" and e.__cause__ else e
        if isinstance(cause, (FileNotFoundError, ValueError, TypeError)):
            print(f"error: {cause}", file=sys.stderr)
            return 2
        raise
    report(df, params, out, resolution=method.resolution)
    return 0 if (df["status"] == "ok").all() else 1


#: exit status of each job of this process (Hydra's basic launcher runs the jobs in-process)
_STATUS: list[int] = []


@hydra.main(config_path=str(Path(CONF_DIR) / "scoring"), config_name="score", version_base=None)
def main(cfg: DictConfig) -> int:
    rc = run(cfg, Path(HydraConfig.get().runtime.output_dir))
    _STATUS.append(rc)
    return rc


def cli() -> int:
    """The command: overrides with ``{id}`` placeholders quoted for Hydra's parser, errors in one
    line with exit status 2, the jobs' worst exit status otherwise."""
    import os

    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    from benchmark.config import config_location, quote_braces

    # the shared groups (paths, metrics) are found in conf/ through the search path
    sys.argv[1:] = [*quote_braces(sys.argv[1:]), *config_location("score")[1]]
    os.environ["HYDRA_FULL_ERROR"] = "1"  # errors reach this function instead of Hydra's printer
    try:
        main()
    except (HydraException, OmegaConfBaseException) as e:
        print(f"error: {' '.join(str(e).split()).split(' full_key:')[0]}", file=sys.stderr)
        return 2
    return max(_STATUS, default=0)


if __name__ == "__main__":
    raise SystemExit(cli())
