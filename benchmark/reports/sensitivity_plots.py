"""Sensitivity plots split by noise model (the oracle classifier configs of
:mod:`benchmark.classifiers.noise`): one figure per model and an overview."""

from __future__ import annotations

from pathlib import Path

#: oracle classifier config -> the noise model's name in plots.
NOISE_TITLES = {"oracle": "independent", "oracle_room": "per room", "oracle_house": "per house (bias)",
                "oracle_confusion": "confusion (objects classifier)"}


def _curves(ax, part, metric: str) -> None:
    from benchmark.reports.formatting import combo_label, error_bars  # noqa: PLC0415

    keys = [c for c in ("aggregator", "postprocess") if c in part]
    for key, g in part.groupby(keys):
        g = g.sort_values("oracle_accuracy")
        key = key if isinstance(key, tuple) else (key,)
        label = combo_label(keys, key)
        ax.errorbar(g["oracle_accuracy"] * 100, g[f"{metric}_mean"] * 100, yerr=error_bars(g, metric),
                    marker="o", capsize=3, label=label, linestyle="--" if "none" in key else "-")
    ax.set_ylim(0, 100)
    ax.grid(alpha=0.3)


def plot_sensitivity_per_noise(summary, out_dir: str | Path) -> list[Path]:
    """Sensitivity plots when several noise models (oracle classifier configs) were swept:
    ``sensitivity_<classifier>.png`` per model (IoU and pixel accuracy against the configured
    accuracy, one curve per aggregator x post-processing, mean and 95 % interval over houses) and
    ``sensitivity.png``, the IoU (top) and pixel-accuracy (bottom) panels of every model side
    by side on one scale.

    Args:
        summary: the sensitivity table's per-cell summary (``classifier``, ``oracle_accuracy``,
            ``aggregator``, ``postprocess``, ``<metric>_mean``/``_std`` columns; fractions).
        out_dir: the folder to write to.

    Returns:
        The paths written; empty (nothing written) when the summary has fewer than two
        classifiers.
    """
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    from benchmark.reports.plotting import save  # noqa: PLC0415

    if "classifier" not in summary or summary["classifier"].nunique() < 2:
        return []
    out_dir = Path(out_dir)
    written = []
    parts = list(summary.groupby("classifier"))
    for name, part in parts:
        fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharex=True)
        for ax, m, words in zip(axes, ("iou", "accuracy"), ("IoU (%)", "pixel accuracy (%)")):
            _curves(ax, part, m)
            ax.set_xlabel("configured oracle accuracy (%)")
            ax.set_ylabel(words)
        axes[0].legend(fontsize=8)
        fig.suptitle(f"oracle noise: {NOISE_TITLES.get(str(name), name)} (classifier={name})", fontsize=10)
        path = out_dir / f"sensitivity_{name}.png"
        save(fig, path)
        written.append(path)
    fig, axes = plt.subplots(2, len(parts), figsize=(3.6 * len(parts), 6.6), sharex=True, sharey=True,
                             squeeze=False)
    for j, (name, part) in enumerate(parts):
        for i, m in enumerate(("iou", "accuracy")):
            _curves(axes[i][j], part, m)
        axes[0][j].set_title(NOISE_TITLES.get(str(name), str(name)), fontsize=10)
        axes[1][j].set_xlabel("configured oracle accuracy (%)")
    axes[0][0].set_ylabel("IoU (%)")
    axes[1][0].set_ylabel("pixel accuracy (%)")
    axes[0][0].legend(fontsize=7)
    path = out_dir / "sensitivity.png"
    save(fig, path)
    written.append(path)
    return written


__all__ = ["NOISE_TITLES", "plot_sensitivity_per_noise"]
