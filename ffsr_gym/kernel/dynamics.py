"""Compiled (numba) free-floating multibody dynamics: ABA, RNEA and CRBA on the free-flyer model.

The robot is the kernel's tree (:mod:`ffsr_gym.kernel.arrays`): body 0 the base on a free-flyer
joint, bodies 1-12 the links of the revolute joints 0-11 (mission arm first). Everything is
expressed in body frames, so the dynamics do not depend on the base pose, only on the joint
angles (there is no gravity in orbit). Spatial vectors are linear part first, as Pinocchio's:
a motion ``[v; ω]``, a force ``[f; n]``. Velocities and accelerations are ``(18,)``: the base twist
in the base frame (Pinocchio's free-flyer ``v``), then the 12 joint rates in kernel order.
Equations: docs/model.md "Dynamics" (Featherstone's articulated-body, recursive Newton-Euler and
composite-rigid-body algorithms). Validated against Pinocchio's ``aba``, ``rnea`` and ``crba``
(``tests/test_dynamics.py``).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from ffsr_gym.kernel.linalg import solve_into
from ffsr_gym.kernel.physics import _rot_into

#: Buffers of one dynamics call: body transforms and spatial inertias, velocities, the ABA's
#: articulated inertias and bias forces, and scratch.
Dynamics = namedtuple("Dynamics", [
    "X",  # (12, 6, 6) motion transform from the parent body's frame to the link's
    "I",  # (13, 6, 6) spatial inertia of each body in its own frame
    "vel", "bias", "acc",  # (13, 6) body velocity, velocity-product acceleration, acceleration
    "IA", "pA",  # (13, 6, 6), (13, 6) articulated inertia and bias force (ABA), composite inertia and force (CRBA, RNEA)
    "U", "D", "u",  # (12, 6), (12,), (12,) the ABA's joint terms
    "T", "C3", "rot", "f6", "g6", "M6",  # scratch
])


@njit(cache=True, error_model="numpy")
def dynamics_workspace(mdl):
    """A fresh :data:`Dynamics` workspace for the model arrays ``mdl`` (their spatial inertias computed once)."""
    dyn = Dynamics(np.zeros((12, 6, 6)), np.zeros((13, 6, 6)), np.zeros((13, 6)), np.zeros((13, 6)),
                    np.zeros((13, 6)), np.zeros((13, 6, 6)), np.zeros((13, 6)), np.zeros((12, 6)), np.zeros(12),
                   np.zeros(12), np.zeros((6, 6)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(6), np.zeros(6), np.zeros((6, 6)))
    for b in range(13):
        spatial_inertia_into(dyn.I[b], mdl.mass[b], mdl.lever[b], mdl.inertia[b])
    return dyn


@njit(cache=True, error_model="numpy")
def spatial_inertia_into(out, m, c, I_c):
    """Spatial inertia (6, 6) of a body of mass ``m`` [kg], CoM ``c`` [m] and inertia ``I_c`` about it [kg m²].

    ``[[m 1, -m S(c)], [m S(c), I_c - m S(c) S(c)]]``, linear part first.
    """
    out[:, :] = 0.0
    for a in range(3):
        out[a, a] = m
    cx, cy, cz = c[0], c[1], c[2]
    out[0, 4], out[0, 5], out[1, 3], out[1, 5], out[2, 3], out[2, 4] = m * cz, -m * cy, -m * cz, m * cx, m * cy, -m * cx
    for a in range(3):
        for b in range(3):
            out[3 + a, b] = -out[a, 3 + b]
    cc = cx * cx + cy * cy + cz * cz
    for a in range(3):
        for b in range(3):
            out[3 + a, 3 + b] = I_c[a, b] + m * ((cc if a == b else 0.0) - c[a] * c[b])


@njit(cache=True, error_model="numpy")
def _transforms_into(mdl, q_joints, dyn):
    """Parent-to-link motion transforms at the joint angles ``q_joints`` (12,) [rad].

    Link k sits at the parent's ``placement_p`` rotated by ``placement_R · rot(axis, q_k)`` = R; the
    motion transform is ``[[Rᵀ, -Rᵀ S(p)], [0, Rᵀ]]``.
    """
    rot = dyn.rot
    for k in range(12):
        _rot_into(rot, mdl.axis[k], math.cos(q_joints[k]), math.sin(q_joints[k]))
        L, p, X = mdl.placement_R[k], mdl.placement_p[k], dyn.X[k]
        X[:, :] = 0.0
        for a in range(3):
            for b in range(3):  # Rᵀ[a, b] = R[b, a] with R = L rot
                r_ba = L[b, 0] * rot[0, a] + L[b, 1] * rot[1, a] + L[b, 2] * rot[2, a]
                X[a, b] = r_ba
                X[3 + a, 3 + b] = r_ba
        for a in range(3):  # the -Rᵀ S(p) block
            r0, r1, r2 = X[a, 0], X[a, 1], X[a, 2]
            X[a, 3], X[a, 4], X[a, 5] = r2 * p[1] - r1 * p[2], r0 * p[2] - r2 * p[0], r1 * p[0] - r0 * p[1]


@njit(cache=True, error_model="numpy", inline="always")
def _mv6(out, A, v):
    """out = A v (6 x 6)."""
    for a in range(6):
        acc = 0.0
        for b in range(6):
            acc += A[a, b] * v[b]
        out[a] = acc


@njit(cache=True, error_model="numpy", inline="always")
def _mtv6_add(out, A, v):
    """out += Aᵀ v."""
    for b in range(6):
        acc = 0.0
        for a in range(6):
            acc += A[a, b] * v[a]
        out[b] += acc


@njit(cache=True, error_model="numpy", inline="always")
def _congruence_add(out, X, p, A, T, C):
    """out += Xᵀ A X for the motion transform X = diag(E, E) [[1, -S(p)], [0, 1]] and a symmetric A (6 x 6).

    The blocks of A are rotated first, B_ij = Eᵀ A_ij E (into ``T``; E = X[:3, :3]), then shifted by p
    (the link's origin in the parent frame, P = -S(p)): C11 = B11, C12 = B11 P + B12 (into ``C``),
    C22 = Pᵀ C12 + B21 P + B22; products with P are cross products with p.
    """
    for bi in range(0, 6, 3):
        for bj in range(bi, 6, 3):
            for a in range(3):
                t0 = X[0, a] * A[bi, bj] + X[1, a] * A[bi + 1, bj] + X[2, a] * A[bi + 2, bj]
                t1 = X[0, a] * A[bi, bj + 1] + X[1, a] * A[bi + 1, bj + 1] + X[2, a] * A[bi + 2, bj + 1]
                t2 = X[0, a] * A[bi, bj + 2] + X[1, a] * A[bi + 1, bj + 2] + X[2, a] * A[bi + 2, bj + 2]
                for b in range(3):
                    T[bi + a, bj + b] = t0 * X[0, b] + t1 * X[1, b] + t2 * X[2, b]
    p0, p1, p2 = p[0], p[1], p[2]
    for r in range(3):  # row r of B11 P is p × (row r of B11)
        m0, m1, m2 = T[r, 0], T[r, 1], T[r, 2]
        C[r, 0] = T[r, 3] + (p1 * m2 - p2 * m1)
        C[r, 1] = T[r, 4] + (p2 * m0 - p0 * m2)
        C[r, 2] = T[r, 5] + (p0 * m1 - p1 * m0)
    for r in range(3):
        for c in range(3):
            out[r, c] += T[r, c]
            out[r, 3 + c] += C[r, c]
            out[3 + c, r] += C[r, c]
    for c in range(3):  # column c of Pᵀ C12 = S(p) C12 is p × (column c of C12)
        c0, c1, c2 = C[0, c], C[1, c], C[2, c]
        out[3, 3 + c] += p1 * c2 - p2 * c1
        out[4, 3 + c] += p2 * c0 - p0 * c2
        out[5, 3 + c] += p0 * c1 - p1 * c0
    for r in range(3):  # row r of B21 P is p × (row r of B21) = p × (column r of B12); plus B22
        b0, b1, b2 = T[0, 3 + r], T[1, 3 + r], T[2, 3 + r]
        out[3 + r, 3] += (p1 * b2 - p2 * b1) + T[3 + r, 3]
        out[3 + r, 4] += (p2 * b0 - p0 * b2) + T[3 + r, 4]
        out[3 + r, 5] += (p0 * b1 - p1 * b0) + T[3 + r, 5]


@njit(cache=True, error_model="numpy", inline="always")
def _cross_force_add(out, v, f):
    """out += v ×* f = [ω × f_lin; ω × n + v_lin × f_lin]."""
    w0, w1, w2, l0, l1, l2 = v[3], v[4], v[5], v[0], v[1], v[2]
    f0, f1, f2, n0, n1, n2 = f[0], f[1], f[2], f[3], f[4], f[5]
    out[0] += w1 * f2 - w2 * f1
    out[1] += w2 * f0 - w0 * f2
    out[2] += w0 * f1 - w1 * f0
    out[3] += w1 * n2 - w2 * n1 + l1 * f2 - l2 * f1
    out[4] += w2 * n0 - w0 * n2 + l2 * f0 - l0 * f2
    out[5] += w0 * n1 - w1 * n0 + l0 * f1 - l1 * f0


@njit(cache=True, error_model="numpy")
def _velocities_into(mdl, v, dyn):
    """Body velocities and the velocity-product accelerations c_k = v_k ×m (S_k q̇_k) (base: 0)."""
    vel, bias, X, axis = dyn.vel, dyn.bias, dyn.X, mdl.axis
    for a in range(6):
        vel[0, a] = v[a]
        bias[0, a] = 0.0
    for k in range(12):
        b, dq = k + 1, v[6 + k]
        _mv6(vel[b], X[k], vel[mdl.parent[k] + 1])
        s0, s1, s2 = axis[k, 0] * dq, axis[k, 1] * dq, axis[k, 2] * dq
        vel[b, 3] += s0
        vel[b, 4] += s1
        vel[b, 5] += s2
        l0, l1, l2, w0, w1, w2 = vel[b, 0], vel[b, 1], vel[b, 2], vel[b, 3], vel[b, 4], vel[b, 5]
        bias[b, 0], bias[b, 1], bias[b, 2] = l1 * s2 - l2 * s1, l2 * s0 - l0 * s2, l0 * s1 - l1 * s0
        bias[b, 3], bias[b, 4], bias[b, 5] = w1 * s2 - w2 * s1, w2 * s0 - w0 * s2, w0 * s1 - w1 * s0


@njit(cache=True, error_model="numpy")
def aba_into(out, mdl, q_joints, v, tau, armature, dyn):
    """Forward dynamics: accelerations (18,) of the free-floating robot under joint torques, no external load.

    Featherstone's articulated-body algorithm in body frames. Solves (M + diag(0, armature)) a + b(q, v)
    = [0; τ] for ``a`` = [base spatial acceleration in the base frame; joint accelerations].

    Args:
        out: (18,) receives the accelerations [m/s², rad/s²].
        mdl: the kernel's model arrays (parent, placements, axes, masses, CoMs, inertias).
        q_joints: (12,) joint angles [rad], kernel order.
        v: (18,) base twist in the base frame and joint rates [m/s, rad/s].
        tau: (12,) joint torques [N m].
        armature: (12,) inertia added to each joint's diagonal [kg m²] (reflected rotor inertia).
        dyn: a :data:`Dynamics` workspace.
    """
    _transforms_into(mdl, q_joints, dyn)
    _velocities_into(mdl, v, dyn)
    IA, pA, I, vel, X, T, axis = dyn.IA, dyn.pA, dyn.I, dyn.vel, dyn.X, dyn.T, mdl.axis
    for b in range(13):
        IA[b, :, :] = I[b]
        _mv6(dyn.f6, I[b], vel[b])
        pA[b, :] = 0.0
        _cross_force_add(pA[b], vel[b], dyn.f6)
    for k in range(11, -1, -1):
        b, U = k + 1, dyn.U[k]
        a0, a1, a2 = axis[k, 0], axis[k, 1], axis[k, 2]
        for r in range(6):
            U[r] = IA[b, r, 3] * a0 + IA[b, r, 4] * a1 + IA[b, r, 5] * a2
        D = a0 * U[3] + a1 * U[4] + a2 * U[5] + armature[k]
        u = tau[k] - (a0 * pA[b, 3] + a1 * pA[b, 4] + a2 * pA[b, 5])
        dyn.D[k], dyn.u[k] = D, u
        Ia = dyn.M6
        for r in range(6):
            for c in range(6):
                Ia[r, c] = IA[b, r, c] - U[r] * U[c] / D
        pa = dyn.f6
        _mv6(pa, Ia, dyn.bias[b])
        for r in range(6):
            pa[r] += pA[b, r] + U[r] * u / D
        parent = mdl.parent[k] + 1
        _congruence_add(IA[parent], X[k], mdl.placement_p[k], Ia, T, dyn.C3)
        _mtv6_add(pA[parent], X[k], pa)
    acc = dyn.acc
    for r in range(6):
        dyn.f6[r] = -pA[0, r]
    solve_into(IA[0], dyn.f6, dyn.M6, acc[0])
    for r in range(6):
        out[r] = acc[0, r]
    for k in range(12):
        b, U = k + 1, dyn.U[k]
        _mv6(acc[b], X[k], acc[mdl.parent[k] + 1])
        for r in range(6):
            acc[b, r] += dyn.bias[b, r]
        dd = (dyn.u[k] - (U[0] * acc[b, 0] + U[1] * acc[b, 1] + U[2] * acc[b, 2] + U[3] * acc[b, 3] + U[4] * acc[b, 4]
                          + U[5] * acc[b, 5])) / dyn.D[k]
        acc[b, 3] += axis[k, 0] * dd
        acc[b, 4] += axis[k, 1] * dd
        acc[b, 5] += axis[k, 2] * dd
        out[6 + k] = dd


@njit(cache=True, error_model="numpy")
def rnea_into(out, mdl, q_joints, v, a, armature, dyn):
    """Inverse dynamics: the generalised forces (18,) that produce accelerations ``a`` (18,).

    Featherstone's recursive Newton-Euler algorithm: the base wrench [N, N m] (base frame; zero for
    a free-floating motion) and the joint torques [N m], including ``armature`` (12,) · q̈.
    """
    _transforms_into(mdl, q_joints, dyn)
    _velocities_into(mdl, v, dyn)
    acc, f, I, vel, X = dyn.acc, dyn.pA, dyn.I, dyn.vel, dyn.X
    for r in range(6):
        acc[0, r] = a[r]
    for k in range(12):
        b = k + 1
        _mv6(acc[b], X[k], acc[mdl.parent[k] + 1])
        for r in range(6):
            acc[b, r] += dyn.bias[b, r]
        for r in range(3):
            acc[b, 3 + r] += mdl.axis[k, r] * a[6 + k]
    for b in range(13):
        _mv6(f[b], I[b], acc[b])
        _mv6(dyn.f6, I[b], vel[b])
        _cross_force_add(f[b], vel[b], dyn.f6)
    for k in range(11, -1, -1):
        b = k + 1
        out[6 + k] = mdl.axis[k, 0] * f[b, 3] + mdl.axis[k, 1] * f[b, 4] + mdl.axis[k, 2] * f[b, 5] + armature[k] * a[6 + k]
        _mtv6_add(f[mdl.parent[k] + 1], X[k], f[b])
    for r in range(6):
        out[r] = f[0, r]


@njit(cache=True, error_model="numpy")
def crba_into(out, mdl, q_joints, armature, dyn):
    """Joint-space inertia matrix (18, 18) with ``armature`` (12,) on the joints' diagonal (composite-rigid-body algorithm).

    Kinetic energy is ½ vᵀ M v for ``v`` (18,) in this module's layout.
    """
    _transforms_into(mdl, q_joints, dyn)
    Ic, X, F = dyn.IA, dyn.X, dyn.f6
    for b in range(13):
        Ic[b, :, :] = dyn.I[b]
    for k in range(11, -1, -1):
        _congruence_add(Ic[mdl.parent[k] + 1], X[k], mdl.placement_p[k], Ic[k + 1], dyn.T, dyn.C3)
    out[:, :] = 0.0
    for r in range(6):
        for c in range(6):
            out[r, c] = Ic[0, r, c]
    for k in range(12):
        b = k + 1
        for r in range(6):
            F[r] = Ic[b, r, 3] * mdl.axis[k, 0] + Ic[b, r, 4] * mdl.axis[k, 1] + Ic[b, r, 5] * mdl.axis[k, 2]
        out[6 + k, 6 + k] = mdl.axis[k, 0] * F[3] + mdl.axis[k, 1] * F[4] + mdl.axis[k, 2] * F[5] + armature[k]
        j = k
        while j >= 0:  # carry the force to the parent's frame, one joint at a time
            g = dyn.g6
            g[:] = 0.0
            _mtv6_add(g, X[j], F)
            F[:] = g
            j = mdl.parent[j]
            if j >= 0:
                value = mdl.axis[j, 0] * F[3] + mdl.axis[j, 1] * F[4] + mdl.axis[j, 2] * F[5]
                out[6 + j, 6 + k], out[6 + k, 6 + j] = value, value
        for r in range(6):
            out[r, 6 + k], out[6 + k, r] = F[r], F[r]


@njit(cache=True, error_model="numpy")
def kinetic_energy(mdl, q_joints, v, armature, dyn):
    """Kinetic energy [J]: Σ ½ v_bᵀ I_b v_b over the bodies plus ½ Σ armature q̇² (independent of :func:`crba_into`)."""
    _transforms_into(mdl, q_joints, dyn)
    _velocities_into(mdl, v, dyn)
    energy = 0.0
    for b in range(13):
        _mv6(dyn.f6, dyn.I[b], dyn.vel[b])
        for r in range(6):
            energy += 0.5 * dyn.vel[b, r] * dyn.f6[r]
    for k in range(12):
        energy += 0.5 * armature[k] * v[6 + k] * v[6 + k]
    return energy
