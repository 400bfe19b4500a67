"""Compiled (numba) filtered inverse of one arm's Jacobian: ``ffsr_gym.planning.inverse`` in one kernel
function, the singular values damped below ε and the avoidance blended by μ (docs/model.md)."""

from __future__ import annotations

import math

from numba import njit

from ffsr_gym.kernel.linalg import solve_into, svd_into


@njit(cache=True, error_model="numpy", inline="always")
def filtered_solve_into(out, ws, J, s_min, target, lam_max, eps, mu, avoiding):
    """out = μ J♯ target + (Θ̇_c − μ P Θ̇_c) (``ffsr_gym.planning.inverse``); returns σ_min of J.

    J♯ damps each singular value below ε (λ²(1 − (σ/ε)²)); P projects onto J's row space. When
    σ_min ≥ ε (nothing damped) and J is well conditioned (σ_min ≥ 1e-3 ‖J‖_F), J♯ = J⁻¹ and
    P = I: σ_min comes from ``smallest_singular_value`` and an LU solve gives the rates (96% of
    mission-arm steps and every balance-arm step on ``paper``). Otherwise the Jacobi SVD decides
    (its singular values alone when that estimate was not certified) and its singular vectors
    give J♯ when something is damped. The result depends on the current J only (no state between
    steps). ``s_min``: ``smallest_singular_value(J)`` (-1 when it declined), computed by the caller.
    """
    Ut, s, Vt, dq_c = ws.U, ws.s, ws.V, ws.dq_c  # singular vectors as rows
    frobenius = 0.0
    for r in range(6):
        for c in range(6):
            frobenius += J[r, c] * J[r, c]
    certified = s_min >= 1e-3 * math.sqrt(frobenius)
    undamped = certified and s_min >= eps
    if not certified:
        svd_into(J, Ut, s, Vt, False)
        s_max, s_min = 0.0, 1e300
        for i in range(6):
            s_max, s_min = max(s_max, s[i]), min(s_min, s[i])
        undamped = s_min >= eps and s_min > s_max * 6.0 * 2.220446049250313e-16
    if undamped:
        y = ws.b6
        solve_into(J, target, ws.M6, y)
        for r in range(6):
            out[r] = mu * y[r] + (dq_c[r] - mu * dq_c[r])
        return s_min
    svd_into(J, Ut, s, Vt)
    s_max, s_min = 0.0, 1e300
    for i in range(6):
        s_max, s_min = max(s_max, s[i]), min(s_min, s[i])
    y = ws.b6
    for i in range(6):
        damping = lam_max * lam_max * (1.0 - (s[i] / eps) ** 2) if (eps > 0.0 and s[i] < eps) else 0.0
        denom = s[i] * s[i] + damping
        gain = s[i] / denom if denom > 0.0 else 0.0
        acc = 0.0
        for r in range(6):
            acc += Ut[i, r] * target[r]
        y[i] = gain * acc
    for r in range(6):
        acc = 0.0
        for i in range(6):
            acc += Vt[i, r] * y[i]
        out[r] = mu * acc
    if avoiding:
        tol = s_max * 6.0 * 2.220446049250313e-16
        for i in range(6):
            acc = 0.0
            if s[i] > tol:
                for r in range(6):
                    acc += Vt[i, r] * dq_c[r]
            y[i] = acc
        for r in range(6):
            acc = 0.0
            for i in range(6):
                acc += Vt[i, r] * y[i]
            out[r] += dq_c[r] - mu * acc
    return s_min
