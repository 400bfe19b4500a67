"""Compiled (numba) planner step: ``ffsr_gym.planning.planner`` (with its pose errors, path, φ, danger field) in one kernel.

Same equations as the Pinocchio reference (docs/model.md §3-8), validated against it to 1e-9 on
every trajectory array (``tests/test_kernel.py``). Settings travel in two vectors built by
:mod:`ffsr_gym.sim.compiled`: ``fp`` (floats) and ``ip`` (integers), laid out by :mod:`ffsr_gym.kernel.settings`;
the danger field is :mod:`ffsr_gym.kernel.field`.
Results and intermediates live in the :data:`~ffsr_gym.kernel.physics.Workspace`; 3-vectors are
scalars, so a planner step allocates nothing.
"""

from __future__ import annotations

import math

from numba import njit

from ffsr_gym.kernel.field import avoidance_into
from ffsr_gym.kernel.inverse import filtered_solve_into
from ffsr_gym.kernel.linalg import smallest_singular_values, solve3
from ffsr_gym.kernel.physics import (
    R_to_quat_wxyz,
    kinematics_into,
    momentum_about_base_into,
    momentum_into,
)
from ffsr_gym.kernel.settings import (
    F_BODY_DANGER,
    F_EPS1,
    F_EPS2,
    F_H,
    F_K,
    F_LAM1,
    F_LAM2,
    F_M,
    F_P0,
    F_Q0,
    F_R0D,
    F_SBD,
    F_TA,
    F_TC,
    F_TF,
    F_TRUE,
    I_ATT,
    I_FRAMES,
    I_METHOD,
    I_N_OBS,
    I_PHI,
    I_SPLIT,
    estimate_record,
    frame_record,
)

_CAP = 700.0


@njit(cache=True, error_model="numpy", inline="always")
def _qmul(a0, a1, a2, a3, b0, b1, b2, b3):
    """Hamilton product of scalar-first quaternions a ⊗ b (4-tuple)."""
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + b0 * a1 + a2 * b3 - a3 * b2,
            a0 * b2 + b0 * a2 + a3 * b1 - a1 * b3,
            a0 * b3 + b0 * a3 + a1 * b2 - a2 * b1)


@njit(cache=True, error_model="numpy")
def _phi_scale(r, T_c, m, printed):
    """φ(x) = (x / r) · scale with r = |x| (``ffsr_gym.planning.ptsf.phi``, log-space, capped at e^700)."""
    if r == 0.0:
        return 0.0
    log_r = math.log(r)
    log_mag = min(math.exp(m * log_r), _CAP) - math.log(m * T_c)
    if not printed:
        log_mag += (1.0 - m) * log_r
    return math.exp(min(log_mag, _CAP))


@njit(cache=True, error_model="numpy", inline="always")
def feedback_into(out, e, fp, ip):
    """Feedback term of the planner for the pose error ``e`` (6): 0, K e, or φ(e) (whole or split)."""
    method = ip[I_METHOD]
    if method == 1:
        out[:] = 0.0
        return
    if method == 2:
        for i in range(6):
            out[i] = fp[F_K] * e[i]
        return
    printed = ip[I_PHI] == 1
    for part in range(2 if ip[I_SPLIT] == 1 else 1):
        lo, hi = (3 * part, 3 * part + 3) if ip[I_SPLIT] == 1 else (0, 6)
        norm = 0.0
        for i in range(lo, hi):
            norm += e[i] * e[i]
        r = math.sqrt(norm)
        scale = _phi_scale(r, fp[F_TC], fp[F_M], printed)
        for i in range(lo, hi):
            out[i] = (e[i] / r) * scale if r > 0.0 else 0.0


@njit(cache=True, error_model="numpy", inline="always")
def pose_error_into(e, Jo, Jo_d, p, sigma, p_d, sigma_d, body):
    """Pose error e = [p − p_d; e_o] (6) and the attitude blocks J_o, J_od of ``ffsr_gym.planning.pose_error``.

    ``sigma`` is a scalar-first 4-tuple; J = blkdiag(I, J_o), J_d = blkdiag(I, J_od).
    """
    sw, sx, sy, sz = sigma
    if sw * sigma_d[0] + sx * sigma_d[1] + sy * sigma_d[2] + sz * sigma_d[3] < 0.0:
        sw, sx, sy, sz = -sw, -sx, -sy, -sz
    for a in range(3):
        e[a] = p[a] - p_d[a]
    if body:
        eta, e0, e1, e2 = _qmul(sigma_d[0], -sigma_d[1], -sigma_d[2], -sigma_d[3], sw, sx, sy, sz)
        A = ((eta, -e2, e1), (e2, eta, -e0), (-e1, e0, eta))  # eta I + S(eps)
        vv = sx * sx + sy * sy + sz * sz
        Rs = ((sw * sw - vv + 2 * sx * sx, 2 * (sx * sy - sw * sz), 2 * (sx * sz + sw * sy)),
              (2 * (sx * sy + sw * sz), sw * sw - vv + 2 * sy * sy, 2 * (sy * sz - sw * sx)),
              (2 * (sx * sz - sw * sy), 2 * (sy * sz + sw * sx), sw * sw - vv + 2 * sz * sz))
        for r in range(3):
            for c in range(3):
                Jo[r, c] = 0.5 * (A[r][0] * Rs[c][0] + A[r][1] * Rs[c][1] + A[r][2] * Rs[c][2])
                Jo_d[r, c] = Jo[r, c]
    else:
        eta, e0, e1, e2 = _qmul(sw, sx, sy, sz, sigma_d[0], -sigma_d[1], -sigma_d[2], -sigma_d[3])
        S = ((0.0, -e2, e1), (e2, 0.0, -e0), (-e1, e0, 0.0))
        for r in range(3):
            for c in range(3):
                diagonal = eta if r == c else 0.0
                Jo[r, c] = 0.5 * (diagonal - S[r][c])
                Jo_d[r, c] = 0.5 * (diagonal + S[r][c])
    e[3], e[4], e[5] = e0, e1, e2


@njit(cache=True, error_model="numpy", inline="always")
def moving_desired_into(p_d, sigma_d, V_ed, t, fp, ip):
    """Desired EE pose and world twist at t [s] onto a moving grasp frame: the record of the step
    (``ffsr_gym.planning.moving_target.MovingTargetPath``, sampled once per scenario)."""
    r = frame_record(t, fp, ip)
    for i in range(3):
        p_d[i] = fp[r + i]
    for i in range(4):
        sigma_d[i] = fp[r + 3 + i]
    for i in range(6):
        V_ed[i] = fp[r + 7 + i]


@njit(cache=True, error_model="numpy", inline="always")
def desired_into(p_d, sigma_d, V_ed, t, fp, rec):
    """Desired EE pose and world twist at t [s] towards the target record at ``fp[rec]``
    (``ffsr_gym.planning.desired_path``: trapezoid + SLERP)."""
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
    axis = rec + 3
    angle = fp[rec + 6]
    ch, sh = math.cos(0.5 * s * angle), math.sin(0.5 * s * angle)
    for a in range(3):
        p_d[a] = fp[F_P0 + a] + s * (fp[rec + a] - fp[F_P0 + a])
        V_ed[a] = sd * (fp[rec + a] - fp[F_P0 + a])
        V_ed[3 + a] = sd * angle * fp[axis + a]
    q = fp[F_Q0:F_Q0 + 4]
    sigma_d[0], sigma_d[1], sigma_d[2], sigma_d[3] = _qmul(
        ch, sh * fp[axis], sh * fp[axis + 1], sh * fp[axis + 2], q[0], q[1], q[2], q[3])


@njit(cache=True, error_model="numpy", inline="always")
def true_error_into(ws, t, fp, ip):
    """EE pose error to the true desired pose into ``ws.e1t`` (after :func:`plan` at the same state)."""
    desired_into(ws.p_d, ws.sigma_d, ws.V_ed, t, fp, F_TRUE)
    pose_error_into(ws.e1t, ws.Jo, ws.Jo_d, ws.pe[0], R_to_quat_wxyz(ws.Re[0]), ws.p_d, ws.sigma_d, ip[I_ATT] == 1)


@njit(cache=True, error_model="numpy", inline="always")
def _base_command_into(x, fp, ip, ws):
    """Commanded base twist V0 = −J_b⁻¹ f(e₀) into ``ws.V0`` (base pose error in ``ws.e0``)."""
    pose_error_into(ws.e0, ws.Jo, ws.Jo_d, x, (x[6], x[3], x[4], x[5]), fp[F_R0D:F_R0D + 3], fp[F_SBD:F_SBD + 4],
                    ip[I_ATT] == 1)
    f = ws.target
    feedback_into(f, ws.e0, fp, ip)
    ws.V0[0], ws.V0[1], ws.V0[2] = -f[0], -f[1], -f[2]
    w0, w1, w2 = solve3(ws.Jo, f[3], f[4], f[5])
    ws.V0[3], ws.V0[4], ws.V0[5] = -w0, -w1, -w2


@njit(cache=True, error_model="numpy", inline="always")
def _mission_task_into(x, t, fp, ip, ws):
    """Mission-arm task rate x₁ = J_e⁻¹(J_ed V_ed − f(e₁)) − J₀ V0 into ``ws.x1`` (EE error in ``ws.e1``)."""
    if ip[I_FRAMES] > 0:
        moving_desired_into(ws.p_d, ws.sigma_d, ws.V_ed, t, fp, ip)
    else:
        desired_into(ws.p_d, ws.sigma_d, ws.V_ed, t, fp, estimate_record(t, fp, ip))
    pe = ws.pe[0]
    pose_error_into(ws.e1, ws.Jo, ws.Jo_d, pe, R_to_quat_wxyz(ws.Re[0]), ws.p_d, ws.sigma_d, ip[I_ATT] == 1)
    f, V_ed, V0, x1, Jd = ws.target, ws.V_ed, ws.V0, ws.x1, ws.Jo_d
    feedback_into(f, ws.e1, fp, ip)
    r0 = Jd[0, 0] * V_ed[3] + Jd[0, 1] * V_ed[4] + Jd[0, 2] * V_ed[5] - f[3]
    r1 = Jd[1, 0] * V_ed[3] + Jd[1, 1] * V_ed[4] + Jd[1, 2] * V_ed[5] - f[4]
    r2 = Jd[2, 0] * V_ed[3] + Jd[2, 1] * V_ed[4] + Jd[2, 2] * V_ed[5] - f[5]
    w0, w1, w2 = solve3(ws.Jo, r0, r1, r2)
    dx, dy, dz = pe[0] - x[0], pe[1] - x[1], pe[2] - x[2]  # J₀ V0 = [v − d × ω; ω]
    x1[0] = V_ed[0] - f[0] - (V0[0] - (dy * V0[5] - dz * V0[4]))
    x1[1] = V_ed[1] - f[1] - (V0[1] - (dz * V0[3] - dx * V0[5]))
    x1[2] = V_ed[2] - f[2] - (V0[2] - (dx * V0[4] - dy * V0[3]))
    x1[3], x1[4], x1[5] = w0 - V0[3], w1 - V0[4], w2 - V0[5]


@njit(cache=True, error_model="numpy", inline="always")
def plan(mdl, x, t, fp, ip, ws):
    """Joint rates and diagnostics at (t, x): docs/model.md §8 steps 1-8 (fills the workspace at x).

    Writes ``ws.dq`` (12, mission first), ``ws.e1``, ``ws.e0``, ``ws.mu``, ``ws.cdf``, ``ws.smin``.
    """
    kinematics_into(mdl, x, ws)
    momentum_into(mdl, x, ws)
    _base_command_into(x, fp, ip, ws)
    _mission_task_into(x, t, fp, ip, ws)
    J, Jb, dq, pj, pe, z, H_b, H_bm, V0 = ws.J, ws.Jb, ws.dq, ws.pj, ws.pe, ws.z, ws.H_b, ws.H_bm, ws.V0
    for k in range(6):  # geometric Jacobian of the mission arm (world)
        dx, dy, dz = pe[0, 0] - pj[k, 0], pe[0, 1] - pj[k, 1], pe[0, 2] - pj[k, 2]
        J[0, k], J[1, k] = z[k, 1] * dz - z[k, 2] * dy, z[k, 2] * dx - z[k, 0] * dz
        J[2, k] = z[k, 0] * dy - z[k, 1] * dx
        J[3, k], J[4, k], J[5, k] = z[k, 0], z[k, 1], z[k, 2]
    for r in range(6):  # the balance arm's: J_c² = −H_bm2
        for c in range(6):
            Jb[r, c] = -H_bm[1, r, c]
    s_mission, s_balance = smallest_singular_values(J, Jb, ws.G, ws.G_b, ws.tri, ws.tri_b)
    for arm in range(2):
        mu, cdf = 1.0, 0.0
        ws.dq_c[:] = 0.0
        if ip[I_N_OBS] > 0 or fp[F_BODY_DANGER] > 0.0:
            mu, cdf = avoidance_into(ws, fp, ip, arm, t)
        if arm == 0:
            A, s_min, target, lam, eps = J, s_mission, ws.x1, fp[F_LAM1], fp[F_EPS1]
        else:
            A, s_min, target, lam, eps = Jb, s_balance, ws.target, fp[F_LAM2], fp[F_EPS2]
            momentum_about_base_into(target, fp[F_H:F_H + 6], ws.rg, x)  # x₂ = H_bm1 Θ̇₁ + H_b V0 − C
            for r in range(6):
                acc = -target[r]
                for c in range(6):
                    acc += H_bm[0, r, c] * dq[c] + H_b[r, c] * V0[c]
                target[r] = acc
        ws.mu[arm], ws.cdf[arm] = mu, cdf
        ws.smin[arm] = filtered_solve_into(dq[6 * arm:6 * arm + 6], ws, A, s_min, target, lam, eps, mu, mu < 1.0)
