"""Desired end-effector trajectory: trapezoidal velocity profile (paper Fig. 3; docs/model.md §5).

s(t) rises from 0 to 1 over the motion time t_f with constant acceleration for t_a, constant
speed, then constant deceleration for t_a; it holds s = 1 afterwards. Position moves on the
straight line p_e0 → p_t, attitude on the shortest great arc (SLERP) σ_e0 → σ_t, both with s(t).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ffsr_gym.model import portable
from ffsr_gym.model import quaternion as quat
from ffsr_gym.types import Array


def trapezoid(t: float, motion_time: float, accel_time: float) -> tuple[float, float]:
    """Normalised path parameter s(t) and its rate ds/dt [1/s] for the trapezoidal profile."""
    t_f, t_a = motion_time, accel_time
    speed = 1.0 / (t_f - t_a)
    accel = speed / t_a
    if t <= 0.0:
        return 0.0, 0.0
    if t < t_a:
        return 0.5 * accel * t * t, accel * t
    if t <= t_f - t_a:
        return 0.5 * accel * t_a * t_a + speed * (t - t_a), speed
    if t < t_f:
        return 1.0 - 0.5 * accel * (t_f - t) ** 2, accel * (t_f - t)
    return 1.0, 0.0


@dataclass(frozen=True)
class DesiredPath:
    """Straight-line + SLERP path from the initial to the target end-effector pose.

    Attributes:
        start_position, target_position: [m], (3,).
        start_attitude: σ_e0, scalar-first.
        axis, angle: the rotation σ_t ⊗ σ_e0* as unit axis and angle [rad] in [0, π].
        motion_time, accel_time: t_f and t_a [s].
    """

    start_position: Array
    target_position: Array
    start_attitude: Array
    axis: Array
    angle: float
    motion_time: float
    accel_time: float

    @classmethod
    def between(cls, start_position: Array, start_attitude: Array, target_position: Array,
                target_attitude: Array, *, motion_time: float, accel_time: float) -> DesiredPath:
        """Build the path between two poses (quaternions scalar-first)."""
        delta = quat.multiply(np.asarray(target_attitude), quat.conjugate(np.asarray(start_attitude)))
        if delta[0] < 0.0:
            delta = -delta
        sin_half = portable.norm(delta[1:])
        angle = 2.0 * math.atan2(sin_half, float(delta[0]))
        axis = delta[1:] / sin_half if sin_half > 0.0 else np.array([1.0, 0.0, 0.0])
        return cls(np.asarray(start_position, float), np.asarray(target_position, float),
                   np.asarray(start_attitude, float), axis, angle, motion_time, accel_time)

    def at(self, t: float) -> tuple[Array, Array, Array]:
        """Desired position [m], attitude (scalar-first) and world twist V_ed = [v_d; ω_d] at ``t`` [s]."""
        s, s_dot = trapezoid(t, self.motion_time, self.accel_time)
        chord = self.target_position - self.start_position
        position = self.start_position + s * chord
        attitude = quat.multiply(quat.from_axis_angle(self.axis, s * self.angle), self.start_attitude)
        twist = np.concatenate((s_dot * chord, s_dot * self.angle * self.axis))
        return position, attitude, twist
