"""Cumulative danger field (CDF) of an arm at an obstacle point, its gradient and the blend μ.

docs/model.md §6 (reconstructed eqs. R16-R18), after Lacevic & Rocco's kinetostatic danger field, static
part only. The arm is the chain of segments p_i → p_{i+1} between consecutive joint origins (and the
tool segment to the end-effector); zero-length segments are skipped. Each segment is
parameterised as r(s) = A + s (B − A), s ∈ [0, 1]:

.. math:: \\mathrm{CDF} = k_1 \\sum_{\\text{segments}} \\int_0^1 \\frac{ds}{\\|p_o - r(s)\\|}

The integrals and the joint-space gradient are evaluated in closed form (numerically stable for
points on the segment's extension), not by quadrature.
"""

from __future__ import annotations

import math

import numpy as np

from ffsr_gym.model import portable
from ffsr_gym.types import Array

_MIN_LENGTH = 1e-12
_MIN_HEIGHT = 1e-12


def _segment_integrals(p_o: Array, a: Array, b: Array) -> tuple[float, float, float, float]:
    """Integrals over s ∈ [0, 1] of 1/ρ, 1/ρ³ and s/ρ³ with ρ = ||p_o − r(s)||, and min ρ [m]."""
    L = b - a
    length = math.sqrt(L @ L)
    w = p_o - a
    t0 = (w @ L) / length
    cross = np.cross(L, w)
    h = max(math.sqrt(cross @ cross) / length, _MIN_HEIGHT)
    tau1, tau2 = -t0, length - t0
    rho1, rho2 = math.hypot(tau1, h), math.hypot(tau2, h)
    lo, hi, r_lo, r_hi = (tau1, tau2, rho1, rho2) if tau2 > 0.0 else (-tau2, -tau1, rho2, rho1)
    if lo >= 0.0:  # the foot of the perpendicular is off the segment: avoid cancellation
        inv1 = math.log((hi + r_hi) / (lo + r_lo))
        inv3 = (hi * hi - lo * lo) / (r_lo * r_hi * (hi * r_lo + lo * r_hi))
        nearest = r_lo
    else:
        inv1 = math.asinh(hi / h) + math.asinh(-lo / h)
        inv3 = (hi / r_hi - lo / r_lo) / (h * h)
        nearest = h
    F = inv1 / length
    I0 = inv3 / length
    I1 = (1.0 / rho1 - 1.0 / rho2) / (length * length) + (t0 / length) * I0
    return F, I0, I1, nearest


def danger_field(points: Array, p_o: Array, k1: float = 1.0) -> tuple[float, float]:
    """CDF of one arm at ``p_o`` and the arm's distance to ``p_o`` (R16).

    Args:
        points: (7, 3) joint origins p_0..p_5 and end-effector p_6 [m].
        p_o: obstacle point [m].
        k1: field gain.

    Returns:
        ``(cdf, distance)``: CDF [1/m · (field units)], shortest distance from ``p_o`` to a
        segment [m].
    """
    total, distance = 0.0, math.inf
    for a, b in zip(points[:-1], points[1:]):
        if portable.norm(b - a) < _MIN_LENGTH:
            continue
        F, _, _, nearest = _segment_integrals(p_o, a, b)
        total += F
        distance = min(distance, nearest)
    return k1 * total, distance


def danger_field_gradient(points: Array, axes: Array, p_o: Array, k1: float = 1.0) -> Array:
    """Joint-space gradient of the arm's CDF at ``p_o``, fixed base (R17).

    :math:`\\partial\\mathrm{CDF}/\\partial\\theta_k = k_1 \\sum_{i \\ge k} \\int_0^1 (z_k \\times (r - p_k))
    \\cdot (p_o - r) / \\|p_o - r\\|^3 ds`, evaluated as
    :math:`z_k \\cdot (c_0 I_0 + c_1 I_1)` with :math:`c_0 = (A - p_k) \\times (p_o - A)` and
    :math:`c_1 = (B - A) \\times (p_o - p_k)`.

    Args:
        points: (7, 3) joint origins and end-effector [m].
        axes: (6, 3) joint axes z_0..z_5 (unit, world frame).
        p_o: obstacle point [m].
        k1: field gain.

    Returns:
        (6,) gradient [field units per rad].
    """
    grad = np.zeros(len(axes))
    for i, (a, b) in enumerate(zip(points[:-1], points[1:])):
        if portable.norm(b - a) < _MIN_LENGTH:
            continue
        _, I0, I1, _ = _segment_integrals(p_o, a, b)
        for k in range(i + 1):
            c0 = np.cross(a - points[k], p_o - a)
            c1 = np.cross(b - a, p_o - points[k])
            grad[k] += axes[k] @ (c0 * I0 + c1 * I1)
    return k1 * grad


def blend_factor(cdf: float, distance: float, *, law: str, delta: float, danger_radius: float) -> float:
    """Blend μ ∈ [0, 1] between tracking (1) and avoidance (R18).

    ``law="cdf"``: μ = min(1, Δ / CDF). ``law="distance"``: μ = min(1, d / d_s)².
    """
    if law == "cdf":
        return 1.0 if cdf <= delta else delta / cdf
    return min(1.0, distance / danger_radius) ** 2
