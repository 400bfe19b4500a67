"""Compiled (numba) batches of decisions: many episodes advanced in one thread-parallel call.

Each episode runs :func:`ffsr_gym.kernel.decision.decide` unchanged (same numbers as one at a
time); ``prange`` spreads the episodes over numba's threads (``numba.set_num_threads``) in a few
interleaved groups. :func:`decide_batch` keeps one workspace per episode between calls
(:func:`workspaces`), so each decision reuses the planner step its observation computed, as the
single environment does.
"""

from __future__ import annotations

import numba
from numba import njit, prange
from numba.typed import List

from ffsr_gym.kernel.decision import decide
from ffsr_gym.kernel.flags import runtime_flag
from ffsr_gym.kernel.physics import workspace


def groups(n: int) -> int:
    """Episode groups for ``n`` episodes: four per thread of numba's (load balance), at most one per episode."""
    return max(1, min(n, 4 * numba.get_num_threads()))


@njit(cache=True)
def workspaces(n, n_capsules):
    """A typed list of ``n`` fresh workspaces, one per episode of :func:`decide_batch` (kept between its calls)."""
    out = List()
    for _ in range(n):
        out.append(workspace(n_capsules))
    return out


@njit(cache=True, parallel=True)
def decide_batch(mdl, plants, WS, X, K, active, n_total, n_max, FP, IP, DS, actions, mode, logs, LAST, SCRATCH, OBS,
                 out, n_groups):
    """:func:`ffsr_gym.kernel.decision.decide` for every active episode e (stopping on a violation).

    ``X``, ``K``, ``FP`` (the (m, T_c) of ``MODE_PARAMETERS``) and ``LAST`` (N, 12) advance in
    place; ``logs`` as :func:`run_batch`'s, written from row K[e]; ``OBS`` (N, 53) float32.
    ``out`` (N, 7) float64 receives the returns (rows, status, clipped, increment, cost,
    clearance, EE error); inactive episodes keep their rows of ``out`` and ``OBS``. ``WS``:
    :func:`workspaces`, episode e's in ``WS[e]``; a new episode clears its planned flag in
    ``SCRATCH[e]`` (:func:`ffsr_gym.kernel.decision.forget_plan`).
    """
    PM, PL, PI, PD = plants
    LX, LV, LDQ, LERR, LCLEAR, LSELF, LMU, LCDF, LSMIN, LTAU = logs
    n = X.shape[0]
    for g in prange(n_groups):
        for e in range(g, n, n_groups):
            if not active[e]:
                continue
            k = K[e]
            rows, status, clipped, increment, cost, clearance, ee_error = decide(
                mdl, (PM[e], PL[e], PI[e], PD[e]), WS[e], X[e], k, n_total, n_max, FP[e], IP[e], DS[e], actions[e],
                mode, runtime_flag(True),
                (LX[e], LV[e], LDQ[e], LERR[e], LCLEAR[e], LSELF[e], LMU[e], LCDF[e], LSMIN[e], LTAU[e]), k, LAST[e],
                SCRATCH[e], OBS[e], runtime_flag(True))
            K[e] = k + rows
            out[e, 0], out[e, 1], out[e, 2], out[e, 3] = rows, status, clipped, increment
            out[e, 4], out[e, 5], out[e, 6] = cost, clearance, ee_error
