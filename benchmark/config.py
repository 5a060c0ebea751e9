"""The one place that composes the project's Hydra configs outside a Hydra app.

Commands that are not Hydra apps (``roomseg-segment``, ``evaluate``, ``train``, the scoring and
figure commands, ``gpu_check``) and the tests build their configuration here, from ``conf/``
(:data:`benchmark.paths.CONF_DIR`), with Hydra's compose API: the same groups, defaults and
``_target_`` plug-ins as ``roomseg-bench``, and no Hydra output folder.
"""

from __future__ import annotations

from collections.abc import Sequence

from benchmark.paths import CONF_DIR


def compose(config_name: str = "config", overrides: Sequence[str] = (), *, hydra: bool = False):
    """``conf/<config_name>.yaml`` composed with Hydra ``overrides`` (``key=value`` strings).

    Args:
        config_name: ``config`` (the bench app), ``segment`` or ``score``.
        overrides: Hydra overrides, as on the command line.
        hydra: keep the ``hydra`` node (its ``runtime.choices`` name the chosen options).

    Returns:
        The composed ``DictConfig``.

    Raises:
        hydra.errors.HydraException, omegaconf.errors.OmegaConfBaseException: a bad override.
    """
    from hydra import compose as hydra_compose  # noqa: PLC0415
    from hydra import initialize_config_dir  # noqa: PLC0415

    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        return hydra_compose(config_name=config_name, overrides=list(overrides), return_hydra_config=hydra)


def compose_job(overrides: Sequence[str] = (), config_name: str = "config"):
    """A job's config as the bench app sees it, and the options chosen per group.

    Returns:
        (config without the ``hydra`` node, {group: chosen option name} without Hydra's own
        groups), what :func:`benchmark.harness.runner.run` takes.
    """
    from omegaconf import OmegaConf  # noqa: PLC0415

    full = compose(config_name, overrides, hydra=True)
    choices = {k: (str(v) if v is not None else "") for k, v in full.hydra.runtime.choices.items()
               if not k.startswith("hydra")}
    return OmegaConf.masked_copy(full, [k for k in full if k != "hydra"]), choices


__all__ = ["compose", "compose_job", "CONF_DIR"]
