"""Torque-free motion of a rigid target body: a tumbling satellite or piece of debris (docs/model.md §22).

Until it is captured, the target moves independently of the robot: its centre of mass drifts at constant velocity
and its attitude follows Euler's equations for a body with principal inertia ``I = diag(I_1, I_2, I_3)`` [kg m²]
and no torque,

.. math:: I_1 \\dot\\omega_1 = (I_2 - I_3) \\omega_2 \\omega_3 \\quad (\\text{and cyclically}),
          \\qquad \\dot q = \\tfrac12\\, q \\otimes (0, \\omega),

with ``ω`` the body-frame angular velocity [rad/s] and ``q`` the scalar-first unit quaternion body → world. The
motion is a function of time alone, so an episode computes it once, at every physics step
(:func:`propagate`), before the robot moves.

Integration: classical RK4 on ``(q, ω)`` with ``substeps`` steps per physics step, the quaternion renormalised after
each (a projection back onto the unit sphere, of the size of RK4's local error). At the benchmark's step (0.01 s)
and 4 substeps, a 60 s tumble of a body spinning at up to 1 rad/s keeps its kinetic energy and its angular momentum
in the world frame to about 1e-12 relative (tests/library/model/test_tumbling.py states the tolerances it checks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ffsr_gym.model import portable
from ffsr_gym.model.quaternion import multiply, to_rotation, to_rotations
from ffsr_gym.types import Array


@dataclass(frozen=True)
class TargetMotion:
    """The target at every physics step of an episode: ``(steps + 1)`` rows from t = 0.

    Attributes:
        time_s: (N+1,) [s].
        position_m: (N+1, 3) centre of mass in the world frame [m].
        quaternion: (N+1, 4) attitude body → world, scalar first.
        omega_body_rad_s: (N+1, 3) angular velocity in the body frame [rad/s].
        velocity_m_s: (3,) the constant drift of the centre of mass [m/s].
    """

    time_s: Array
    position_m: Array
    quaternion: Array
    omega_body_rad_s: Array
    velocity_m_s: Array

    @classmethod
    def drifting(cls, position_m: Array, velocity_m_s: Array, dt_s: float, quaternion: Array,
                 omega_body_rad_s: Array) -> TargetMotion:
        """The motion of a body whose attitude and body rates (N+1 rows, one per step of ``dt_s`` [s]) are given and
        whose centre drifts from ``position_m`` [m] at ``velocity_m_s`` [m/s]."""
        time = dt_s * np.arange(len(quaternion))
        velocity = np.asarray(velocity_m_s, dtype=float)
        return cls(time_s=time, position_m=np.asarray(position_m, dtype=float) + time[:, None] * velocity,
                   quaternion=quaternion, omega_body_rad_s=omega_body_rad_s, velocity_m_s=velocity)

    def omega_world_rad_s(self) -> Array:
        """(N+1, 3) angular velocity in the world frame, R(q) ω [rad/s]."""
        return portable.matvec_rows(rotations(self.quaternion), self.omega_body_rad_s)


def euler_rates(omega_body: Array, inertia: Array) -> Array:
    """Torque-free Euler equations: dω/dt in the body frame [rad/s²] for principal ``inertia`` (3,) [kg m²]."""
    i1, i2, i3 = inertia
    w1, w2, w3 = omega_body
    return np.array([(i2 - i3) * w2 * w3 / i1, (i3 - i1) * w3 * w1 / i2, (i1 - i2) * w1 * w2 / i3])


def quaternion_rate(quaternion: Array, omega_body: Array) -> Array:
    """dq/dt = ½ q ⊗ (0, ω) for a body-frame angular velocity ``omega_body`` [rad/s]."""
    return 0.5 * multiply(quaternion, np.array([0.0, *omega_body]))


def _rates(q: tuple, w: tuple, inertia: tuple) -> tuple[tuple, tuple]:
    """:func:`quaternion_rate` and :func:`euler_rates` in Python floats, each operation in their order (the same
    bits, without numpy's per-call cost on 4-vectors)."""
    q0, q1, q2, q3 = q
    w0, w1, w2 = w
    i1, i2, i3 = inertia
    dq = (0.5 * (q0 * 0.0 - ((q1 * w0 + q2 * w1) + q3 * w2)), 0.5 * ((q0 * w0 + 0.0 * q1) + (q2 * w2 - q3 * w1)),
          0.5 * ((q0 * w1 + 0.0 * q2) + (q3 * w0 - q1 * w2)), 0.5 * ((q0 * w2 + 0.0 * q3) + (q1 * w1 - q2 * w0)))
    dw = ((i2 - i3) * w1 * w2 / i1, (i3 - i1) * w2 * w0 / i2, (i1 - i2) * w0 * w1 / i3)
    return dq, dw


def rk4_step(quaternion: Array, omega_body: Array, inertia: Array, h: float) -> tuple[Array, Array]:
    """One classical Runge-Kutta step of length ``h`` [s] of (q, ω); the quaternion returned is renormalised."""
    q, w = _rk4(tuple(map(float, quaternion)), tuple(map(float, omega_body)), tuple(map(float, inertia)), float(h))
    return np.array(q), np.array(w)


def _rk4(q: tuple, w: tuple, inertia: tuple, h: float) -> tuple[tuple, tuple]:
    """:func:`rk4_step` on tuples of Python floats, written out (every sum in numpy's order: the same bits)."""
    half, sixth = 0.5 * h, h / 6.0
    q0, q1, q2, q3 = q
    w0, w1, w2 = w
    (a0, a1, a2, a3), (b0, b1, b2) = _rates(q, w, inertia)
    (c0, c1, c2, c3), (d0, d1, d2) = _rates((q0 + half * a0, q1 + half * a1, q2 + half * a2, q3 + half * a3),
                                            (w0 + half * b0, w1 + half * b1, w2 + half * b2), inertia)
    (e0, e1, e2, e3), (f0, f1, f2) = _rates((q0 + half * c0, q1 + half * c1, q2 + half * c2, q3 + half * c3),
                                            (w0 + half * d0, w1 + half * d1, w2 + half * d2), inertia)
    (g0, g1, g2, g3), (k0, k1, k2) = _rates((q0 + h * e0, q1 + h * e1, q2 + h * e2, q3 + h * e3),
                                            (w0 + h * f0, w1 + h * f1, w2 + h * f2), inertia)
    n0 = q0 + sixth * (((a0 + 2.0 * c0) + 2.0 * e0) + g0)
    n1 = q1 + sixth * (((a1 + 2.0 * c1) + 2.0 * e1) + g1)
    n2 = q2 + sixth * (((a2 + 2.0 * c2) + 2.0 * e2) + g2)
    n3 = q3 + sixth * (((a3 + 2.0 * c3) + 2.0 * e3) + g3)
    size = math.sqrt(((n0 * n0 + n1 * n1) + n2 * n2) + n3 * n3)  # portable.norm's order
    return ((n0 / size, n1 / size, n2 / size, n3 / size),
            (w0 + sixth * (((b0 + 2.0 * d0) + 2.0 * f0) + k0), w1 + sixth * (((b1 + 2.0 * d1) + 2.0 * f1) + k1),
             w2 + sixth * (((b2 + 2.0 * d2) + 2.0 * f2) + k2)))


def propagate(*, position_m: Array, velocity_m_s: Array, quaternion: Array, omega_body_rad_s: Array,
              inertia_kg_m2: Array, dt_s: float, steps: int, substeps: int = 4) -> TargetMotion:
    """The target's motion over ``steps`` physics steps of ``dt_s`` [s] from the given initial state.

    Args:
        position_m: (3,) initial centre of mass, world frame [m].
        velocity_m_s: (3,) constant drift of the centre of mass [m/s].
        quaternion: (4,) initial attitude body → world, scalar first (normalised here).
        omega_body_rad_s: (3,) initial angular velocity in the body frame [rad/s].
        inertia_kg_m2: (3,) principal moments of inertia [kg m²], each > 0.
        dt_s: the physics step [s].
        steps: number of physics steps.
        substeps: RK4 steps per physics step.
    """
    inertia = tuple(float(i) for i in np.asarray(inertia_kg_m2, dtype=float))
    q = tuple(float(c) for c in np.asarray(quaternion, dtype=float) / portable.norm(quaternion))
    w = tuple(float(c) for c in np.asarray(omega_body_rad_s, dtype=float))
    quats, omegas = np.empty((steps + 1, 4)), np.empty((steps + 1, 3))
    quats[0], omegas[0] = q, w
    h = dt_s / substeps
    for n in range(steps):
        for _ in range(substeps):
            q, w = _rk4(q, w, inertia, h)
        quats[n + 1], omegas[n + 1] = q, w
    return TargetMotion.drifting(position_m, velocity_m_s, dt_s, quats, omegas)


def rotations(quaternions: Array) -> Array:
    """(N, 3, 3) rotation matrices of (N, 4) scalar-first unit quaternions."""
    return to_rotations(quaternions)


def angular_momentum_world(motion: TargetMotion, inertia_kg_m2: Array) -> Array:
    """(N+1, 3) angular momentum about the centre of mass in the world frame, R I ω [kg m²/s]."""
    body = np.asarray(inertia_kg_m2)[None, :] * motion.omega_body_rad_s
    return portable.matvec_rows(rotations(motion.quaternion), body)


def kinetic_energy(motion: TargetMotion, inertia_kg_m2: Array) -> Array:
    """(N+1,) rotational kinetic energy ½ ωᵀ I ω [J]."""
    return 0.5 * np.sum(np.asarray(inertia_kg_m2)[None, :] * motion.omega_body_rad_s ** 2, axis=1)


def point_motion(motion: TargetMotion, offset_body_m: Array) -> tuple[Array, Array]:
    """Position [m] and velocity [m/s] in the world frame, (N+1, 3) each, of a point fixed on the body at
    ``offset_body_m`` (3,) from the centre of mass in the body frame: p + R r and v + ω_world × R r."""
    turn = rotations(motion.quaternion)
    arm = portable.matvec_rows(turn, offset_body_m)
    omega_world = portable.matvec_rows(turn, motion.omega_body_rad_s)
    return motion.position_m + arm, motion.velocity_m_s[None, :] + np.cross(omega_world, arm)


def grasp_pose(position_m: Array, quaternion: Array, handle_position_m: Array,
               handle_quaternion: Array) -> tuple[Array, Array]:
    """World position [m] and attitude (scalar first, normalised) of a grasp frame fixed on the body at
    ``handle_position_m`` with attitude ``handle_quaternion`` (body frame), for the body's pose (p, q):
    p + R(q) h and q ⊗ q_h."""
    q = np.asarray(quaternion, dtype=float) / portable.norm(quaternion)
    q_h = np.asarray(handle_quaternion, dtype=float) / portable.norm(handle_quaternion)
    position = np.asarray(position_m, dtype=float) + portable.matvec(to_rotation(q), handle_position_m)
    return position, multiply(q, q_h)
