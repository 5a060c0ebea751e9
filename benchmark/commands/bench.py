"""The Hydra app ``roomseg-bench`` (or ``python -m benchmark.commands.bench``).

    roomseg-bench                                   # defaults from conf/config.yaml
    roomseg-bench aggregator=vision_cone run.limit=5
    roomseg-bench -m aggregator=graph_knn,vision_cone postprocess=none,default
    roomseg-bench experiment=table4                 # a paper table's sweep
"""

from __future__ import annotations

from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig

from benchmark.harness.runner import CONF_DIR, run


@hydra.main(version_base="1.3", config_path=CONF_DIR, config_name="config")
def main(cfg: DictConfig) -> float:
    out_dir = Path(HydraConfig.get().runtime.output_dir)
    df = run(cfg, out_dir)
    ok = df[df["status"] == "ok"] if "status" in df else df
    return float(ok["iou"].mean()) if "iou" in ok and len(ok) else float("nan")


if __name__ == "__main__":
    main()
