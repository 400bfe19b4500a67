"""Compiled (numba) robot physics: kinematics, momentum, SE(3) integration, collision distances.

A re-implementation of ``ffsr_gym.robot`` and ``ffsr_gym.collision`` for the kernel, validated
against them to 1e-9 (``tests/test_kernel.py``). State layout ``x`` (19): base position [m], base
quaternion (x, y, z, w), 12 joint angles [rad] mission arm first. Model arrays come from
:func:`ffsr_gym.kernel_model.extract`, passed as the tuple ``mdl`` in declaration order.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ffsr_gym.kernel_linalg import cross, dot, mtv, mv, solve

_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


@njit(cache=True)
def skew(a):
    out = np.zeros((3, 3))
    out[0, 1], out[0, 2], out[1, 0] = -a[2], a[1], a[2]
    out[1, 2], out[2, 0], out[2, 1] = -a[0], -a[1], a[0]
    return out


@njit(cache=True)
def quat_xyzw_to_R(q):
    x, y, z, w = q[0], q[1], q[2], q[3]
    R = np.empty((3, 3))
    R[0, 0], R[0, 1], R[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
    R[1, 0], R[1, 1], R[1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    R[2, 0], R[2, 1], R[2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
    return R


@njit(cache=True)
def R_to_quat_wxyz(R):
    """Scalar-first unit quaternion with w >= 0 (Shepperd's method)."""
    t = R[0, 0] + R[1, 1] + R[2, 2]
    q = np.empty(4)
    if t > 0.0:
        s = math.sqrt(t + 1.0) * 2.0
        q[0], q[1], q[2], q[3] = 0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2]) * 2.0
        q[0], q[1], q[2], q[3] = (R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s
    elif R[1, 1] > R[2, 2]:
        s = math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2]) * 2.0
        q[0], q[1], q[2], q[3] = (R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s
    else:
        s = math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1]) * 2.0
        q[0], q[1], q[2], q[3] = (R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s
    if q[0] < 0.0:
        q = -q
    return q / math.sqrt(dot(q, q))


@njit(cache=True)
def workspace():
    """Buffers reused by the kinematics and momentum routines (no allocation in the inner loop)."""
    return (np.empty((12, 3, 3)), np.empty((12, 3)), np.empty((3, 3)), np.empty((2, 3, 3)), np.empty((2, 3)),
            np.empty((12, 3)), np.empty((6, 6)), np.empty((2, 6, 6)), np.empty(3), np.empty((12, 3)),
            np.empty((12, 3, 3)), np.empty((3, 3)))


@njit(cache=True)
def _rot_into(out, axis, angle):
    c, s = math.cos(angle), math.sin(angle)
    x, y, z = axis[0], axis[1], axis[2]
    C = 1.0 - c
    out[0, 0], out[0, 1], out[0, 2] = c + x * x * C, x * y * C - z * s, x * z * C + y * s
    out[1, 0], out[1, 1], out[1, 2] = y * x * C + z * s, c + y * y * C, y * z * C - x * s
    out[2, 0], out[2, 1], out[2, 2] = z * x * C - y * s, z * y * C + x * s, c + z * z * C


@njit(cache=True)
def _mm3_into(out, A, B):
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@njit(cache=True)
def _mv3_add_into(out, base, A, v):
    for i in range(3):
        out[i] = base[i] + A[i, 0] * v[0] + A[i, 1] * v[1] + A[i, 2] * v[2]


@njit(cache=True)
def kinematics_into(mdl, x, ws):
    """Forward kinematics into the workspace: joint rotations/origins, base rotation, EE poses, axes."""
    parent, pl_R, pl_p, axis = mdl[0], mdl[1], mdl[2], mdl[3]
    ee_parent, ee_R, ee_p = mdl[7], mdl[8], mdl[9]
    Rj, pj, R_b, Re, pe, z, tmp = ws[0], ws[1], ws[2], ws[3], ws[4], ws[5], ws[11]
    R_b[:, :] = quat_xyzw_to_R(x[3:7])
    rot = np.empty((3, 3))
    for k in range(12):
        if parent[k] < 0:
            _mm3_into(tmp, R_b, pl_R[k])
            _mv3_add_into(pj[k], x, R_b, pl_p[k])
        else:
            q = parent[k]
            _mm3_into(tmp, Rj[q], pl_R[k])
            _mv3_add_into(pj[k], pj[q], Rj[q], pl_p[k])
        _rot_into(rot, axis[k], x[7 + k])
        _mm3_into(Rj[k], tmp, rot)
        for a in range(3):
            z[k, a] = Rj[k, a, 0] * axis[k, 0] + Rj[k, a, 1] * axis[k, 1] + Rj[k, a, 2] * axis[k, 2]
    for a in range(2):
        j = ee_parent[a]
        _mm3_into(Re[a], Rj[j], ee_R[a])
        _mv3_add_into(pe[a], pj[j], Rj[j], ee_p[a])


@njit(cache=True)
def momentum_into(mdl, x, ws):
    """H_b, H_bm (about the base CoM, world frame; SPEC §2.3) and the system CoM, into the workspace."""
    mass, lever, inertia, parent = mdl[4], mdl[5], mdl[6], mdl[0]
    Rj, pj, R_b, z = ws[0], ws[1], ws[2], ws[5]
    H_b, H_bm, rg, r, Iw, tmp = ws[6], ws[7], ws[8], ws[9], ws[10], ws[11]
    r0 = x
    M = mass[0]
    for a in range(3):
        rg[a] = mass[0] * r0[a]
    _mm3_into(tmp, R_b, inertia[0])
    H_w = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            H_w[a, b] = tmp[a, 0] * R_b[b, 0] + tmp[a, 1] * R_b[b, 1] + tmp[a, 2] * R_b[b, 2]
    d = np.empty(3)
    for i in range(12):
        m_i = mass[i + 1]
        _mv3_add_into(r[i], pj[i], Rj[i], lever[i + 1])
        _mm3_into(tmp, Rj[i], inertia[i + 1])
        for a in range(3):
            for b in range(3):
                Iw[i, a, b] = tmp[a, 0] * Rj[i, b, 0] + tmp[a, 1] * Rj[i, b, 1] + tmp[a, 2] * Rj[i, b, 2]
        M += m_i
        for a in range(3):
            rg[a] += m_i * r[i, a]
            d[a] = r[i, a] - r0[a]
        dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
        for a in range(3):  # S(d)^T S(d) = |d|^2 I - d d^T
            for b in range(3):
                H_w[a, b] += Iw[i, a, b] + m_i * ((dd if a == b else 0.0) - d[a] * d[b])
    for a in range(3):
        rg[a] /= M
    H_b[:, :] = 0.0
    w0, w1, w2 = M * (rg[0] - r0[0]), M * (rg[1] - r0[1]), M * (rg[2] - r0[2])
    for a in range(3):
        H_b[a, a] = M
    H_b[0, 4], H_b[0, 5], H_b[1, 3], H_b[1, 5], H_b[2, 3], H_b[2, 4] = w2, -w1, -w2, w0, w1, -w0
    H_b[4, 0], H_b[5, 0], H_b[3, 1], H_b[5, 1], H_b[3, 2], H_b[4, 2] = w2, -w1, -w2, w0, w1, -w0
    H_b[3:6, 3:6] = H_w
    H_bm[:, :, :] = 0.0
    for k in range(12):
        arm, col = k // 6, k % 6
        zk = z[k]
        for i in range(k, 6 * arm + 6):  # bodies at and after joint k on the same serial arm
            ancestor = i
            while ancestor > k and parent[ancestor] >= 0:
                ancestor = parent[ancestor]
            if ancestor != k:
                continue
            m_i = mass[i + 1]
            ex, ey, ez = r[i, 0] - pj[k, 0], r[i, 1] - pj[k, 1], r[i, 2] - pj[k, 2]
            vx, vy, vz = zk[1] * ez - zk[2] * ey, zk[2] * ex - zk[0] * ez, zk[0] * ey - zk[1] * ex
            fx, fy, fz = r[i, 0] - r0[0], r[i, 1] - r0[1], r[i, 2] - r0[2]
            H_bm[arm, 0, col] += m_i * vx
            H_bm[arm, 1, col] += m_i * vy
            H_bm[arm, 2, col] += m_i * vz
            H_bm[arm, 3, col] += Iw[i, 0, 0] * zk[0] + Iw[i, 0, 1] * zk[1] + Iw[i, 0, 2] * zk[2] + m_i * (fy * vz - fz * vy)
            H_bm[arm, 4, col] += Iw[i, 1, 0] * zk[0] + Iw[i, 1, 1] * zk[1] + Iw[i, 1, 2] * zk[2] + m_i * (fz * vx - fx * vz)
            H_bm[arm, 5, col] += Iw[i, 2, 0] * zk[0] + Iw[i, 2, 1] * zk[1] + Iw[i, 2, 2] * zk[2] + m_i * (fx * vy - fy * vx)


@njit(cache=True)
def momentum_about_base(h, rg, r0):
    C = h.copy()
    C[3:6] = h[3:6] + cross(rg - r0[0:3], h[0:3])
    return C


@njit(cache=True)
def base_velocity_ws(mdl, x, dq, h, ws):
    """Base velocity (base frame, Pinocchio layout) conserving ``h`` = [P; L_G], with a workspace."""
    kinematics_into(mdl, x, ws)
    momentum_into(mdl, x, ws)
    return velocity_from_workspace(x, dq, h, ws)


@njit(cache=True)
def velocity_from_workspace(x, dq, h, ws):
    """Base velocity from the momentum matrices already in the workspace (computed at ``x``)."""
    H_b, H_bm, rg, R_b = ws[6], ws[7], ws[8], ws[2]
    rhs = momentum_about_base(h, rg, x)
    for a in range(6):
        for c in range(6):
            rhs[a] -= H_bm[0, a, c] * dq[c] + H_bm[1, a, c] * dq[6 + c]
    V0 = solve(H_b, rhs)
    out = np.empty(6)
    out[0:3] = mtv(R_b, V0[0:3])
    out[3:6] = mtv(R_b, V0[3:6])
    return out


@njit(cache=True)
def integrate(x, v_base, dq, dt):
    """x ⊕ (v dt): base by the SE(3) exponential of the base-frame twist, joints additively."""
    w = v_base[3:6] * dt
    u = v_base[0:3] * dt
    theta2 = dot(w, w)
    theta = math.sqrt(theta2)
    if theta < 1e-6:
        c1, c2 = 0.5, 1.0 / 6.0
        half = 0.5 - theta2 / 48.0
        cos_half = 1.0 - theta2 / 8.0
    else:
        c1, c2 = (1.0 - math.cos(theta)) / theta2, (theta - math.sin(theta)) / (theta2 * theta)
        half = math.sin(0.5 * theta) / theta
        cos_half = math.cos(0.5 * theta)
    wu = cross(w, u)
    Vu = u + c1 * wu + c2 * cross(w, wu)
    R = quat_xyzw_to_R(x[3:7])
    out = x.copy()
    out[0:3] = x[0:3] + mv(R, Vu)
    qx, qy, qz, qw = x[3], x[4], x[5], x[6]
    dx, dy, dz, dw = half * w[0], half * w[1], half * w[2], cos_half
    nx = qw * dx + qx * dw + qy * dz - qz * dy
    ny = qw * dy - qx * dz + qy * dw + qz * dx
    nz = qw * dz + qx * dy - qy * dx + qz * dw
    nw = qw * dw - qx * dx - qy * dy - qz * dz
    norm = math.sqrt(nx * nx + ny * ny + nz * nz + nw * nw)
    out[3], out[4], out[5], out[6] = nx / norm, ny / norm, nz / norm, nw / norm
    out[7:19] = x[7:19] + dq * dt
    return out


@njit(cache=True)
def midpoint_step(mdl, x, v0, dq, dt, h, ws):
    """Explicit midpoint on SE(3) with momentum re-solved at the half step (``Robot.step``).

    ``v0`` is the base velocity at ``x`` (already known to the caller: it is logged).
    """
    x_half = integrate(x, v0, dq, 0.5 * dt)
    v_mid = base_velocity_ws(mdl, x_half, dq, h, ws)
    return integrate(x, v_mid, dq, dt)


# --------------------------------------------------------------------------- collision
@njit(cache=True)
def point_segment(p, a, b):
    """Closest point on segment [a, b] to p."""
    d = b - a
    t = dot(p - a, d) / dot(d, d)
    t = min(1.0, max(0.0, t))
    return a + t * d


@njit(cache=True)
def segment_segment(a0, a1, b0, b1):
    """Distance between two segments (clamped closed form)."""
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a, e, f = dot(d1, d1), dot(d2, d2), dot(d2, r)
    c, b = dot(d1, r), dot(d1, d2)
    denom = a * e - b * b
    s = min(1.0, max(0.0, (b * f - c * e) / denom)) if denom > 1e-14 * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = min(1.0, max(0.0, -c / a))
    elif t > 1.0:
        t = 1.0
        s = min(1.0, max(0.0, (b - c) / a))
    dx = a0[0] + s * d1[0] - b0[0] - t * d2[0]
    dy = a0[1] + s * d1[1] - b0[1] - t * d2[1]
    dz = a0[2] + s * d1[2] - b0[2] - t * d2[2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, inline="always")
def _sdf_local(x, y, z, half):
    dx, dy, dz = abs(x) - half[0], abs(y) - half[1], abs(z) - half[2]
    ox, oy, oz = max(dx, 0.0), max(dy, 0.0), max(dz, 0.0)
    outside = ox * ox + oy * oy + oz * oz
    return math.sqrt(outside) if outside > 0.0 else max(dx, max(dy, dz))


@njit(cache=True)
def box_sdf(p, R_b, c_b, half):
    local = mtv(R_b, p - c_b)
    return _sdf_local(local[0], local[1], local[2], half)


@njit(cache=True)
def segment_box(a, b, R_b, c_b, half):
    """Signed distance segment-box: min of the (convex) box SDF along the segment (golden section)."""
    la, lb = mtv(R_b, a - c_b), mtv(R_b, b - c_b)
    dx, dy, dz = lb[0] - la[0], lb[1] - la[1], lb[2] - la[2]
    lo, hi = 0.0, 1.0
    for _ in range(64):
        m1 = hi - _GOLDEN * (hi - lo)
        m2 = lo + _GOLDEN * (hi - lo)
        f1 = _sdf_local(la[0] + m1 * dx, la[1] + m1 * dy, la[2] + m1 * dz, half)
        f2 = _sdf_local(la[0] + m2 * dx, la[1] + m2 * dy, la[2] + m2 * dz, half)
        if f1 < f2:
            hi = m2
        else:
            lo = m1
    m = 0.5 * (lo + hi)
    best = _sdf_local(la[0] + m * dx, la[1] + m * dy, la[2] + m * dz, half)
    best = min(best, _sdf_local(la[0], la[1], la[2], half))
    return min(best, _sdf_local(lb[0], lb[1], lb[2], half))


@njit(cache=True)
def capsule_ends(mdl, Rj, pj, R_b, p_b):
    cap_parent, cap_a, cap_b = mdl[10], mdl[11], mdl[12]
    n = len(cap_parent)
    A = np.empty((n, 3))
    B = np.empty((n, 3))
    for i in range(n):
        j = cap_parent[i]
        R, p = (R_b, p_b) if j < 0 else (Rj[j], pj[j])
        A[i] = p + mv(R, cap_a[i])
        B[i] = p + mv(R, cap_b[i])
    return A, B


@njit(cache=True)
def obstacle_clearance(mdl, A, B, R_b, p_b, p_o, r_o):
    """Signed distance robot-obstacle sphere [m] and the vector robot point → obstacle point."""
    radius, half = mdl[13], mdl[16]
    best = box_sdf(p_o, R_b, p_b, half) - r_o
    local = mtv(R_b, p_o - p_b)
    clamped = np.minimum(np.maximum(local, -half), half)
    rel = p_o - (p_b + mv(R_b, clamped))
    n = math.sqrt(dot(rel, rel))
    if n > 0.0:
        rel = rel - r_o * rel / n
    for i in range(len(radius)):
        d = p_o - point_segment(p_o, A[i], B[i])
        dist = math.sqrt(dot(d, d))
        value = dist - radius[i] - r_o
        if value < best:
            best = value
            rel = d * (1.0 - (radius[i] + r_o) / dist) if dist > 0.0 else np.zeros(3)
    return best, rel


@njit(cache=True)
def self_clearance(mdl, A, B, R_b, p_b):
    """Smallest signed distance arm-arm and arm-base (mounting links excluded) [m].

    Candidate pairs are visited in order of a cheap lower bound (bounding spheres); exact
    distances are computed only while a bound can still beat the best so far.
    """
    radius, arm, vs_base, half = mdl[13], mdl[14], mdl[15], mdl[16]
    n = len(radius)
    mid = 0.5 * (A + B)
    hl = np.empty(n)
    for i in range(n):
        dx, dy, dz = B[i, 0] - A[i, 0], B[i, 1] - A[i, 1], B[i, 2] - A[i, 2]
        hl[i] = 0.5 * math.sqrt(dx * dx + dy * dy + dz * dz)
    bound = np.empty(n * n + n)
    first = np.empty(n * n + n, dtype=np.int64)
    second = np.empty(n * n + n, dtype=np.int64)
    count = 0
    for i in range(n):
        if arm[i] == 0:
            for j in range(n):
                if arm[j] == 1:
                    dx, dy, dz = mid[i, 0] - mid[j, 0], mid[i, 1] - mid[j, 1], mid[i, 2] - mid[j, 2]
                    bound[count] = math.sqrt(dx * dx + dy * dy + dz * dz) - hl[i] - hl[j] - radius[i] - radius[j]
                    first[count], second[count] = i, j
                    count += 1
        if vs_base[i]:
            bound[count] = box_sdf(mid[i], R_b, p_b, half) - hl[i] - radius[i]
            first[count], second[count] = i, -1
            count += 1
    best = 1e300
    for _ in range(count):
        k = 0
        for c in range(1, count):
            if bound[c] < bound[k]:
                k = c
        if bound[k] >= best:
            break
        bound[k] = 1e301  # visited
        i, j = first[k], second[k]
        if j >= 0:
            value = segment_segment(A[i], B[i], A[j], B[j]) - radius[i] - radius[j]
        else:
            value = segment_box(A[i], B[i], R_b, p_b, half) - radius[i]
        best = min(best, value)
    return best
