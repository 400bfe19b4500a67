"""Compiled (numba) planner step and closed loop: ``ffsr_gym.planner`` + ``ffsr_gym.rollout`` in one kernel.

Same equations as the Pinocchio reference (docs/model.md §3-8), validated against it to 1e-9 on
every trajectory array (``tests/test_kernel.py``). Settings travel in two vectors built by
:mod:`ffsr_gym.kernel_rollout`: ``fp`` (floats, indices ``F_*``) and ``ip`` (integers, ``I_*``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ffsr_gym.kernel_linalg import cross, dot, mmt, mv, solve, svd
from ffsr_gym.kernel_physics import (
    R_to_quat_wxyz, capsule_ends, kinematics_into, midpoint_step, momentum_about_base, momentum_into,
    obstacle_clearance, self_clearance, skew, velocity_from_workspace, workspace,
)

F_M, F_TC, F_K, F_LAM1, F_LAM2, F_EPS1, F_EPS2, F_XI, F_DELTA, F_K1, F_DANGER, F_OBS_R = range(12)
F_TF, F_TA, F_ANGLE, F_DT, F_RATE_MAX = 12, 13, 14, 15, 16
F_P0, F_P1, F_Q0, F_AXIS, F_OBS, F_R0D, F_SBD, F_H = 17, 20, 23, 27, 30, 33, 36, 40
N_FP = 46
I_METHOD, I_PHI, I_SPLIT, I_ATT, I_MU, I_BAL_AVOID, I_HAS_OBS, I_SCOPE = range(8)
N_IP = 8
METHOD_CODES = {"no_avoidance": 0, "no_feedback": 1, "proportional": 2, "predefined_time": 3}
_CAP = 700.0


@njit(cache=True)
def qmul(a, b):
    out = np.empty(4)
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3]
    out[1:4] = a[0] * b[1:4] + b[0] * a[1:4] + cross(a[1:4], b[1:4])
    return out


@njit(cache=True)
def qconj(a):
    return np.array([a[0], -a[1], -a[2], -a[3]])


@njit(cache=True)
def phi(x, T_c, m, printed):
    r = math.sqrt(dot(x, x))
    if r == 0.0:
        return np.zeros_like(x)
    log_r = math.log(r)
    log_mag = min(math.exp(m * log_r), _CAP) - math.log(m * T_c)
    if not printed:
        log_mag += (1.0 - m) * log_r
    return (x / r) * math.exp(min(log_mag, _CAP))


@njit(cache=True)
def feedback(e, fp, ip):
    method = ip[I_METHOD]
    if method == 1:
        return np.zeros(6)
    if method == 2:
        return fp[F_K] * e
    printed = ip[I_PHI] == 1
    if ip[I_SPLIT] == 1:
        out = np.empty(6)
        out[0:3] = phi(e[0:3], fp[F_TC], fp[F_M], printed)
        out[3:6] = phi(e[3:6], fp[F_TC], fp[F_M], printed)
        return out
    return phi(e, fp[F_TC], fp[F_M], printed)


@njit(cache=True)
def pose_error(p, sigma, p_d, sigma_d, body):
    """e (6), J (6, 6), J_d (6, 6) of ``ffsr_gym.pose_error.pose_error``."""
    s = sigma.copy()
    if dot(s, sigma_d) < 0.0:
        s = -s
    J = np.eye(6)
    J_d = np.eye(6)
    e = np.empty(6)
    e[0:3] = p - p_d
    if body:
        d = qmul(qconj(sigma_d), s)
        eta, eps = d[0], d[1:4]
        w, v = s[0], s[1:4]
        Re = (w * w - dot(v, v)) * np.eye(3) + 2.0 * np.outer(v, v) + 2.0 * w * skew(v)
        Jo = mmt(0.5 * (eta * np.eye(3) + skew(eps)), Re)
        J[3:6, 3:6] = Jo
        J_d[3:6, 3:6] = Jo
    else:
        d = qmul(s, qconj(sigma_d))
        eta, eps = d[0], d[1:4]
        J[3:6, 3:6] = 0.5 * (eta * np.eye(3) - skew(eps))
        J_d[3:6, 3:6] = 0.5 * (eta * np.eye(3) + skew(eps))
    e[3:6] = eps
    return e, J, J_d


@njit(cache=True)
def desired(t, fp):
    t_f, t_a = fp[F_TF], fp[F_TA]
    speed = 1.0 / (t_f - t_a)
    acc = speed / t_a
    if t <= 0.0:
        s, sd = 0.0, 0.0
    elif t < t_a:
        s, sd = 0.5 * acc * t * t, acc * t
    elif t <= t_f - t_a:
        s, sd = 0.5 * acc * t_a * t_a + speed * (t - t_a), speed
    elif t < t_f:
        s, sd = 1.0 - 0.5 * acc * (t_f - t) ** 2, acc * (t_f - t)
    else:
        s, sd = 1.0, 0.0
    p0, p1, axis, angle = fp[F_P0:F_P0 + 3], fp[F_P1:F_P1 + 3], fp[F_AXIS:F_AXIS + 3], fp[F_ANGLE]
    rot = np.empty(4)
    rot[0] = math.cos(0.5 * s * angle)
    rot[1:4] = math.sin(0.5 * s * angle) * axis
    twist = np.empty(6)
    twist[0:3] = sd * (p1 - p0)
    twist[3:6] = sd * angle * axis
    return p0 + s * (p1 - p0), qmul(rot, fp[F_Q0:F_Q0 + 4]), twist


@njit(cache=True)
def filtered_inverse(J, lam_max, eps):
    U, s, V = svd(J)
    gain = np.zeros(6)
    for i in range(6):
        damping = lam_max * lam_max * (1.0 - (s[i] / eps) ** 2) if (eps > 0.0 and s[i] < eps) else 0.0
        denom = s[i] * s[i] + damping
        gain[i] = s[i] / denom if denom > 0.0 else 0.0
    J_sharp = mmt(V * gain, U)
    P = np.zeros((6, 6))
    tol = s[0] * 6.0 * 2.220446049250313e-16
    for i in range(6):
        if s[i] > tol:
            for r in range(6):
                for c in range(6):
                    P[r, c] += V[r, i] * V[c, i]
    return J_sharp, P, s[5]


@njit(cache=True)
def _integrals(p_o, a, b):
    L = b - a
    length = math.sqrt(dot(L, L))
    w = p_o - a
    t0 = dot(w, L) / length
    cr = cross(L, w)
    h = max(math.sqrt(dot(cr, cr)) / length, 1e-12)
    tau1, tau2 = -t0, length - t0
    rho1, rho2 = math.hypot(tau1, h), math.hypot(tau2, h)
    if tau2 > 0.0:
        lo, hi, r_lo, r_hi = tau1, tau2, rho1, rho2
    else:
        lo, hi, r_lo, r_hi = -tau2, -tau1, rho2, rho1
    if lo >= 0.0:
        inv1 = math.log((hi + r_hi) / (lo + r_lo))
        inv3 = (hi * hi - lo * lo) / (r_lo * r_hi * (hi * r_lo + lo * r_hi))
        nearest = r_lo
    else:
        inv1 = math.asinh(hi / h) + math.asinh(-lo / h)
        inv3 = (hi / r_hi - lo / r_lo) / (h * h)
        nearest = h
    I0 = inv3 / length
    return inv1 / length, I0, (1.0 / rho1 - 1.0 / rho2) / (length * length) + (t0 / length) * I0, nearest


@njit(cache=True)
def avoidance(points, axes, p_o, fp, ip, arm):
    """μ, Θ̇_c (6), CDF and distance of one arm (``Planner._avoidance``)."""
    total, dist = 0.0, 1e300
    I0s, I1s = np.zeros(6), np.zeros(6)
    for i in range(6):
        a, b = points[i], points[i + 1]
        d = b - a
        if math.sqrt(dot(d, d)) < 1e-12:
            continue
        F, I0s[i], I1s[i], nearest = _integrals(p_o, a, b)
        total += F
        dist = min(dist, nearest)
    cdf = fp[F_K1] * total
    if ip[I_MU] == 0:
        mu = 1.0 if cdf <= fp[F_DELTA] else fp[F_DELTA] / cdf
    else:
        mu = min(1.0, dist / fp[F_DANGER]) ** 2
    if ip[I_METHOD] == 0 or (arm == 1 and ip[I_BAL_AVOID] == 0):
        mu = 1.0
    if mu >= 1.0:
        return 1.0, np.zeros(6), cdf, dist
    grad = np.zeros(6)  # only needed while the avoidance acts
    for i in range(6):
        a, b = points[i], points[i + 1]
        if I0s[i] == 0.0 and I1s[i] == 0.0:
            continue  # zero-length segment
        for k in range(i + 1):
            c0 = cross(a - points[k], p_o - a)
            c1 = cross(b - a, p_o - points[k])
            grad[k] += dot(axes[k], c0 * I0s[i] + c1 * I1s[i])
    return mu, -fp[F_XI] * fp[F_K1] * grad, cdf, dist


@njit(cache=True)
def plan(mdl, x, t, fp, ip, ws):
    """Joint rates (12) and diagnostics at (t, x): SPEC §7 steps 1-8 (fills the workspace at x)."""
    kinematics_into(mdl, x, ws)
    momentum_into(mdl, x, ws)
    pj, Re, pe, z, H_b, H_bm, rg = ws[1], ws[3], ws[4], ws[5], ws[6], ws[7], ws[8]
    r0 = x[0:3]
    sigma_b = np.array([x[6], x[3], x[4], x[5]])
    e0, J_b, _ = pose_error(r0, sigma_b, fp[F_R0D:F_R0D + 3], fp[F_SBD:F_SBD + 4], ip[I_ATT] == 1)
    V0 = -solve(J_b, feedback(e0, fp, ip))
    p_d, sigma_d, V_ed = desired(t, fp)
    e1, J_e, J_ed = pose_error(pe[0], R_to_quat_wxyz(Re[0]), p_d, sigma_d, ip[I_ATT] == 1)
    J0 = np.eye(6)
    J0[0:3, 3:6] = -skew(pe[0] - r0)
    x1 = solve(J_e, mv(J_ed, V_ed) - feedback(e1, fp, ip)) - mv(J0, V0)
    mu = np.ones(2)
    cdf = np.zeros(2)
    dist = np.full(2, np.inf)
    smin = np.empty(2)
    dq = np.empty(12)
    for arm in range(2):
        points = np.empty((7, 3))
        points[0:6] = pj[6 * arm:6 * arm + 6]
        points[6] = pe[arm]
        dq_c = np.zeros(6)
        if ip[I_HAS_OBS] == 1:
            mu[arm], dq_c, cdf[arm], dist[arm] = avoidance(points, z[6 * arm:6 * arm + 6], fp[F_OBS:F_OBS + 3], fp, ip, arm)
        if arm == 0:
            J = np.empty((6, 6))
            for k in range(6):
                J[0:3, k] = cross(z[k], pe[0] - pj[k])
                J[3:6, k] = z[k]
            J_sharp, P, smin[0] = filtered_inverse(J, fp[F_LAM1], fp[F_EPS1])
            target = x1
        else:
            C = momentum_about_base(fp[F_H:F_H + 6], rg, r0)
            target = mv(H_bm[0], dq[0:6]) + mv(H_b, V0) - C
            J_sharp, P, smin[1] = filtered_inverse(-H_bm[1], fp[F_LAM2], fp[F_EPS2])
        dq[6 * arm:6 * arm + 6] = mu[arm] * mv(J_sharp, target) + (dq_c - mu[arm] * mv(P, dq_c))
    return dq, e1, e0, mu, cdf, smin


@njit(cache=True)
def run(mdl, x, k0, n_total, n_max, fp, ip, residual, stop_on_violation, record_only, out_x, out_v, out_dq, out_err,
        out_clear, out_self, out_mu, out_cdf, out_smin):
    """Advance up to ``n_max`` steps from step ``k0`` (or only record when ``record_only``).

    Writes one sample per step into the ``out_*`` arrays (from row 0) and returns
    ``(x_next, rows, status)``: status 0 ok, 1 rate-limit violation, 2 collision, 3 non-finite rates.
    """
    dt, h = fp[F_DT], fp[F_H:F_H + 6]
    to_deg = 180.0 / math.pi
    first = 6 if ip[I_SCOPE] == 1 else 0
    rows, status = 0, 0
    ws = workspace()
    steps = 1 if record_only else min(n_max, n_total - k0)
    for i in range(steps):
        t = (k0 + i) * dt
        dq, e1, e0, mu, cdf, smin = plan(mdl, x, t, fp, ip, ws)
        dq = dq + residual
        for j in range(12):
            if not math.isfinite(dq[j]):
                return x, rows, 3
        R_b = ws[2]
        A, B = capsule_ends(mdl, ws[0], ws[1], R_b, x[0:3])
        clear = 1e300
        if ip[I_HAS_OBS] == 1:
            clear = obstacle_clearance(mdl, A, B, R_b, x[0:3], fp[F_OBS:F_OBS + 3], fp[F_OBS_R])[0]
        self_c = self_clearance(mdl, A, B, R_b, x[0:3])
        out_x[i] = x
        v0 = velocity_from_workspace(x, dq, h, ws)
        out_v[i, 0:6] = v0
        out_v[i, 6:18] = dq
        out_dq[i] = dq
        out_err[i, 0] = math.sqrt(dot(e1[0:3], e1[0:3]))
        out_err[i, 1] = math.sqrt(dot(e1[3:6], e1[3:6]))
        out_err[i, 2] = math.sqrt(dot(e0[0:3], e0[0:3]))
        out_err[i, 3] = math.sqrt(dot(e0[3:6], e0[3:6]))
        out_clear[i] = clear if ip[I_HAS_OBS] == 1 else np.inf
        out_self[i] = self_c
        out_mu[i] = mu
        out_cdf[i] = cdf
        out_smin[i] = smin
        rows += 1
        if record_only:
            return x, rows, 0
        x = midpoint_step(mdl, x, v0, dq, dt, h, ws)
        if stop_on_violation:
            for j in range(first, 12):
                if abs(dq[j]) * to_deg > fp[F_RATE_MAX]:
                    status = 1
            if status == 0 and (clear < 0.0 or self_c < 0.0):
                status = 2
            if status != 0:
                return x, rows, status
    return x, rows, status


@njit(cache=True)
def observe(mdl, x, t, fp, ip):
    """EE error (6), base error (6), obstacle-relative vector (3) and clearance at (t, x)."""
    ws = workspace()
    _, e1, e0, _, _, _ = plan(mdl, x, t, fp, ip, ws)
    rel = np.zeros(3)
    clear = np.inf
    if ip[I_HAS_OBS] == 1:
        R_b = ws[2]
        A, B = capsule_ends(mdl, ws[0], ws[1], R_b, x[0:3])
        clear, rel = obstacle_clearance(mdl, A, B, R_b, x[0:3], fp[F_OBS:F_OBS + 3], fp[F_OBS_R])
    return e1, e0, rel, clear
