"""Compiled (numba) danger field of an arm (``ffsr_gym.planning.avoidance``): the CDF of every obstacle point (and
of a tumbling target's centre) along the arm's segments, in closed form, its joint-space gradient and the blend μ.
Validated against the reference to 1e-9 (``tests/test_kernel.py``)."""

from __future__ import annotations

import math

from numba import njit

from ffsr_gym.kernel.physics import MAX_OBSTACLES
from ffsr_gym.kernel.settings import (
    F_BODY_DANGER,
    F_BODY_RB,
    F_DANGER,
    F_DELTA,
    F_K1,
    F_XI,
    I_BAL_AVOID,
    I_METHOD,
    I_MU,
    I_N_OBS,
    frame_record,
    obstacle_at,
)


@njit(cache=True, error_model="numpy", inline="always")
def _field_of_segment(ox, oy, oz, points, i, geometry):
    """Integral of 1/ρ along segment i (points i → i+1) seen from the obstacle point (ox, oy, oz), and its
    nearest distance [m]; stores (length, t0, h, ρ1, ρ2) in ``geometry`` (5) for :func:`_moments_of_segment`.

    Returns (0, inf) for a zero-length segment (skipped, as the reference skips it). Both ends' distances
    are plain norms (ρ1 = |p_o − a|, ρ2 = |p_o − b|), and the two inverse hyperbolic sines of a foot on
    the segment are one logarithm: asinh(u/h) + asinh(v/h) = log((u + ρ_u)(v + ρ_v) / h²).
    """
    ax, ay, az = points[i, 0], points[i, 1], points[i, 2]
    Lx, Ly, Lz = points[i + 1, 0] - ax, points[i + 1, 1] - ay, points[i + 1, 2] - az
    length = math.sqrt(Lx * Lx + Ly * Ly + Lz * Lz)
    geometry[0] = length
    if length < 1e-12:
        return 0.0, math.inf
    wx, wy, wz = ox - ax, oy - ay, oz - az
    t0 = (wx * Lx + wy * Ly + wz * Lz) / length
    cx, cy, cz = Ly * wz - Lz * wy, Lz * wx - Lx * wz, Lx * wy - Ly * wx
    h = max(math.sqrt(cx * cx + cy * cy + cz * cz) / length, 1e-12)
    rho1 = math.sqrt(wx * wx + wy * wy + wz * wz)
    vx, vy, vz = wx - Lx, wy - Ly, wz - Lz
    rho2 = math.sqrt(vx * vx + vy * vy + vz * vz)
    geometry[1], geometry[2], geometry[3], geometry[4] = t0, h, rho1, rho2
    tau1, tau2 = -t0, length - t0
    if tau2 > 0.0:
        lo, hi, r_lo, r_hi = tau1, tau2, rho1, rho2
    else:
        lo, hi, r_lo, r_hi = -tau2, -tau1, rho2, rho1
    if lo >= 0.0:  # the foot of the perpendicular is off the segment
        return math.log((hi + r_hi) / (lo + r_lo)) / length, r_lo
    return math.log((hi + r_hi) * (r_lo - lo) / (h * h)) / length, h


@njit(cache=True, error_model="numpy", inline="always")
def _moments_of_segment(geometry):
    """(I0, I1): integrals of 1/ρ³ and s/ρ³ along a segment from its ``geometry`` (:func:`_field_of_segment`)."""
    length, t0, h, rho1, rho2 = geometry[0], geometry[1], geometry[2], geometry[3], geometry[4]
    tau1, tau2 = -t0, length - t0
    if tau2 > 0.0:
        lo, hi, r_lo, r_hi = tau1, tau2, rho1, rho2
    else:
        lo, hi, r_lo, r_hi = -tau2, -tau1, rho2, rho1
    if lo >= 0.0:
        inv3 = (hi * hi - lo * lo) / (r_lo * r_hi * (hi * r_lo + lo * r_hi))
    else:
        inv3 = (hi / r_hi - lo / r_lo) / (h * h)
    I0 = inv3 / length
    return I0, (1.0 / rho1 - 1.0 / rho2) / (length * length) + (t0 / length) * I0


@njit(cache=True, error_model="numpy", inline="always")
def avoidance_into(ws, fp, ip, arm, t):
    """μ and CDF of one arm at time ``t`` (``Planner._avoidance``); Θ̇_c (6) into ``ws.dq_c``.

    The CDF and its gradient sum over the obstacles, the distance is the smallest (docs/model.md §14).
    The gradient pass, needed only while μ < 1, reuses each segment's geometry from the field pass.
    """
    points, z, dq_c, pj, pe, seg = ws.points, ws.z, ws.dq_c, ws.pj, ws.pe, ws.seg
    for a in range(3):
        for i in range(6):
            points[i, a] = pj[6 * arm + i, a]
        points[6, a] = pe[arm, a]
    total, dist = 0.0, 1e300
    n_obs = ip[I_N_OBS]
    for o in range(n_obs):
        ox, oy, oz = obstacle_at(fp, o, t)
        for i in range(6):
            F, nearest = _field_of_segment(ox, oy, oz, points, i, seg[6 * o + i])
            total += F
            dist = min(dist, nearest)
    ratio = dist / fp[F_DANGER] if n_obs > 0 else math.inf
    body = fp[F_BODY_DANGER] > 0.0
    if body:  # the tumbling body's centre: every segment but the tool's, seen from its bounding sphere (§22)
        r = frame_record(t, fp, ip) + 13
        near = math.inf
        for i in range(5):
            F, nearest = _field_of_segment(fp[r], fp[r + 1], fp[r + 2], points, i, seg[6 * MAX_OBSTACLES + i])
            total += F
            near = min(near, nearest)
        ratio = min(ratio, (near - fp[F_BODY_RB]) / fp[F_BODY_DANGER])
    cdf = fp[F_K1] * total
    if ip[I_MU] == 0:
        mu = 1.0 if cdf <= fp[F_DELTA] else fp[F_DELTA] / cdf
    else:
        mu = min(1.0, ratio) ** 2
    if ip[I_METHOD] == 0 or (arm == 1 and ip[I_BAL_AVOID] == 0):
        mu = 1.0
    dq_c[:] = 0.0
    if mu >= 1.0:
        return 1.0, cdf
    scale = -fp[F_XI] * fp[F_K1]  # Θ̇_c = −ξ k₁ ∂CDF/∂Θ, only needed while the avoidance acts
    for o in range(n_obs + 1 if body else n_obs):
        if o < n_obs:
            ox, oy, oz = obstacle_at(fp, o, t)
            base = 6 * o
        else:
            r = frame_record(t, fp, ip) + 13
            ox, oy, oz = fp[r], fp[r + 1], fp[r + 2]
            base = 6 * MAX_OBSTACLES
        for i in range(6 if o < n_obs else 5):
            geometry = seg[base + i]
            if geometry[0] < 1e-12:
                continue  # zero-length segment
            I0, I1 = _moments_of_segment(geometry)
            ax, ay, az = points[i, 0], points[i, 1], points[i, 2]
            bx, by, bz = points[i + 1, 0], points[i + 1, 1], points[i + 1, 2]
            for k in range(i + 1):
                px, py, pz = points[k, 0], points[k, 1], points[k, 2]
                ux, uy, uz = ax - px, ay - py, az - pz  # c0 = (a - p_k) x (p_o - a)
                wx, wy, wz = ox - ax, oy - ay, oz - az
                c0x, c0y, c0z = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
                ux, uy, uz = bx - ax, by - ay, bz - az  # c1 = (b - a) x (p_o - p_k)
                wx, wy, wz = ox - px, oy - py, oz - pz
                c1x, c1y, c1z = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
                j = 6 * arm + k
                dq_c[k] += scale * (z[j, 0] * (c0x * I0 + c1x * I1) + z[j, 1] * (c0y * I0 + c1y * I1)
                                    + z[j, 2] * (c0z * I0 + c1z * I1))
    return mu, cdf
