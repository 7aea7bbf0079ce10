"""The statistics every study report uses: a mean with its 95 % interval (Student t, scipy), and
a sample's spread. One place, so every report states its intervals the same way."""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence

import numpy as np


def t95(df: int) -> float:
    """The two-sided 95 % quantile of Student's t with ``df`` degrees of freedom (nan below 1)."""
    if df < 1:
        return math.nan
    from scipy.stats import t  # scipy takes ~0.3 s to import: only when a report needs it

    return float(t.ppf(0.975, df))


def interval(xs: Sequence[float]) -> tuple[float, float]:
    """The mean and the half-width of its 95 % interval (Student t over the samples). One sample
    has no interval: the half-width is nan, and tables and figures show none."""
    mean = statistics.fmean(xs)
    if len(xs) < 2:
        return mean, math.nan
    return mean, t95(len(xs) - 1) * statistics.stdev(xs) / len(xs) ** 0.5


def spread(xs: Sequence[float]) -> tuple[float, float, float, float]:
    """Mean, standard deviation (of the samples themselves, ddof 0), minimum and maximum."""
    a = np.asarray(xs, dtype=float)
    return float(a.mean()), float(a.std()), float(a.min()), float(a.max())
