"""Compiled (numba) collision distances: capsules against the obstacle sphere, each other and the base box.

A re-implementation of ``ffsr_gym.model.collision`` (coal) for the kernel, exact in closed form and
validated against it to 1e-9 (``tests/test_kernel.py``). Capsule end points live in the
:data:`~ffsr_gym.kernel.physics.Workspace`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy", inline="always")
def capsule_ends_into(mdl, ws, p_b):
    """World end points of every capsule axis into ``ws.cap_A`` / ``ws.cap_B`` (kinematics in ``ws``)."""
    _capsule_ends(mdl.cap_parent, mdl.cap_a, mdl.cap_b, ws.R_b, ws.Rj, ws.pj, p_b, ws.cap_A, ws.cap_B)


@njit(cache=True, error_model="numpy", inline="always")
def _capsule_ends(cap_parent, cap_a, cap_b, R_b, Rj, pj, p_b, A, B):
    for i in range(len(cap_parent)):
        j = cap_parent[i]
        for a in range(3):
            if j < 0:
                origin, r0, r1, r2 = p_b[a], R_b[a, 0], R_b[a, 1], R_b[a, 2]
            else:
                origin, r0, r1, r2 = pj[j, a], Rj[j, a, 0], Rj[j, a, 1], Rj[j, a, 2]
            A[i, a] = origin + r0 * cap_a[i, 0] + r1 * cap_a[i, 1] + r2 * cap_a[i, 2]
            B[i, a] = origin + r0 * cap_b[i, 0] + r1 * cap_b[i, 1] + r2 * cap_b[i, 2]


@njit(cache=True, error_model="numpy", inline="always")
def _sdf_local(x, y, z, half):
    dx, dy, dz = abs(x) - half[0], abs(y) - half[1], abs(z) - half[2]
    ox, oy, oz = max(dx, 0.0), max(dy, 0.0), max(dz, 0.0)
    outside = ox * ox + oy * oy + oz * oz
    return math.sqrt(outside) if outside > 0.0 else max(dx, max(dy, dz))


@njit(cache=True, error_model="numpy", inline="always")
def _to_box(R_b, c_b, p, i):
    """Coordinate i of p in the box frame (rotation R_b, centre c_b)."""
    return R_b[0, i] * (p[0] - c_b[0]) + R_b[1, i] * (p[1] - c_b[1]) + R_b[2, i] * (p[2] - c_b[2])


@njit(cache=True, error_model="numpy", inline="always")
def _row_to_box(R_b, c_b, P, k, i):
    """Coordinate i of row k of P in the box frame."""
    return R_b[0, i] * (P[k, 0] - c_b[0]) + R_b[1, i] * (P[k, 1] - c_b[1]) + R_b[2, i] * (P[k, 2] - c_b[2])


@njit(cache=True, error_model="numpy")
def box_sdf(p, R_b, c_b, half):
    """Signed distance of point p to the box [m] (negative inside)."""
    return _sdf_local(_to_box(R_b, c_b, p, 0), _to_box(R_b, c_b, p, 1), _to_box(R_b, c_b, p, 2), half)


_PAIRS = ((0, 1), (0, 2), (1, 2))
N_OUTSIDE, N_CANDIDATES = 11, 23


@njit(cache=True, error_model="numpy", inline="always")
def _candidate(la, d, half, k):
    """Candidate k (0..22) of the parameters where the box SDF along la + t d changes formula.

    0, 1: the segment's ends; 2-10: faces and sign changes (x_i = -h_i, 0, h_i); 11-22: crossings
    |x_i| - h_i = |x_j| - h_j of the inside part (a maximum of linear pieces), needed only when
    the segment enters the box. Returns -1 when the candidate does not exist or lies outside [0, 1].
    """
    if k < 2:
        return float(k)
    if k < N_OUTSIDE:
        i = (k - 2) // 3
        if d[i] == 0.0:
            return -1.0
        t = (half[i] * ((k - 2) % 3 - 1) - la[i]) / d[i]
    else:
        i, j = _PAIRS[(k - N_OUTSIDE) // 4]
        si, sj = 2.0 * ((k - N_OUTSIDE) % 2) - 1.0, 2.0 * (((k - N_OUTSIDE) // 2) % 2) - 1.0
        denom = si * d[i] - sj * d[j]
        if denom == 0.0:
            return -1.0
        t = (half[i] - half[j] - si * la[i] + sj * la[j]) / denom
    return t if 0.0 <= t <= 1.0 else -1.0


@njit(cache=True, error_model="numpy", inline="always")
def _sdf_at(la, d, half, t):
    return _sdf_local(la[0] + t * d[0], la[1] + t * d[1], la[2] + t * d[2], half)


@njit(cache=True, error_model="numpy", inline="always")
def _piece_minimum(la, d, half, lo, hi):
    """Minimum of the SDF on [lo, hi], a piece where it has one formula.

    Outside the box the squared SDF is a quadratic in t (closed-form minimiser); inside it is
    linear, so the minimum is at an end (evaluated by the caller).
    """
    tm = 0.5 * (lo + hi)
    num = den = 0.0
    for i in range(3):
        xi = la[i] + tm * d[i]
        if abs(xi) > half[i]:
            s = 1.0 if xi > 0.0 else -1.0
            num -= (s * la[i] - half[i]) * s * d[i]
            den += d[i] * d[i]
    if den == 0.0:
        return 1e300
    return _sdf_at(la, d, half, min(hi, max(lo, num / den)))


@njit(cache=True, error_model="numpy")
def segment_box(a, b, R_b, c_b, half):
    """Signed distance segment–box [m], exact: the convex SDF minimised piece by piece.

    Args:
        a, b: segment end points (world) [m]. R_b, c_b: box rotation and centre. half: half extents [m].
    """
    la = (_to_box(R_b, c_b, a, 0), _to_box(R_b, c_b, a, 1), _to_box(R_b, c_b, a, 2))
    lb = (_to_box(R_b, c_b, b, 0), _to_box(R_b, c_b, b, 1), _to_box(R_b, c_b, b, 2))
    return _segment_box_local(la, (lb[0] - la[0], lb[1] - la[1], lb[2] - la[2]), half, np.empty(N_CANDIDATES))


@njit(cache=True, error_model="numpy")
def _capsule_box(A, B, k, R_b, c_b, half, scratch):
    """:func:`segment_box` for the axis of capsule k (rows of ``A``, ``B``); ``scratch`` has 23 entries."""
    la = (_row_to_box(R_b, c_b, A, k, 0), _row_to_box(R_b, c_b, A, k, 1), _row_to_box(R_b, c_b, A, k, 2))
    lb = (_row_to_box(R_b, c_b, B, k, 0), _row_to_box(R_b, c_b, B, k, 1), _row_to_box(R_b, c_b, B, k, 2))
    return _segment_box_local(la, (lb[0] - la[0], lb[1] - la[1], lb[2] - la[2]), half, scratch)


@njit(cache=True, error_model="numpy")
def _segment_box_local(la, d, half, ts):
    """Minimum over t in [0, 1] of the box SDF at la + t d (box-frame coordinates).

    The candidates of :func:`_candidate` cut [0, 1] into pieces with one formula each; the
    minimum is the smallest of the values at the cuts and of each piece's own minimum.
    """
    n, best = 0, 1e300
    for k in range(N_CANDIDATES):
        if k == N_OUTSIDE and best > 0.0:
            break  # the segment stays outside: the inside crossings do not matter
        t = _candidate(la, d, half, k)
        if t >= 0.0:
            ts[n] = t
            n += 1
            best = min(best, _sdf_at(la, d, half, t))
    for k in range(1, n):  # insertion sort
        t, j = ts[k], k - 1
        while j >= 0 and ts[j] > t:
            ts[j + 1] = ts[j]
            j -= 1
        ts[j + 1] = t
    for k in range(n - 1):
        if ts[k + 1] > ts[k]:
            best = min(best, _piece_minimum(la, d, half, ts[k], ts[k + 1]))
    return best


@njit(cache=True, error_model="numpy", inline="always")
def _point_capsule_axis(p, A, B, k):
    """Distance [m] from p to the axis of capsule k and the vector axis point → p."""
    dx, dy, dz = B[k, 0] - A[k, 0], B[k, 1] - A[k, 1], B[k, 2] - A[k, 2]
    t = ((p[0] - A[k, 0]) * dx + (p[1] - A[k, 1]) * dy + (p[2] - A[k, 2]) * dz) / (dx * dx + dy * dy + dz * dz)
    t = min(1.0, max(0.0, t))
    ex, ey, ez = p[0] - A[k, 0] - t * dx, p[1] - A[k, 1] - t * dy, p[2] - A[k, 2] - t * dz
    return math.sqrt(ex * ex + ey * ey + ez * ez), ex, ey, ez


@njit(cache=True, error_model="numpy")
def _axis_axis(A, B, i, j):
    """Distance [m] between the axes of capsules i and j (clamped closed form)."""
    d1 = (B[i, 0] - A[i, 0], B[i, 1] - A[i, 1], B[i, 2] - A[i, 2])
    d2 = (B[j, 0] - A[j, 0], B[j, 1] - A[j, 1], B[j, 2] - A[j, 2])
    r = (A[i, 0] - A[j, 0], A[i, 1] - A[j, 1], A[i, 2] - A[j, 2])
    a = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]
    e = d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2]
    f = d2[0] * r[0] + d2[1] * r[1] + d2[2] * r[2]
    c = d1[0] * r[0] + d1[1] * r[1] + d1[2] * r[2]
    b = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]
    denom = a * e - b * b
    s = min(1.0, max(0.0, (b * f - c * e) / denom)) if denom > 1e-14 * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = min(1.0, max(0.0, -c / a))
    elif t > 1.0:
        t = 1.0
        s = min(1.0, max(0.0, (b - c) / a))
    dx = r[0] + s * d1[0] - t * d2[0]
    dy = r[1] + s * d1[1] - t * d2[1]
    dz = r[2] + s * d1[2] - t * d2[2]
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, error_model="numpy", inline="always")
def obstacle_clearance(mdl, ws, p_b, p_o, r_o):
    """Signed distance robot–obstacle sphere [m]; ``ws.rel`` gets the vector robot point → obstacle point.

    Needs :func:`capsule_ends_into` done at the current state.
    """
    return _obstacle_clearance(mdl.cap_radius, mdl.box_half, ws.R_b, p_b, ws.cap_A, ws.cap_B, p_o, r_o, ws.rel)


@njit(cache=True, error_model="numpy", inline="always")
def _obstacle_clearance(radius, half, R_b, p_b, A, B, p_o, r_o, rel):
    best = box_sdf(p_o, R_b, p_b, half) - r_o
    l0 = min(half[0], max(-half[0], _to_box(R_b, p_b, p_o, 0)))  # nearest box point (box frame)
    l1 = min(half[1], max(-half[1], _to_box(R_b, p_b, p_o, 1)))
    l2 = min(half[2], max(-half[2], _to_box(R_b, p_b, p_o, 2)))
    for a in range(3):
        rel[a] = p_o[a] - (p_b[a] + R_b[a, 0] * l0 + R_b[a, 1] * l1 + R_b[a, 2] * l2)
    n = math.sqrt(rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2])
    if n > 0.0:
        for a in range(3):
            rel[a] -= r_o * rel[a] / n
    for i in range(len(radius)):
        dist, ex, ey, ez = _point_capsule_axis(p_o, A, B, i)
        value = dist - radius[i] - r_o
        if value < best:
            best = value
            scale = 1.0 - (radius[i] + r_o) / dist if dist > 0.0 else 0.0
            rel[0], rel[1], rel[2] = ex * scale, ey * scale, ez * scale
    return best


@njit(cache=True, error_model="numpy", inline="always")
def body_clearance(mdl, ws, p_b, R_o, c_o, half_o):
    """Signed distance robot–box obstacle [m] (a tumbling target's body: rotation ``R_o``, centre ``c_o``, half
    extents ``half_o``): each capsule's axis against the box less its radius, and the base box against it.

    Box against box is the smallest distance of an edge of either to the other box: exact while they are apart
    (closest points of two convex polyhedra lie on an edge of one of them) and negative once they overlap. Needs
    :func:`capsule_ends_into` done at the current state.
    """
    best = math.inf
    for i in range(len(mdl.cap_radius)):
        best = min(best, _capsule_box(ws.cap_A, ws.cap_B, i, R_o, c_o, half_o, ws.cand) - mdl.cap_radius[i])
    best = min(best, _edges_to_box(ws.R_b, p_b, mdl.box_half, R_o, c_o, half_o, ws.cand))
    return min(best, _edges_to_box(R_o, c_o, half_o, ws.R_b, p_b, mdl.box_half, ws.cand))


@njit(cache=True, error_model="numpy", inline="always")
def _edges_to_box(R_a, c_a, half_a, R_b, c_b, half_b, scratch):
    """Smallest signed distance [m] of the 12 edges of box a to box b (rotations, centres, half extents)."""
    best = math.inf
    for axis in range(3):
        j, k = (axis + 1) % 3, (axis + 2) % 3
        u0, u1, u2 = half_a[axis] * R_a[0, axis], half_a[axis] * R_a[1, axis], half_a[axis] * R_a[2, axis]
        for sj in (-half_a[j], half_a[j]):
            for sk in (-half_a[k], half_a[k]):
                # the edge runs from m − u to m + u (world), m its midpoint seen from box b's centre
                m0 = c_a[0] - c_b[0] + sj * R_a[0, j] + sk * R_a[0, k]
                m1 = c_a[1] - c_b[1] + sj * R_a[1, j] + sk * R_a[1, k]
                m2 = c_a[2] - c_b[2] + sj * R_a[2, j] + sk * R_a[2, k]
                la = (R_b[0, 0] * (m0 - u0) + R_b[1, 0] * (m1 - u1) + R_b[2, 0] * (m2 - u2),
                      R_b[0, 1] * (m0 - u0) + R_b[1, 1] * (m1 - u1) + R_b[2, 1] * (m2 - u2),
                      R_b[0, 2] * (m0 - u0) + R_b[1, 2] * (m1 - u1) + R_b[2, 2] * (m2 - u2))
                d = (2.0 * (R_b[0, 0] * u0 + R_b[1, 0] * u1 + R_b[2, 0] * u2),
                     2.0 * (R_b[0, 1] * u0 + R_b[1, 1] * u1 + R_b[2, 1] * u2),
                     2.0 * (R_b[0, 2] * u0 + R_b[1, 2] * u1 + R_b[2, 2] * u2))
                best = min(best, _segment_box_local(la, d, half_b, scratch))
    return best


@njit(cache=True, error_model="numpy", inline="always")
def self_clearance(mdl, ws, p_b):
    """Smallest signed distance arm–arm and arm–base (mounting links excluded) [m].

    Each candidate pair has a cheap lower bound (bounding spheres); the pair of the smallest bound
    is measured first, then only pairs whose bound can still beat the best so far. Needs
    :func:`capsule_ends_into` done at the current state.
    """
    return _self_clearance(mdl.cap_radius, mdl.cap_arm, mdl.cap_vs_base, mdl.box_half, ws.R_b, p_b, ws.cap_A, ws.cap_B, ws.cap_mid, ws.cap_hl,
                           ws.bound, ws.first, ws.second, ws.cand)


@njit(cache=True, error_model="numpy", inline="always")
def _self_clearance(radius, arm, vs_base, half, R_b, p_b, A, B, mid, hl, bound, first, second, scratch):
    n = len(radius)
    for i in range(n):
        for a in range(3):
            mid[i, a] = 0.5 * (A[i, a] + B[i, a])
        dx, dy, dz = B[i, 0] - A[i, 0], B[i, 1] - A[i, 1], B[i, 2] - A[i, 2]
        hl[i] = 0.5 * math.sqrt(dx * dx + dy * dy + dz * dz)
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
            local = (_row_to_box(R_b, p_b, mid, i, 0), _row_to_box(R_b, p_b, mid, i, 1), _row_to_box(R_b, p_b, mid, i, 2))
            bound[count] = _sdf_local(local[0], local[1], local[2], half) - hl[i] - radius[i]
            first[count], second[count] = i, -1
            count += 1
    k0 = 0
    for c in range(1, count):
        if bound[c] < bound[k0]:
            k0 = c
    best = _pair_distance(A, B, radius, half, R_b, p_b, first[k0], second[k0], scratch)
    for c in range(count):  # only pairs whose bound can still beat the best so far
        if c != k0 and bound[c] < best:
            best = min(best, _pair_distance(A, B, radius, half, R_b, p_b, first[c], second[c], scratch))
    return best


@njit(cache=True, error_model="numpy", inline="always")
def _pair_distance(A, B, radius, half, R_b, p_b, i, j, scratch):
    """Signed distance [m] of capsules i and j, or of capsule i and the base box when j is -1."""
    if j >= 0:
        return _axis_axis(A, B, i, j) - radius[i] - radius[j]
    return _capsule_box(A, B, i, R_b, p_b, half, scratch) - radius[i]
