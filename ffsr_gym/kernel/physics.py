"""Compiled (numba) robot physics: kinematics, momentum, momentum-conserving base velocity, SE(3) step.

A re-implementation of ``ffsr_gym.model.robot`` for the kernel, validated against it to 1e-9
(``tests/test_kernel.py``). State layout ``x`` (19): base position [m], base quaternion
(x, y, z, w), 12 joint angles [rad] mission arm first. Model arrays come from
:func:`ffsr_gym.kernel.arrays.extract`, passed as the tuple ``mdl`` in declaration order. Every
routine writes into a :data:`Workspace` made once per call of the kernel: nothing is allocated
inside the time loop.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from ffsr_gym.kernel.linalg import solve_sym3

#: Obstacle slots of the planner's settings vector (``ffsr_gym.kernel.planner``), sizing the danger-field buffer.
MAX_OBSTACLES = 8

#: Buffers of one closed loop (kinematics, momentum, planner, collision, integrator).
Workspace = namedtuple("Workspace", [
    "Rj", "pj", "R_b", "Re", "pe", "z",  # joint frames, base rotation, EE frames, joint axes (world)
    "H_b", "H_bm", "rg", "comp",  # momentum matrices, system CoM, composite bodies (mass, D, A: momentum_into)
    "tmp", "rot", "M6", "b6", "x_half", "v_mid",  # scratch
    "J", "U", "V", "s", "G", "tri", "Jo", "Jo_d", "points", "p_obs", "dq_c",  # planner
    "V0", "x1", "target", "p_d", "sigma_d", "V_ed",
    "dq", "e1", "e0", "mu", "cdf", "smin", "v0", "e1t",  # planner outputs (e1t: EE error to the true target)
    "cap_A", "cap_B", "cap_mid", "cap_hl", "bound", "first", "second", "rel", "cand",  # collision
    "Jb", "G_b", "tri_b",  # the balance arm's Jacobian, Gram matrix and tridiagonal form (both arms' σ_min run together)
    "cs",  # cos, sin of the joint angles at the last planned state, and those angles (kinematics_into)
    "seg",  # danger field: (length, t0, h, ρ1, ρ2) of each obstacle's (then a tumbling body's) view of each arm segment
])


@njit(cache=True, error_model="numpy")
def workspace(n_capsules):
    """A fresh :data:`Workspace` for a robot with ``n_capsules`` collision capsules."""
    n_pairs = n_capsules * n_capsules + n_capsules
    return Workspace(
        np.empty((12, 3, 3)), np.empty((12, 3)), np.empty((3, 3)), np.empty((2, 3, 3)), np.empty((2, 3)),
        np.empty((12, 3)), np.empty((6, 6)), np.empty((2, 6, 6)), np.empty(3), np.empty((12, 10)),
        np.empty((3, 3)), np.empty((3, 3)), np.empty((6, 6)), np.empty(6), np.empty(19),
        np.empty(6), np.empty((6, 6)), np.empty((6, 6)), np.empty((6, 6)), np.empty(6), np.empty((6, 6)),
        np.empty((2, 6)), np.empty((3, 3)),
        np.empty((3, 3)), np.empty((7, 3)), np.empty(3), np.empty(6), np.empty(6), np.empty(6),
        np.empty(6), np.empty(3), np.empty(4), np.empty(6), np.empty(12), np.empty(6), np.empty(6), np.empty(2),
        np.empty(2), np.empty(2), np.empty(6), np.empty(6), np.empty((n_capsules, 3)), np.empty((n_capsules, 3)),
        np.empty((n_capsules, 3)), np.empty(n_capsules), np.empty(n_pairs), np.empty(n_pairs, dtype=np.int64),
        np.empty(n_pairs, dtype=np.int64), np.empty(3), np.empty(23), np.empty((6, 6)), np.empty((6, 6)), np.empty((2, 6)),
        np.full((3, 12), np.nan), np.empty((6 * MAX_OBSTACLES + 6, 5)),
    )


@njit(cache=True, error_model="numpy")
def quat_into(R, qx, qy, qz, qw):
    """Rotation matrix of the unit quaternion (x, y, z, w)."""
    R[0, 0], R[0, 1], R[0, 2] = 1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)
    R[1, 0], R[1, 1], R[1, 2] = 2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)
    R[2, 0], R[2, 1], R[2, 2] = 2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)


@njit(cache=True, error_model="numpy")
def R_to_quat_wxyz(R):
    """Scalar-first unit quaternion (w, x, y, z) with w >= 0 of a rotation matrix (Shepperd's method)."""
    t = R[0, 0] + R[1, 1] + R[2, 2]
    if t > 0.0:
        s = math.sqrt(t + 1.0) * 2.0
        w, x, y, z = 0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2.0
        w, x, y, z = (R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s
    elif R[1, 1] > R[2, 2]:
        s = math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2.0
        w, x, y, z = (R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s
    else:
        s = math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2.0
        w, x, y, z = (R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s
    norm = math.sqrt(w * w + x * x + y * y + z * z) * (-1.0 if w < 0.0 else 1.0)
    return w / norm, x / norm, y / norm, z / norm


@njit(cache=True, error_model="numpy")
def _rot_into(out, axis, c, s):
    """Rotation by the angle of cosine ``c`` and sine ``s`` about the unit ``axis``."""
    x, y, z = axis[0], axis[1], axis[2]
    C = 1.0 - c
    out[0, 0], out[0, 1], out[0, 2] = c + x * x * C, x * y * C - z * s, x * z * C + y * s
    out[1, 0], out[1, 1], out[1, 2] = y * x * C + z * s, c + y * y * C, y * z * C - x * s
    out[2, 0], out[2, 1], out[2, 2] = z * x * C - y * s, z * y * C + x * s, c + z * z * C


@njit(cache=True, error_model="numpy", inline="always")
def _mm3_into(out, A, B):
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@njit(cache=True, error_model="numpy", inline="always")
def _mv3_add_into(out, base, A, v):
    for i in range(3):
        out[i] = base[i] + A[i, 0] * v[0] + A[i, 1] * v[1] + A[i, 2] * v[2]


@njit(cache=True, error_model="numpy", inline="always")
def _sym_inertia_into(out, R, I):
    """Upper triangle of the symmetric R I Rᵀ (``I`` symmetric): out[a, b] for a <= b."""
    for a in range(3):
        ra0, ra1, ra2 = R[a, 0], R[a, 1], R[a, 2]
        t0 = ra0 * I[0, 0] + ra1 * I[1, 0] + ra2 * I[2, 0]
        t1 = ra0 * I[0, 1] + ra1 * I[1, 1] + ra2 * I[2, 1]
        t2 = ra0 * I[0, 2] + ra1 * I[1, 2] + ra2 * I[2, 2]
        for b in range(a, 3):
            out[a, b] = t0 * R[b, 0] + t1 * R[b, 1] + t2 * R[b, 2]


@njit(cache=True, error_model="numpy", inline="always")
def _joint_cos_sin(x, k, cs, dq, h):
    """cos and sin of joint angle k of ``x``: computed (and kept in ``cs``) when ``h`` is 0; else ``x`` is
    a state advanced by ``dq`` h from the one ``cs`` holds, and the angle-sum formula turns the kept
    values into the new ones (a short series for the small increment), unless ``cs`` is not of that state.
    """
    if h != 0.0 and cs[2, k] + dq[k] * h == x[7 + k]:
        d = dq[k] * h
        c0, s0 = cs[0, k], cs[1, k]
        if abs(d) < 1e-2:  # series to d⁹ and d⁸: below 1e-22 of the result
            d2 = d * d
            sd = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0 * (1.0 - d2 / 42.0 * (1.0 - d2 / 72.0))))
            cd = 1.0 - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0 * (1.0 - d2 / 56.0)))
        else:
            cd, sd = math.cos(d), math.sin(d)
        return c0 * cd - s0 * sd, s0 * cd + c0 * sd
    c, s = math.cos(x[7 + k]), math.sin(x[7 + k])
    if h == 0.0:
        cs[0, k], cs[1, k], cs[2, k] = c, s, x[7 + k]
    return c, s


@njit(cache=True, error_model="numpy", inline="always")
def kinematics_into(mdl, x, ws, dq=None, h=0.0):
    """Forward kinematics into the workspace: joint rotations/origins, base rotation, EE poses, axes.

    With ``h`` = 0 the joint angles' cosines and sines are kept in ``ws.cs``; a later call for the
    state advanced by ``dq`` h (the midpoint) reuses them (:func:`_joint_cos_sin`).
    """
    parent, pl_R, pl_p, axis = mdl.parent, mdl.placement_R, mdl.placement_p, mdl.axis
    ee_parent, ee_R, ee_p, axis_code = mdl.ee_parent, mdl.ee_R, mdl.ee_p, mdl.axis_code
    Rj, pj, R_b, Re, pe, z, tmp, rot = ws.Rj, ws.pj, ws.R_b, ws.Re, ws.pe, ws.z, ws.tmp, ws.rot
    rates = ws.dq if dq is None else dq
    quat_into(R_b, x[3], x[4], x[5], x[6])
    for k in range(12):
        q = parent[k]
        P = R_b if q < 0 else Rj[q]  # the parent frame's rotation and origin
        _mv3_add_into(pj[k], x if q < 0 else pj[q], P, pl_p[k])
        L, a = pl_R[k], axis_code[k]
        c, s = _joint_cos_sin(x, k, ws.cs, rates, h)
        if a >= 0:  # rotation about frame axis a of P L: column a kept, the other two mixed (P L in registers)
            b, d = (a + 1) % 3, (a + 2) % 3
            for r in range(3):
                p0, p1, p2 = P[r, 0], P[r, 1], P[r, 2]
                ta = p0 * L[0, a] + p1 * L[1, a] + p2 * L[2, a]
                tb = p0 * L[0, b] + p1 * L[1, b] + p2 * L[2, b]
                td = p0 * L[0, d] + p1 * L[1, d] + p2 * L[2, d]
                Rj[k, r, a] = ta
                Rj[k, r, b] = c * tb + s * td
                Rj[k, r, d] = c * td - s * tb
                z[k, r] = ta
        else:
            _mm3_into(tmp, P, L)
            _rot_into(rot, axis[k], c, s)
            _mm3_into(Rj[k], tmp, rot)
            for r in range(3):
                z[k, r] = Rj[k, r, 0] * axis[k, 0] + Rj[k, r, 1] * axis[k, 1] + Rj[k, r, 2] * axis[k, 2]
    for a in range(2):
        j = ee_parent[a]
        _mm3_into(Re[a], Rj[j], ee_R[a])
        _mv3_add_into(pe[a], pj[j], Rj[j], ee_p[a])


@njit(cache=True, error_model="numpy", inline="always")
def momentum_into(mdl, x, ws):
    """H_b, H_bm (about the base CoM, world frame; docs/model.md §2) and the system CoM, into the workspace.

    One pass from the tips to the base over composite bodies (docs/model.md §12): joint k's subtree
    has mass M_k, first moment D_k = Σ m_i d_i and second moment A_k = Σ (I_i + m_i (|d_i|² 1 − d_i d_iᵀ))
    about the base CoM x (d_i = r_i − x, I_i the body's world inertia), so with e_k = p_k − x
    column k of H_bm is [z_k × (D_k − M_k e_k); A_k z_k − D_k × (z_k × e_k)], and the arms' roots
    give H_b (rotational block I_base + Σ A_root, coupling S(D), system CoM x + D / M).
    """
    mass, lever, inertia, parent = mdl.mass, mdl.lever, mdl.inertia, mdl.parent
    Rj, pj, z, H_b, H_bm, rg, comp = ws.Rj, ws.pj, ws.z, ws.H_b, ws.H_bm, ws.rg, ws.comp
    x0, x1, x2 = x[0], x[1], x[2]
    comp[:, :] = 0.0
    tm, t0, t1, t2 = mass[0], 0.0, 0.0, 0.0  # whole robot: mass and first moment
    _sym_inertia_into(ws.tmp, ws.R_b, inertia[0])
    a00, a01, a02, a11, a12, a22 = ws.tmp[0, 0], ws.tmp[0, 1], ws.tmp[0, 2], ws.tmp[1, 1], ws.tmp[1, 2], ws.tmp[2, 2]
    for i in range(11, -1, -1):
        m, R, lv, c = mass[i + 1], Rj[i], lever[i + 1], comp[i]
        dx = pj[i, 0] - x0 + (R[0, 0] * lv[0] + R[0, 1] * lv[1] + R[0, 2] * lv[2])
        dy = pj[i, 1] - x1 + (R[1, 0] * lv[0] + R[1, 1] * lv[1] + R[1, 2] * lv[2])
        dz = pj[i, 2] - x2 + (R[2, 0] * lv[0] + R[2, 1] * lv[1] + R[2, 2] * lv[2])
        _sym_inertia_into(ws.tmp, R, inertia[i + 1])
        W = ws.tmp
        mx, my, mz = m * dx, m * dy, m * dz
        c[0] += m
        c[1] += mx
        c[2] += my
        c[3] += mz
        c[4] += W[0, 0] + (my * dy + mz * dz)
        c[5] += W[0, 1] - mx * dy
        c[6] += W[0, 2] - mx * dz
        c[7] += W[1, 1] + (mx * dx + mz * dz)
        c[8] += W[1, 2] - my * dz
        c[9] += W[2, 2] + (mx * dx + my * dy)
        zx, zy, zz = z[i, 0], z[i, 1], z[i, 2]
        ex, ey, ez = pj[i, 0] - x0, pj[i, 1] - x1, pj[i, 2] - x2
        Mk, Dx, Dy, Dz = c[0], c[1], c[2], c[3]
        fx, fy, fz = Dx - Mk * ex, Dy - Mk * ey, Dz - Mk * ez
        ux, uy, uz = zy * ez - zz * ey, zz * ex - zx * ez, zx * ey - zy * ex  # z × e
        arm, col = i // 6, i % 6
        H_bm[arm, 0, col] = zy * fz - zz * fy
        H_bm[arm, 1, col] = zz * fx - zx * fz
        H_bm[arm, 2, col] = zx * fy - zy * fx
        H_bm[arm, 3, col] = c[4] * zx + c[5] * zy + c[6] * zz - (Dy * uz - Dz * uy)
        H_bm[arm, 4, col] = c[5] * zx + c[7] * zy + c[8] * zz - (Dz * ux - Dx * uz)
        H_bm[arm, 5, col] = c[6] * zx + c[8] * zy + c[9] * zz - (Dx * uy - Dy * ux)
        q = parent[i]
        if q >= 0:
            for a in range(10):
                comp[q, a] += c[a]
        else:  # an arm's root: its composite joins the base
            tm, t0, t1, t2 = tm + c[0], t0 + c[1], t1 + c[2], t2 + c[3]
            a00, a01, a02, a11, a12, a22 = a00 + c[4], a01 + c[5], a02 + c[6], a11 + c[7], a12 + c[8], a22 + c[9]
    H_b[:, :] = 0.0
    H_b[3, 3], H_b[3, 4], H_b[3, 5] = a00, a01, a02
    H_b[4, 3], H_b[4, 4], H_b[4, 5] = a01, a11, a12
    H_b[5, 3], H_b[5, 4], H_b[5, 5] = a02, a12, a22
    for a in range(3):
        H_b[a, a] = tm
    rg[0], rg[1], rg[2] = x0 + t0 / tm, x1 + t1 / tm, x2 + t2 / tm
    H_b[0, 4], H_b[0, 5], H_b[1, 3], H_b[1, 5], H_b[2, 3], H_b[2, 4] = t2, -t1, -t2, t0, t1, -t0
    H_b[4, 0], H_b[5, 0], H_b[3, 1], H_b[5, 1], H_b[3, 2], H_b[4, 2] = t2, -t1, -t2, t0, t1, -t0


@njit(cache=True, error_model="numpy", inline="always")
def momentum_about_base_into(out, h, rg, x):
    """Momentum [P; L] about the base CoM from ``h`` = [P; L_G] about the system CoM."""
    dx, dy, dz = rg[0] - x[0], rg[1] - x[1], rg[2] - x[2]
    out[0], out[1], out[2] = h[0], h[1], h[2]
    out[3] = h[3] + dy * h[2] - dz * h[1]
    out[4] = h[4] + dz * h[0] - dx * h[2]
    out[5] = h[5] + dx * h[1] - dy * h[0]


@njit(cache=True, error_model="numpy", inline="always")
def velocity_into(out, x, dq, h, ws):
    """Base velocity (base frame, Pinocchio layout) conserving ``h`` = [P; L_G].

    Uses the momentum matrices already in the workspace (computed at ``x``). H_b = [M 1, S(D)ᵀ;
    S(D), A] (:func:`momentum_into`) is solved by its Schur complement: (A − (|D|² 1 − D Dᵀ) / M) ω
    = l − D × p / M (the locked inertia about the system CoM, positive definite), then
    v = (p + D × ω) / M, for [p; l] = momentum about the base CoM minus H_bm Θ̇.
    """
    H_b, H_bm, R_b, rhs = ws.H_b, ws.H_bm, ws.R_b, ws.b6
    momentum_about_base_into(rhs, h, ws.rg, x)
    for a in range(6):
        acc = rhs[a]
        for c in range(6):
            acc -= H_bm[0, a, c] * dq[c] + H_bm[1, a, c] * dq[6 + c]
        rhs[a] = acc
    M, d0, d1, d2 = H_b[0, 0], H_b[5, 1], H_b[3, 2], H_b[4, 0]
    inv_m = 1.0 / M
    p0, p1, p2 = rhs[0], rhs[1], rhs[2]
    dd = (d0 * d0 + d1 * d1 + d2 * d2) * inv_m
    w0, w1, w2 = solve_sym3(H_b[3, 3] - dd + d0 * d0 * inv_m, H_b[3, 4] + d0 * d1 * inv_m, H_b[3, 5] + d0 * d2 * inv_m,
                            H_b[4, 4] - dd + d1 * d1 * inv_m, H_b[4, 5] + d1 * d2 * inv_m,
                            H_b[5, 5] - dd + d2 * d2 * inv_m,
                            rhs[3] - (d1 * p2 - d2 * p1) * inv_m, rhs[4] - (d2 * p0 - d0 * p2) * inv_m,
                            rhs[5] - (d0 * p1 - d1 * p0) * inv_m)
    v0, v1, v2 = (p0 + (d1 * w2 - d2 * w1)) * inv_m, (p1 + (d2 * w0 - d0 * w2)) * inv_m, (p2 + (d0 * w1 - d1 * w0)) * inv_m
    for a in range(3):
        out[a] = R_b[0, a] * v0 + R_b[1, a] * v1 + R_b[2, a] * v2
        out[3 + a] = R_b[0, a] * w0 + R_b[1, a] * w1 + R_b[2, a] * w2


@njit(cache=True, error_model="numpy")
def integrate_into(out, x, v_base, dq, dt):
    """out = x ⊕ (v dt): base by the SE(3) exponential of the base-frame twist, joints additively.

    ``out`` may be ``x`` itself.
    """
    wx, wy, wz = v_base[3] * dt, v_base[4] * dt, v_base[5] * dt
    ux, uy, uz = v_base[0] * dt, v_base[1] * dt, v_base[2] * dt
    theta2 = wx * wx + wy * wy + wz * wz
    theta = math.sqrt(theta2)
    if theta < 1e-6:
        c1, c2 = 0.5, 1.0 / 6.0
        half = 0.5 - theta2 / 48.0
        cos_half = 1.0 - theta2 / 8.0
    else:
        c1, c2 = (1.0 - math.cos(theta)) / theta2, (theta - math.sin(theta)) / (theta2 * theta)
        half = math.sin(0.5 * theta) / theta
        cos_half = math.cos(0.5 * theta)
    ax, ay, az = wy * uz - wz * uy, wz * ux - wx * uz, wx * uy - wy * ux  # w x u
    bx, by, bz = wy * az - wz * ay, wz * ax - wx * az, wx * ay - wy * ax  # w x (w x u)
    vx, vy, vz = ux + c1 * ax + c2 * bx, uy + c1 * ay + c2 * by, uz + c1 * az + c2 * bz
    qx, qy, qz, qw = x[3], x[4], x[5], x[6]
    # position += R(q) v, with R(q) v = v + 2 w (q x v) + 2 q x (q x v) for q = (qx, qy, qz)
    tx, ty, tz = 2.0 * (qy * vz - qz * vy), 2.0 * (qz * vx - qx * vz), 2.0 * (qx * vy - qy * vx)
    out[0] = x[0] + vx + qw * tx + (qy * tz - qz * ty)
    out[1] = x[1] + vy + qw * ty + (qz * tx - qx * tz)
    out[2] = x[2] + vz + qw * tz + (qx * ty - qy * tx)
    dx, dy, dz, dw = half * wx, half * wy, half * wz, cos_half
    nx = qw * dx + qx * dw + qy * dz - qz * dy
    ny = qw * dy - qx * dz + qy * dw + qz * dx
    nz = qw * dz + qx * dy - qy * dx + qz * dw
    nw = qw * dw - qx * dx - qy * dy - qz * dz
    norm = math.sqrt(nx * nx + ny * ny + nz * nz + nw * nw)
    out[3], out[4], out[5], out[6] = nx / norm, ny / norm, nz / norm, nw / norm
    for j in range(12):
        out[7 + j] = x[7 + j] + dq[j] * dt


@njit(cache=True, error_model="numpy", inline="always")
def midpoint_into(out, mdl, x, v0, dq, dt, h, ws):
    """Explicit midpoint on SE(3) with momentum re-solved at the half step (``Robot.step``).

    ``v0`` is the base velocity at ``x`` (already known to the caller: it is logged). Leaves the
    workspace's kinematics at the half step. ``out`` may be ``x`` itself.
    """
    integrate_into(ws.x_half, x, v0, dq, 0.5 * dt)
    kinematics_into(mdl, ws.x_half, ws, dq, 0.5 * dt)
    momentum_into(mdl, ws.x_half, ws)
    velocity_into(ws.v_mid, ws.x_half, dq, h, ws)
    integrate_into(out, x, ws.v_mid, dq, dt)
