"""Aggregates of episode scores shared by the leaderboards and their figures."""

from __future__ import annotations

import math

import numpy as np

from ffsr_gym.types import Array


def iqm(values: Array) -> float:
    """Interquartile mean: the mean of the middle half of the sorted values."""
    v = np.sort(np.asarray(values, dtype=float))
    lo, hi = int(math.floor(0.25 * len(v))), int(math.ceil(0.75 * len(v)))
    return float(np.mean(v[lo:hi] if hi > lo else v))
