"""Timing helpers of the benchmark scripts: best of several runs, with the garbage collector held off."""

from __future__ import annotations

import gc
import time
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def _no_gc() -> Iterator[None]:
    """A timed section without Python's cycle collector (collected first), as ``timeit`` times.

    Late in a bench process, full collections landed inside single timed passes and doubled them
    in some runs. The environments leave no cyclic garbage (a test), so the collector's time is the
    whole process's heap, not theirs.
    """
    gc.collect()
    gc.disable()
    try:
        yield
    finally:
        gc.enable()


def best_of(fn, repeats: int) -> float:
    """Smallest wall time [s] of ``repeats`` calls (after one warm-up call)."""
    fn()
    times = []
    for _ in range(repeats):
        with _no_gc():
            start = time.perf_counter()
            fn()
            times.append(time.perf_counter() - start)
    return min(times)


@contextmanager
def kernel_time() -> Iterator[list[float]]:
    """Seconds spent in the batched v2 kernel (``ffsr_gym.kernel.batch.decide_batch``) while the block runs, in
    ``[0]``."""
    from ffsr_gym.kernel import batch as kernel_batch

    original, spent = kernel_batch.decide_batch, [0.0]

    def timed(*args):
        start = time.perf_counter()
        try:
            return original(*args)
        finally:
            spent[0] += time.perf_counter() - start

    kernel_batch.decide_batch = timed
    try:
        yield spent
    finally:
        kernel_batch.decide_batch = original
