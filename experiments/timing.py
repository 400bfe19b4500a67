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
def _timed_decisions(kind: str) -> Iterator[list[float]]:
    """Seconds spent in ``decide`` of the native ``kind`` (``Episode`` or ``EpisodeBatch``) objects the engines make
    while the block runs, in ``[0]`` (everything else those objects do is delegated to them)."""
    import types

    from ffsr_gym import _native
    from ffsr_gym.environments import engine

    spent, native_kind = [0.0], getattr(_native, kind)

    class Timed:
        def __init__(self, *args, **kwargs) -> None:
            self.inner = native_kind(*args, **kwargs)

        def __getattr__(self, name: str):
            return getattr(self.inner, name)

        def decide(self, *args):
            start = time.perf_counter()
            try:
                return self.inner.decide(*args)
            finally:
                spent[0] += time.perf_counter() - start

    engine._native = types.SimpleNamespace(**{**vars(_native), kind: Timed})
    try:
        yield spent
    finally:
        engine._native = _native


def kernel_time():
    """Seconds spent in the batched environments' native decisions (``ffsr_gym._native.EpisodeBatch.decide``, the
    GIL released) while the block runs, in ``[0]``: the batches of engines made inside the block are timed."""
    return _timed_decisions("EpisodeBatch")


def decision_time():
    """Seconds spent in single episodes' native decisions (``ffsr_gym._native.Episode.decide``) while the block runs,
    in ``[0]``: the episodes of resets inside the block are timed."""
    return _timed_decisions("Episode")
