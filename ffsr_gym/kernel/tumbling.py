"""Compiled torque-free motion of the target body: the kernel's copy of :mod:`ffsr_gym.model.tumbling` (Euler's
equations and the quaternion kinematics, RK4 with renormalisation), for an episode's reset. Validated against the
numpy implementation (``tests/test_tumbling.py``)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy")
def _rates(q, w, inertia, dq, dw):
    """dq = ½ q ⊗ (0, ω) and dω from Euler's equations, written into ``dq`` (4,) and ``dw`` (3,)."""
    dq[0] = 0.5 * (-q[1] * w[0] - q[2] * w[1] - q[3] * w[2])
    dq[1] = 0.5 * (q[0] * w[0] + q[2] * w[2] - q[3] * w[1])
    dq[2] = 0.5 * (q[0] * w[1] + q[3] * w[0] - q[1] * w[2])
    dq[3] = 0.5 * (q[0] * w[2] + q[1] * w[1] - q[2] * w[0])
    dw[0] = (inertia[1] - inertia[2]) * w[1] * w[2] / inertia[0]
    dw[1] = (inertia[2] - inertia[0]) * w[2] * w[0] / inertia[1]
    dw[2] = (inertia[0] - inertia[1]) * w[0] * w[1] / inertia[2]


@njit(cache=True, error_model="numpy")
def propagate_into(quaternion, omega, inertia, dt, substeps, out_q, out_w):
    """Fill ``out_q`` (N+1, 4) and ``out_w`` (N+1, 3) with the attitude and body rates at every step of ``dt`` [s]
    from (``quaternion``, ``omega``), ``substeps`` RK4 steps per step, the quaternion renormalised after each."""
    h = dt / substeps
    q, w = quaternion / math.sqrt(np.sum(quaternion * quaternion)), omega.copy()
    kq, kw = np.empty((4, 4)), np.empty((4, 3))
    sq, sw = np.empty(4), np.empty(3)
    out_q[0], out_w[0] = q, w
    for n in range(out_q.shape[0] - 1):
        for _ in range(substeps):
            _rates(q, w, inertia, kq[0], kw[0])
            for stage, scale in ((1, 0.5), (2, 0.5), (3, 1.0)):
                for i in range(4):
                    sq[i] = q[i] + scale * h * kq[stage - 1, i]
                for i in range(3):
                    sw[i] = w[i] + scale * h * kw[stage - 1, i]
                _rates(sq, sw, inertia, kq[stage], kw[stage])
            for i in range(4):
                q[i] = q[i] + h / 6.0 * (kq[0, i] + 2.0 * kq[1, i] + 2.0 * kq[2, i] + kq[3, i])
            for i in range(3):
                w[i] = w[i] + h / 6.0 * (kw[0, i] + 2.0 * kw[1, i] + 2.0 * kw[2, i] + kw[3, i])
            norm = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
            for i in range(4):
                q[i] = q[i] / norm
        out_q[n + 1], out_w[n + 1] = q, w
