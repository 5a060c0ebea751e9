"""The levels' scanner set from the fit to the real logs (benchmark/conditions/scanner_levels.py,
``calibrate --write-levels``): the ladder on known values, the rewrite of a level file, and the
files of conf/corruption holding what the fit of the shared logs gives."""

from pathlib import Path
from types import SimpleNamespace

import pytest
from omegaconf import OmegaConf

from benchmark.conditions.scanner_levels import (
    FAMILIES,
    FITTED,
    fitted_values,
    ladder,
    levels_from_fits,
    set_fitted,
)
from benchmark.paths import CONF_DIR

CORRUPTION = Path(CONF_DIR) / "corruption"
LOGS = Path(__file__).resolve().parents[2] / "shared" / "data" / "real_logs"


def test_the_ladder_runs_from_the_best_log_through_the_median_to_the_poorest():
    # by hand: min 1, median (2 + 4) / 2 = 3, max 9; half way 2 and 6
    assert ladder([4.0, 1.0, 9.0, 2.0]) == (1.0, 2.0, 3.0, 6.0, 9.0)
    # three significant figures
    assert ladder([0.012345, 0.012345]) == (0.0123,) * 5
    assert ladder([0.0229, 0.0282, 0.0345, 0.0558]) == (0.0229, 0.0271, 0.0314, 0.0436, 0.0558)
    with pytest.raises(ValueError, match="expected one finite value >= 0 per log"):
        ladder([0.1, float("nan")])
    with pytest.raises(ValueError, match="expected one finite value >= 0 per log"):
        ladder([])


def test_levels_from_fits_takes_each_field_over_the_logs():
    fits = {"a": SimpleNamespace(range_noise=0.02, dropout=0.01, grazing_dropout=0.0),
            "b": SimpleNamespace(range_noise=0.04, dropout=0.03, grazing_dropout=0.2)}
    levels = levels_from_fits(fits)
    assert levels[1] == {"range_noise": 0.02, "dropout": 0.01, "grazing_dropout": 0.0}
    assert levels[5] == {"range_noise": 0.04, "dropout": 0.03, "grazing_dropout": 0.2}
    assert levels[3] == {"range_noise": 0.03, "dropout": 0.02, "grazing_dropout": 0.1}


TEXT = """# @package _global_
mapping:
  max_range: 6.0            # metres
  range_noise: 0.03          # metres (sigma)
  dropout: 0.1              # share of beams returning nothing
  people: 3
pose_error:
  alpha1: 0.0002            # rad^2
  range_noise: 0.03          # metres (sigma), as the mapping scanner
robot:
  severity: 3
"""


def test_set_fitted_rewrites_only_the_fitted_fields_present_and_keeps_the_rest():
    out = set_fitted(TEXT, {"range_noise": 0.0314, "dropout": 0.0172, "grazing_dropout": 0.0122})
    cfg = OmegaConf.create(out)
    assert cfg.mapping.range_noise == 0.0314 and cfg.pose_error.range_noise == 0.0314
    assert cfg.mapping.dropout == 0.0172 and "grazing_dropout" not in cfg.mapping  # not added
    assert cfg.mapping.max_range == 6.0 and cfg.mapping.people == 3 and cfg.pose_error.alpha1 == 0.0002
    assert "fitted to the real logs" in out and out.count("fitted to the real logs") == 3
    assert set_fitted(out, {"range_noise": 0.0314, "dropout": 0.0172, "grazing_dropout": 0.0}) == out  # idempotent
    assert fitted_values(out) == {("mapping", "range_noise"): 0.0314, ("mapping", "dropout"): 0.0172,
                                  ("pose_error", "range_noise"): 0.0314}


def test_every_scanner_level_file_holds_a_fitted_field_under_mapping():
    for family in FAMILIES:
        for k in range(1, 6):
            held = fitted_values((CORRUPTION / f"{family}_{k}.yaml").read_text(encoding="utf-8"))
            assert ("mapping", "range_noise") in held and ("mapping", "dropout") in held, f"{family}_{k}"
            if family == "slam" or family == "realistic":  # the front end matches scans of the same scanner
                assert held[("pose_error", "range_noise")] == held[("mapping", "range_noise")], f"{family}_{k}"
                assert held[("pose_error", "dropout")] == held[("mapping", "dropout")], f"{family}_{k}"


@pytest.mark.skipif(not LOGS.is_dir(), reason=f"the shared real logs are absent ({LOGS})")
def test_the_level_files_hold_what_the_fit_of_the_shared_logs_gives():
    """The published levels are the fit's: fitting the four shared logs again gives, severity by
    severity, the values every scan, slam and realistic file holds (`calibrate --write-levels`)."""
    from benchmark.commands.calibrate import fit_logs

    fits = fit_logs(LOGS)
    levels = levels_from_fits({name: f for name, (f, _) in fits.items()})
    for family in FAMILIES:
        for k, values in levels.items():
            held = fitted_values((CORRUPTION / f"{family}_{k}.yaml").read_text(encoding="utf-8"))
            for (section, field), v in held.items():
                assert field in FITTED
                assert v == values[field], f"conf/corruption/{family}_{k}.yaml {section}.{field}: {v}, the fit gives {values[field]}"
