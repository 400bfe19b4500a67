"""Compiled (numba) batches of closed loops: many episodes advanced in one thread-parallel call.

Each episode runs :func:`ffsr_gym.kernel_loop.run` unchanged (same numbers as one at a time);
``prange`` spreads the episodes over numba's threads (``numba.set_num_threads``).
"""

from __future__ import annotations

from numba import njit, prange

from ffsr_gym.kernel_loop import observe, run
from ffsr_gym.kernel_planner import F_DT


@njit(cache=True, parallel=True)
def run_batch(mdl, X, K, active, n_total, n_max, FP, IP, residuals, logs, rows, status, applied):
    """Advance every active episode e by up to ``n_max`` steps from step ``K[e]``, stopping on a violation.

    ``X`` (N, 19), ``K`` (N,) are updated in place; ``logs`` is the tuple of (N, n + 1, ...)
    trajectory arrays of :class:`~ffsr_gym.kernel_rollout.KernelRollout`, written from row K[e].
    ``rows`` (N,), ``status`` (N,) and ``applied`` (N, n_max, 12; zero-padded rates) are outputs.
    """
    LX, LV, LDQ, LERR, LCLEAR, LSELF, LMU, LCDF, LSMIN = logs
    for e in prange(X.shape[0]):
        rows[e], status[e] = 0, 0
        applied[e, :, :] = 0.0
        if not active[e]:
            continue
        k = K[e]
        x, r, st = run(mdl, X[e], k, n_total, n_max, FP[e], IP[e], residuals[e], True, False, LX[e, k:], LV[e, k:],
                       LDQ[e, k:], LERR[e, k:], LCLEAR[e, k:], LSELF[e, k:], LMU[e, k:], LCDF[e, k:], LSMIN[e, k:])
        X[e, :] = x
        K[e] = k + r
        rows[e], status[e] = r, st
        applied[e, :r, :] = LDQ[e, k:k + r, :]


@njit(cache=True, parallel=True)
def observe_batch(mdl, X, K, FP, IP, E1, E0, REL, CLEAR):
    """EE errors (N, 6), base errors (N, 6), obstacle-relative vectors (N, 3), clearances (N,) at the current states."""
    for e in prange(X.shape[0]):
        e1, e0, rel, clear = observe(mdl, X[e], K[e] * FP[e, F_DT], FP[e], IP[e])
        E1[e, :], E0[e, :], REL[e, :] = e1, e0, rel
        CLEAR[e] = clear
