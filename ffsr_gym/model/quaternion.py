"""Scalar-first unit quaternions ``[w, x, y, z]`` (the paper's convention, docs/model.md §1).

Pinocchio stores the free-flyer attitude as ``(x, y, z, w)``; the two conversions below are the
only place where the orders meet.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ffsr_gym.model import portable
from ffsr_gym.types import Array


def wxyz_from_xyzw(quat_xyzw: Array) -> Array:
    """Reorder a Pinocchio ``(x, y, z, w)`` quaternion to scalar-first ``[w, x, y, z]``."""
    return np.array([quat_xyzw[3], quat_xyzw[0], quat_xyzw[1], quat_xyzw[2]])


def xyzw_from_wxyz(quat_wxyz: Array) -> Array:
    """Reorder a scalar-first ``[w, x, y, z]`` quaternion to Pinocchio's ``(x, y, z, w)``."""
    return np.array([quat_wxyz[1], quat_wxyz[2], quat_wxyz[3], quat_wxyz[0]])


def skew(a: Array) -> Array:
    """Return the 3x3 matrix S(a) with S(a) b = a x b."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def multiply(a: Array, b: Array) -> Array:
    """Hamilton product a ⊗ b of scalar-first quaternions.

    Scalar arithmetic in a fixed order, the same on every machine (``ffsr_gym.model.portable``).
    """
    aw, ax, ay, az = (float(c) for c in a)
    bw, bx, by, bz = (float(c) for c in b)
    return np.array([aw * bw - ((ax * bx + ay * by) + az * bz),
                     (aw * bx + bw * ax) + (ay * bz - az * by),
                     (aw * by + bw * ay) + (az * bx - ax * bz),
                     (aw * bz + bw * az) + (ax * by - ay * bx)])


def multiply_rows(a: Array, b: Array) -> Array:
    """Row-wise :func:`multiply` of (N, 4) (or (4,), broadcast) quaternions, with its operations in its order (the
    same bits, row by row)."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=float), -1, 0)
    return np.stack([aw * bw - ((ax * bx + ay * by) + az * bz),
                     (aw * bx + bw * ax) + (ay * bz - az * by),
                     (aw * by + bw * ay) + (az * bx - ax * bz),
                     (aw * bz + bw * az) + (ax * by - ay * bx)], axis=-1)


def conjugate(a: Array) -> Array:
    """Return the conjugate (w, -x, -y, -z)."""
    return np.array([a[0], -a[1], -a[2], -a[3]])


def to_rotation(quat_wxyz: Array) -> Array:
    """Rotation matrix R(σ) = (η² − εᵀε) I + 2 ε εᵀ + 2 η S(ε) of a unit quaternion."""
    eta, eps = quat_wxyz[0], np.asarray(quat_wxyz[1:])
    return (eta * eta - portable.dot(eps, eps)) * np.eye(3) + 2.0 * np.outer(eps, eps) + 2.0 * eta * skew(eps)


def to_rotations(quats_wxyz: Array) -> Array:
    """(N, 3, 3) :func:`to_rotation` of (N, 4) unit quaternions, with its operations in its order (the same bits,
    row by row): diagonal s + 2 ε_i², off-diagonal 2 ε_i ε_j + 2η S(ε)_ij, s = η² − ((ε₁² + ε₂²) + ε₃²)."""
    w, x, y, z = np.asarray(quats_wxyz, dtype=float).T
    s, tw = w * w - ((x * x + y * y) + z * z), 2.0 * w
    return np.stack([s + 2.0 * (x * x), 2.0 * (x * y) - tw * z, 2.0 * (x * z) + tw * y,
                     2.0 * (y * x) + tw * z, s + 2.0 * (y * y), 2.0 * (y * z) - tw * x,
                     2.0 * (z * x) - tw * y, 2.0 * (z * y) + tw * x, s + 2.0 * (z * z)], axis=-1).reshape(-1, 3, 3)


def from_rotation(rotation: Array) -> Array:
    """Scalar-first unit quaternion of a rotation matrix, with w >= 0."""
    quat = pin.Quaternion(np.asarray(rotation))
    out = np.array([quat.w, quat.x, quat.y, quat.z])
    return out if out[0] >= 0.0 else -out


def from_axis_angle(axis: Array, angle_rad: float) -> Array:
    """Quaternion of a rotation by ``angle_rad`` [rad] about the unit ``axis``."""
    return np.concatenate(([math.cos(angle_rad / 2.0)], math.sin(angle_rad / 2.0) * np.asarray(axis)))


def from_rotation_vector(rotation: Array) -> Array:
    """Quaternion of a rotation vector (axis × angle [rad]); the identity for the zero vector."""
    angle = portable.norm(rotation)
    if angle == 0.0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    return from_axis_angle(np.asarray(rotation) / angle, angle)


def rotation_vector(quaternion: Array) -> Array:
    """The rotation vector (axis × angle [rad], angle in [0, π]) of a scalar-first unit quaternion."""
    q = -np.asarray(quaternion) if quaternion[0] < 0.0 else np.asarray(quaternion)
    sin_half = portable.norm(q[1:])
    if sin_half == 0.0:
        return np.zeros(3)
    return 2.0 * math.atan2(sin_half, float(q[0])) * q[1:] / sin_half
