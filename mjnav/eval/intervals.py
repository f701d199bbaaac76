"""Rates and their 95 % Wilson score intervals, shared by the metrics, the social metrics and the
tables (the bottom of :mod:`mjnav.eval`: it imports nothing from mjnav)."""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["mean_interval", "rate_with_interval", "wilson"]


def wilson(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """95 % Wilson score interval of a rate (fractions); (nan, nan) for n = 0."""
    if n <= 0:
        return math.nan, math.nan
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def rate_with_interval(name: str, hits: int, n: int) -> dict[str, float]:
    """``{name: hits / n, name_lo, name_hi}``: a rate and its 95 % Wilson interval (NaN for n = 0)."""
    lo, hi = wilson(hits, n)
    return {name: hits / n if n > 0 else math.nan, f"{name}_lo": lo, f"{name}_hi": hi}


def mean_interval(values: Sequence[float], level: float = 0.95,
                  bounds: tuple[float, float] = (-math.inf, math.inf)) -> tuple[float, float, float]:
    """Mean of ``values`` (one per seed) and its Student-t interval: ``(mean, lo, hi)``.

    ``mean ± t_{(1+level)/2, n-1} · s / sqrt(n)`` with the sample standard deviation ``s``, clipped to
    ``bounds`` (the values' range: [0, 1] for a rate, [0, inf) for a time); the interval is
    (nan, nan) for fewer than two values, the mean nan for none. NaN values are dropped.
    """
    kept = [float(v) for v in values if not math.isnan(float(v))]
    n = len(kept)
    if n == 0:
        return math.nan, math.nan, math.nan
    mean = sum(kept) / n
    if n < 2:
        return mean, math.nan, math.nan
    from scipy.stats import t  # deferred: scipy.stats ~0.3 s, only for intervals over seeds (mjnav sweep)

    half = float(t.ppf((1 + level) / 2, n - 1)) * math.sqrt(sum((v - mean) ** 2 for v in kept) / (n - 1) / n)
    return mean, max(mean - half, bounds[0]), min(mean + half, bounds[1])
