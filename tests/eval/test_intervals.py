"""Intervals: the mean over seeds with its Student-t 95 % interval (:func:`mean_interval`)."""

from __future__ import annotations

import math

import pytest

from mjnav.eval.intervals import mean_interval


def test_mean_interval_is_students_t() -> None:
    mean, lo, hi = mean_interval([0.5, 0.7, 0.6])
    half = 4.302652729911275 * 0.1 / math.sqrt(3)
    assert (mean, lo, hi) == pytest.approx((0.6, 0.6 - half, 0.6 + half))
    assert mean_interval([0.4, math.nan, 0.4]) == (0.4, 0.4, 0.4)


def test_too_few_values_have_no_interval() -> None:
    mean, lo, hi = mean_interval([0.3])
    assert mean == 0.3 and math.isnan(lo) and math.isnan(hi)
    assert all(math.isnan(v) for v in mean_interval([]))


def test_mean_interval_stays_inside_the_values_range() -> None:
    """Three seeds at 0.56, 0.95 and 0.94: the t half-width (about 0.55) would pass 1; a rate's interval stops at 1."""
    mean, lo, hi = mean_interval([0.56, 0.95, 0.94], bounds=(0.0, 1.0))
    free = mean_interval([0.56, 0.95, 0.94])
    assert free[2] > 1.0 and hi == 1.0 and lo == free[1] > 0.0 and mean == free[0]
