"""Aggregates of episode scores shared by the leaderboards and their figures."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ffsr_gym.types import Array


def iqm(values: Array) -> float:
    """Interquartile mean: the mean of the middle half of the sorted values."""
    v = np.sort(np.asarray(values, dtype=float))
    lo, hi = int(math.floor(0.25 * len(v))), int(math.ceil(0.75 * len(v)))
    return float(np.mean(v[lo:hi] if hi > lo else v))


def iqm_rows(samples: Array) -> Array:
    """:func:`iqm` of each row of ``samples`` (rows of one length), the same numbers row by row."""
    v = np.sort(samples, axis=1)
    n = v.shape[1]
    lo, hi = int(math.floor(0.25 * n)), int(math.ceil(0.75 * n))
    return np.mean(v[:, lo:hi] if hi > lo else v, axis=1)


#: The bootstrap of every leaderboard CI: seed and resamples (part of each entry's protocol).
BOOTSTRAP_SEED = 0
BOOTSTRAP_SAMPLES = 2000


def bootstrap_ci(values: Array, statistic: Callable[[Array], float]) -> list[float]:
    """Seeded-bootstrap 95 % CI of ``statistic`` over ``values`` (percentiles by the inverted CDF)."""
    values = np.asarray(values, dtype=float)
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    if statistic is iqm and len(values):  # all resamples at once: the same draws and means as one by one
        boots = iqm_rows(values[rng.integers(0, len(values), (BOOTSTRAP_SAMPLES, len(values)))])
    else:
        boots = [statistic(values[rng.integers(0, len(values), len(values))]) for _ in range(BOOTSTRAP_SAMPLES)]
    return [float(np.percentile(boots, 2.5, method="inverted_cdf")),
            float(np.percentile(boots, 97.5, method="inverted_cdf"))]
