"""Vectorised forms give exactly the numbers of the plain loops they replace (written out here)."""

from __future__ import annotations

import math
import random

import numpy as np

from ffsr_gym.scoring.aggregate import BOOTSTRAP_SAMPLES, BOOTSTRAP_SEED, bootstrap_ci, iqm
from ffsr_gym.user_files import nesting_depth


def _depth_loop(text: str) -> int:
    depth = deepest = 0
    for char in text:
        if char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth = max(0, depth - 1)
    return deepest


def test_nesting_depth_is_the_character_walk():
    rng = random.Random(0)
    for _ in range(2000):
        text = "".join(rng.choice('[]{}a"é\U0001f600\\') for _ in range(rng.randint(0, 60)))
        assert nesting_depth(text) == _depth_loop(text), text
    assert nesting_depth("]]][[[") == 3 and nesting_depth("") == 0 and nesting_depth("[" * 40 + "]" * 40) == 40


def test_the_iqm_bootstrap_is_the_resample_by_resample_one():
    rng = np.random.default_rng(7)
    for n in (1, 2, 3, 5, 10, 37, 100, 250):
        values = rng.random(n) * rng.integers(0, 2, n)  # scores with failures at 0
        draws = np.random.default_rng(BOOTSTRAP_SEED)
        boots = []
        for _ in range(BOOTSTRAP_SAMPLES):
            sample = np.sort(values[draws.integers(0, n, n)])
            lo, hi = int(math.floor(0.25 * n)), int(math.ceil(0.75 * n))
            boots.append(float(np.mean(sample[lo:hi] if hi > lo else sample)))
        want = [float(np.percentile(boots, q, method="inverted_cdf")) for q in (2.5, 97.5)]
        assert bootstrap_ci(values, iqm) == want, n
        assert bootstrap_ci(values, lambda x: iqm(x)) == want, n  # the general path
