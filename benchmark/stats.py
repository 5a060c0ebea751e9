"""Verdicts with error bars: intervals over houses, paired differences, ties, groups, power.

Every table the harness writes ranks methods by a mean over houses. This module says how far
such a mean can be trusted and when two of them differ:

* :func:`bootstrap_ci`: a 95 % percentile bootstrap interval of a mean over houses (the houses
  are resampled with replacement, :data:`N_BOOT` times, from a fixed seed, so the same rows give
  the same interval on every machine);
* :func:`paired_ci`: the same for the mean of a per-house difference ``a - b`` between two
  methods (or two conditions) scored on the same houses: the spread of the houses, which both
  share, cancels, so a paired interval is much narrower than two unpaired ones;
* :func:`verdict`: words that follow a paired interval: "ahead" only where it excludes zero,
  otherwise "tied" with the interval;
* :func:`groups`: a ranking in groups of methods that cannot be separated;
* :func:`bootstrap_p`, :func:`holm` and :func:`holm_levels`: verdicts corrected for their number.
  A set of sentences read together (a family of m paired comparisons) would, at 95 % each, call
  about one tie in twenty "ahead" by chance. Each comparison gets a two-sided bootstrap p-value
  (twice the share of its resampled mean differences on the far side of zero, the same seeded
  resamples as its interval), Holm's step-down procedure (Holm 1979) gives the i-th smallest
  p-value the level alpha / (m - i + 1) while it keeps rejecting, and the comparison's interval is
  read at that level (:func:`holm_verdicts`): "ahead" only where Holm rejects and that corrected
  interval excludes zero. Holm keeps the chance of any false "ahead" in the family at 5 %;
  Bonferroni (alpha / m for every one) is never less strict.
* :func:`houses_needed` and :func:`detectable_difference`: the power of a two-sided paired
  t-test (noncentral t, as G*Power computes it): how many houses detect a difference of a
  given size at 80 % power from the observed spread of the per-house differences, and the
  smallest difference a given number of houses detects.

Everything here is a plain function over arrays of per-house values (any unit; the tables pass
percent). A house missing from one side of a pair is a caller's error (the tables only pair
cells that hold the same houses).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

#: bootstrap resamples, seed and confidence level used by every table.
N_BOOT = 2000
SEED = 0
LEVEL = 0.95
#: the words under a table that name the method.
METHOD_WORDS = (f"95 % intervals: percentile bootstrap over houses ({N_BOOT} resamples, seed {SEED}); "
                "differences paired by house")


#: resamples kept per process (by ``n``, ``n_boot``, ``seed``): a table draws the same ones for
#: every cell over the same number of houses; larger ones are drawn again each time.
RESAMPLES_KEPT = 16
RESAMPLE_KEEP_BYTES = 16 * 2**20
_RESAMPLES: dict[tuple[int, int, int], np.ndarray] = {}


def resample_indices(n: int, n_boot: int = N_BOOT, seed: int = SEED) -> np.ndarray:
    """Bootstrap resamples of ``n`` houses: int array (n_boot, n) of indices into 0..n-1
    (read-only: the same array may be returned again).

    They depend on ``n`` and ``seed`` only, so two cells over the same sorted houses are
    resampled alike (a paired comparison of their intervals is consistent). Drawn once per
    process for each (``n``, ``n_boot``, ``seed``) up to :data:`RESAMPLE_KEEP_BYTES` each
    (the last :data:`RESAMPLES_KEPT` kept)."""
    key = (int(n), int(n_boot), int(seed))
    kept = _RESAMPLES.get(key)
    if kept is not None:
        return kept
    idx = np.random.default_rng(seed).integers(0, n, size=(n_boot, n))
    idx.flags.writeable = False
    if idx.nbytes <= RESAMPLE_KEEP_BYTES:
        if len(_RESAMPLES) >= RESAMPLES_KEPT:
            _RESAMPLES.pop(next(iter(_RESAMPLES)))
        _RESAMPLES[key] = idx
    return idx


def bootstrap_means(x: np.ndarray, n_boot: int = N_BOOT, seed: int = SEED) -> np.ndarray:
    """Bootstrap distribution of the mean of ``x`` over its last axis (houses).

    Args:
        x: (..., n) finite values, n >= 1.

    Returns:
        (..., n_boot) means of resampled houses."""
    x = np.asarray(x, dtype=float)
    idx = resample_indices(x.shape[-1], n_boot, seed)
    return x[..., idx].mean(axis=-1)


def bootstrap_ci(x: Sequence[float] | np.ndarray, level: float = LEVEL, n_boot: int = N_BOOT,
                 seed: int = SEED) -> tuple[float, float]:
    """Percentile bootstrap interval of the mean of ``x`` (per-house values, 1-D).

    Returns:
        (lo, hi) in the unit of ``x``; (nan, nan) for fewer than two values or a NaN among
        them (an interval from one house, or over a missing number, would be made up)."""
    x = np.asarray(x, dtype=float).ravel()
    if x.size < 2 or not np.all(np.isfinite(x)):
        return float("nan"), float("nan")
    m = bootstrap_means(x, n_boot, seed)
    a = (1.0 - level) / 2.0
    lo, hi = np.quantile(m, [a, 1.0 - a])
    return float(lo), float(hi)


def paired_ci(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray, level: float = LEVEL,
              n_boot: int = N_BOOT, seed: int = SEED) -> tuple[float, float, float]:
    """Mean of the per-house difference ``a - b`` and its bootstrap interval.

    Args:
        a, b: (n,) values of the same houses in the same order.

    Returns:
        (mean difference, lo, hi).

    Raises:
        ValueError: ``a`` and ``b`` of different lengths."""
    a, b = np.asarray(a, dtype=float).ravel(), np.asarray(b, dtype=float).ravel()
    if a.shape != b.shape:
        raise ValueError(f"a paired difference needs the same houses on both sides; got {a.size} and {b.size}")
    d = a - b
    lo, hi = bootstrap_ci(d, level, n_boot, seed)
    return float(d.mean()) if d.size else float("nan"), lo, hi


def separated(lo: float, hi: float) -> bool:
    """Whether an interval of a difference excludes zero (a NaN interval separates nothing)."""
    return bool(np.isfinite(lo) and np.isfinite(hi) and (lo > 0 or hi < 0))


def interval_words(lo: float, hi: float, decimals: int = 1) -> str:
    """``95 % CI -9.1 to +10.6`` (signed: these are differences)."""
    return f"95 % CI {lo:+.{decimals}f} to {hi:+.{decimals}f}"


def verdict(name_a: str, name_b: str, diff: float, lo: float, hi: float, decimals: int = 1) -> str:
    """Words for a paired difference ``a - b``: ``A ahead of B by +2.1 (95 % CI +0.4 to +3.9)``
    where the interval excludes zero, ``B ahead of A by ...`` where it is below zero, else
    ``A and B tied (+0.8, 95 % CI -9.1 to +10.6)``."""
    ci = interval_words(lo, hi, decimals)
    if separated(lo, hi):
        first, second = (name_a, name_b) if diff > 0 else (name_b, name_a)
        return f"{first} ahead of {second} by {abs(diff):.{decimals}f} ({ci} for {name_a} - {name_b})"
    return f"{name_a} and {name_b} tied ({diff:+.{decimals}f}, {ci})"


def level_words(level: float) -> str:
    """A confidence level in words: ``95 %``, ``99.86 %`` (four significant digits at most)."""
    return f"{100.0 * level:.4g} %"


def bootstrap_p(draws: Sequence[float] | np.ndarray) -> float:
    """Two-sided bootstrap p-value of "the mean difference is zero" from bootstrap draws of a
    mean difference: twice the share of draws on the far side of zero (the smaller of the shares
    at or below and at or above zero), at most 1. NaN without two finite draws.

    With :data:`N_BOOT` draws it moves in steps of 1 / 1000: a p-value of 0 says no draw crossed
    zero; a percentile interval at level 1 - alpha excludes zero about where p < alpha."""
    d = np.asarray(draws, dtype=float).ravel()
    d = d[np.isfinite(d)]
    if d.size < 2:
        return float("nan")
    return float(min(1.0, 2.0 * min(np.mean(d <= 0), np.mean(d >= 0))))


def paired_p(a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray, n_boot: int = N_BOOT,
             seed: int = SEED) -> float:
    """:func:`bootstrap_p` of the per-house difference ``a - b`` (the resamples of
    :func:`paired_ci`, so p and interval agree); NaN for fewer than two houses or a NaN value."""
    a, b = np.asarray(a, dtype=float).ravel(), np.asarray(b, dtype=float).ravel()
    if a.shape != b.shape:
        raise ValueError(f"a paired difference needs the same houses on both sides; got {a.size} and {b.size}")
    d = a - b
    if d.size < 2 or not np.all(np.isfinite(d)):
        return float("nan")
    return bootstrap_p(bootstrap_means(d, n_boot, seed))


def _holm_order(p: np.ndarray) -> tuple[np.ndarray, int]:
    """Indices of the finite p-values, smallest first (ties in input order), and their number m."""
    finite = np.flatnonzero(np.isfinite(p))
    order = finite[np.argsort(p[finite], kind="stable")]
    return order, int(order.size)


def holm(p: Sequence[float] | np.ndarray, alpha: float = 1.0 - LEVEL) -> tuple[np.ndarray, np.ndarray]:
    """Holm's step-down procedure (Holm 1979) over a family of comparisons.

    The p-values sorted, p_(1) <= ... <= p_(m): the adjusted p-value of the i-th is
    max over j <= i of min(1, (m - j + 1) p_(j)); a comparison is rejected (its difference
    declared) where its adjusted p-value is <= ``alpha``. That is: reject while p_(i) <=
    alpha / (m - i + 1), and keep the first one that fails and every larger one. The chance
    of one false rejection or more in the family stays at most ``alpha``.

    Args:
        p: the family's p-values (a NaN one is no comparison: not counted in m, never rejected).

    Returns:
        (adjusted p-values, rejected) in the order of ``p`` (NaN and False for a NaN p)."""
    p = np.asarray(p, dtype=float).ravel()
    order, m = _holm_order(p)
    adj = np.full(p.shape, np.nan)
    if m:
        adj[order] = np.maximum.accumulate(np.minimum(1.0, (m - np.arange(m)) * p[order]))
    return adj, np.isfinite(adj) & (adj <= alpha)


def holm_levels(p: Sequence[float] | np.ndarray, alpha: float = 1.0 - LEVEL) -> np.ndarray:
    """The alpha each comparison of a family is read at under Holm's step-down: the i-th
    smallest p-value gets alpha / (m - i + 1) (p-values that are equal share the first one's,
    the strictest), up to the first one Holm keeps; that one's alpha holds for every larger
    p-value too (the procedure stops there). An interval at confidence 1 - level excludes zero
    about where Holm rejects (:func:`holm`). A NaN p-value gets alpha / m.

    Returns:
        alphas, in the order of ``p``."""
    p = np.asarray(p, dtype=float).ravel()
    order, m = _holm_order(p)
    out = np.full(p.shape, alpha / max(m, 1))
    stop = None
    first = 0
    for i, k in enumerate(order):
        if i and p[k] != p[order[i - 1]]:
            first = i
        if stop is None:
            a = alpha / (m - first)
            if not p[k] <= a:
                stop = a
            out[k] = a
        else:
            out[k] = stop
    return out


def holm_verdicts(pairs: Sequence[tuple[np.ndarray, np.ndarray]], alpha: float = 1.0 - LEVEL,
                  n_boot: int = N_BOOT, seed: int = SEED) -> list[dict]:
    """Paired comparisons read as one family of ``len(pairs)``, corrected by Holm.

    Args:
        pairs: per comparison (a, b), per-house values of the same houses in the same order.

    Returns:
        Per comparison, in order, a dict: diff (mean of a - b), p (:func:`paired_p`), p_holm
        (:func:`holm`'s adjusted p), level (the confidence its interval is read at: 1 - its
        :func:`holm_levels` alpha), lo, hi (the paired interval at that level), ahead (Holm
        rejects and the interval excludes zero: the sign of diff says who is ahead), m (the
        family's size)."""
    ps = np.array([paired_p(a, b, n_boot, seed) for a, b in pairs], dtype=float)
    adj, rejected = holm(ps, alpha)
    alphas = holm_levels(ps, alpha)
    out = []
    for (a, b), p, q, r, al in zip(pairs, ps, adj, rejected, alphas):
        d, lo, hi = paired_ci(a, b, 1.0 - al, n_boot, seed)
        out.append({"diff": d, "p": float(p), "p_holm": float(q), "level": float(1.0 - al), "lo": lo, "hi": hi,
                    "ahead": bool(r and separated(lo, hi)), "m": len(pairs)})
    return out


def groups(values: Mapping[str, np.ndarray], level: float = LEVEL, n_boot: int = N_BOOT,
           seed: int = SEED, corrected: bool = False) -> list[list[str]]:
    """A ranking in groups of methods that cannot be separated.

    Methods are taken best first (highest mean). The best method left opens a group; every
    method left whose paired interval against it includes zero joins that group; repeat with
    the methods not yet placed. So a group is "the best remaining method and all it cannot be
    told from", and group 1 holds every method not shown worse than the leader.

    With ``corrected``, the ranking is read as one family of every pair of methods (k (k - 1) / 2
    for k methods, :func:`holm_verdicts` at 1 - ``level``): two methods are separated only where
    Holm separates them.

    Args:
        values: method -> (n,) per-house values, the same houses in the same order for all.

    Returns:
        Groups, best first, each best first."""
    names = sorted(values, key=lambda m: (-float(np.mean(values[m])), m))
    if corrected:
        pairs = [(a, b) for i, a in enumerate(names) for b in names[i + 1:]]
        verdicts = holm_verdicts([(values[a], values[b]) for a, b in pairs], 1.0 - level, n_boot, seed)
        apart = {ab for ab, v in zip(pairs, verdicts) if v["ahead"]}

        def split(a: str, b: str) -> bool:
            return (a, b) in apart
    else:
        def split(a: str, b: str) -> bool:
            return separated(*paired_ci(values[a], values[b], level, n_boot, seed)[1:])
    out: list[list[str]] = []
    left = list(names)
    while left:
        lead = left[0]
        grp = [lead] + [m for m in left[1:] if not split(lead, m)]
        out.append(grp)
        left = [m for m in left if m not in grp]
    return out


def group_words(grps: Sequence[Sequence[str]]) -> str:
    """``{a, b} > {c} > {d, e}``: a ranking whose braces hold methods that cannot be separated."""
    return " > ".join("{" + ", ".join(g) + "}" for g in grps)


def power_paired(n: int, delta: float, sd: float, alpha: float = 1.0 - LEVEL) -> float:
    """Power of a two-sided paired t-test on ``n`` houses to detect a mean difference
    ``delta`` when the per-house differences have standard deviation ``sd`` (noncentral t with
    n - 1 degrees of freedom and noncentrality delta / sd x sqrt(n))."""
    from scipy import stats

    if n < 2 or sd <= 0:
        return float("nan") if sd <= 0 and delta == 0 else (1.0 if sd <= 0 else 0.0)
    df = n - 1
    t = stats.t.ppf(1.0 - alpha / 2.0, df)
    nc = delta / sd * np.sqrt(n)
    p = float(stats.nct.sf(t, df, nc) + stats.nct.cdf(-t, df, nc))
    if not np.isfinite(p):  # SciPy's noncentral t gives up far in the tail: the normal limit there
        p = float(stats.norm.sf(t - nc) + stats.norm.cdf(-t - nc))
    return p


def houses_needed(sd: float, delta: float, power: float = 0.8, alpha: float = 1.0 - LEVEL,
                  most: int = 100_000) -> int:
    """The smallest number of houses at which a two-sided paired t-test detects a mean
    difference ``delta`` with ``power``, given per-house differences of standard deviation
    ``sd`` (same unit as ``delta``). Returns ``most + 1`` when even ``most`` houses do not."""
    if delta <= 0:
        raise ValueError(f"the difference to detect must be > 0, got {delta}")
    if not np.isfinite(sd) or sd <= 0:
        return 2
    z = 1.959963984540054 + 0.8416212335729143  # normal approximation: a starting point below the answer
    n = max(2, int(np.floor((z * sd / delta) ** 2)) - 1)
    while n <= most and power_paired(n, delta, sd, alpha) < power:
        n += 1
    return n


def detectable_difference(sd: float, n: int, power: float = 0.8, alpha: float = 1.0 - LEVEL) -> float:
    """The smallest mean difference a two-sided paired t-test on ``n`` houses detects with
    ``power``, per-house differences of standard deviation ``sd`` (same unit)."""
    from scipy.optimize import brentq

    if n < 2 or not np.isfinite(sd):
        return float("nan")
    if sd <= 0:
        return 0.0
    hi = sd
    while power_paired(n, hi, sd, alpha) < power:
        hi *= 2.0
    return float(brentq(lambda d: power_paired(n, d, sd, alpha) - power, 1e-12 * sd, hi, xtol=1e-9 * sd))


__all__ = ["N_BOOT", "SEED", "LEVEL", "METHOD_WORDS", "resample_indices", "bootstrap_means", "bootstrap_ci",
           "paired_ci", "separated", "interval_words", "verdict", "level_words", "bootstrap_p", "paired_p",
           "holm", "holm_levels", "holm_verdicts", "groups", "group_words", "power_paired",
           "houses_needed", "detectable_difference"]
