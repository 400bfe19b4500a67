"""Compiled (numba) terms of the bounded episode score (v2): rate energy, rate variation, smoothness cost.

The only implementation of these sums: :func:`ffsr_gym.scoring.score.smoothness_terms` (whole
episodes, leaderboards), the environments' fused decision (:mod:`ffsr_gym.kernel.decision`)
and the batched environments all call it, so their numbers agree bit for bit. The order of
the sums is fixed: per arm, step after step, each step's joints in order.
"""

from __future__ import annotations

import math

from numba import njit

#: Settings of the cost C, in this order in the ``score`` vector: α, β, E_ref [rad²/s], V_ref [rad/s].
S_ALPHA, S_BETA, S_E_REF, S_V_REF = range(4)
N_SCORE = 4


@njit(cache=True, error_model="numpy")
def smoothness_into(rates, rows, dt, previous, out):
    """Rate energy E and rate variation V of each arm over ``rates[:rows]`` (held ``dt`` [s] each).

    ``previous`` (12,): the rates applied just before the first row. Writes
    ``out = (E_mission, E_balance, V_mission, V_balance)`` [rad²/s, rad/s].
    """
    for arm in range(2):
        energy, variation = 0.0, 0.0
        for k in range(rows):
            square, step = 0.0, 0.0
            for j in range(6 * arm, 6 * arm + 6):
                rate = rates[k, j]
                before = previous[j] if k == 0 else rates[k - 1, j]
                square += rate * rate
                step += (rate - before) * (rate - before)
            energy += square
            variation += math.sqrt(step)
        out[arm], out[2 + arm] = energy * dt, variation


@njit(cache=True, error_model="numpy")
def smoothness_cost(terms, score):
    """C = α (E₁/E_ref + V₁/V_ref) + β (E₂/E_ref + V₂/V_ref) of ``terms`` from :func:`smoothness_into`."""
    mission = terms[0] / score[S_E_REF] + terms[2] / score[S_V_REF]
    balance = terms[1] / score[S_E_REF] + terms[3] / score[S_V_REF]
    return score[S_ALPHA] * mission + score[S_BETA] * balance
