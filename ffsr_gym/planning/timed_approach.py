"""The commanded approach onto a tumbling target's grasp frame (docs/model.md §23): the method decides when the
end-effector closes in and when the tool goes in.

One command u ∈ [0, 2] drives two progress variables. The approach's s ∈ [0, 1] moves towards min(u, 1); once it
rests at 1, the insertion's w ∈ [0, 1] moves towards u − 1; a command below 1 withdraws the tool first (w back to
0) and then moves s. Each moves as fast as its stage's top speed and acceleration allow and stops on its target
(:func:`profile_step`). The desired end-effector pose is s of the way from the start pose (p₀, σ₀) to the
pre-grasp frame, the grasp frame (p_h, σ_h) moved back along its approach (z) axis a by d = standoff (1 − w):

.. math::
    p_g = p_h - d\\,a, \\qquad v_g = v_h - \\dot d\\,a - d\\,\\omega_h \\times a,

    p_d = p_0 + s\\,(p_g - p_0), \\qquad \\dot p_d = \\dot s\\,(p_g - p_0) + s\\,v_g,

    \\sigma_d = \\sigma_0 \\otimes \\exp(s\\,b), \\quad b = \\log(\\sigma_0^* \\otimes \\sigma_h), \\qquad
    \\omega_d = R(\\sigma_0)\\,J_l(s b)\\,(\\dot s\\,b + s\\,\\dot b), \\quad
    \\dot b = J_l(b)^{-1} R(\\sigma_0)^T \\omega_h,

and, resting at s = 1, the pre-grasp frame itself (σ_h, ω_h). The native kernel computes the same
(``src/native/timing.cpp``) at every physics step; this module is its readable reference, in Python floats in the
kernel's order of operations.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, replace

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model import portable
from ffsr_gym.model import quaternion as quat
from ffsr_gym.model.scenario_sections import CommandedApproach
from ffsr_gym.planning.moving_target import GraspFrameMotion, left_jacobian_times
from ffsr_gym.types import Array

#: The fields of a commanded approach's state, in the kernel's order.
TIMING_FIELDS = ("command", "s", "s_dot", "w", "w_dot")


@dataclass(frozen=True)
class ApproachLimits:
    """How fast a commanded approach may go: the pre-grasp standoff [m] and each stage's top speed [1/s] and
    acceleration [1/s²] (s and w each run over [0, 1])."""

    standoff_m: float
    approach_speed: float
    approach_accel: float
    insert_speed: float
    insert_accel: float

    def kernel_values(self) -> tuple[float, float, float, float, float]:
        """The arguments of the kernel's ``PlannerSettings.set_timing``."""
        return (self.standoff_m, self.approach_speed, self.approach_accel, self.insert_speed, self.insert_accel)


@dataclass
class TimingState:
    """A commanded approach's state: the command u ∈ [0, 2], the approach's progress s and rate ṡ, the insertion's
    progress w and rate ẇ (mutable: one per episode)."""

    command: float = 0.0
    s: float = 0.0
    s_dot: float = 0.0
    w: float = 0.0
    w_dot: float = 0.0

    def values(self) -> tuple[float, float, float, float, float]:
        """(command, s, ṡ, w, ẇ), the kernel's order."""
        return (self.command, self.s, self.s_dot, self.w, self.w_dot)

    def set_command(self, command: float) -> None:
        """Command u from the next step on.

        Raises:
            InvalidInputError: u is not a finite number in [0, 2].
        """
        if isinstance(command, (bool, np.bool_)) or not isinstance(command, numbers.Real) \
                or not math.isfinite(command) or not 0.0 <= command <= 2.0:
            raise InvalidInputError(f"approach command {command!r}; allowed: a number in [0, 2] (0: stay at the "
                                    "start, 1: at the pre-grasp frame, 2: inserted)")
        self.command = float(command)

    def advance(self, limits: ApproachLimits, dt: float) -> None:
        """One physics step of ``dt`` [s]: the insertion moves while s rests at 1 (or w is not at rest at 0),
        else the approach."""
        u = self.command
        s_target = min(max(u, 0.0), 1.0)
        w_target = 0.0 if s_target < 1.0 else min(max(u - 1.0, 0.0), 1.0)
        inserting = self.w != 0.0 or self.w_dot != 0.0
        arrived = self.s == 1.0 and self.s_dot == 0.0
        if inserting or (arrived and w_target > 0.0):
            self.w, self.w_dot = profile_step(w_target, limits.insert_speed, limits.insert_accel, dt, self.w,
                                              self.w_dot)
        else:
            self.s, self.s_dot = profile_step(s_target, limits.approach_speed, limits.approach_accel, dt, self.s,
                                              self.s_dot)


def profile_step(target: float, speed: float, accel: float, dt: float, y: float, y_dot: float) -> tuple[float, float]:
    """One step of ``dt`` of y towards ``target``, semi-implicit Euler (the rate first, then y with the new rate):
    the rate moves by at most ``accel`` dt towards the fastest speed that still stops on the target in steps of
    a dt, a dt (sqrt(1/4 + 2|e|/(a dt²)) − 1/2) (one step later that speed is exactly a dt less: with f that speed
    over a dt, f² + f = 2|e|/(a dt²)), at most ``speed``; a step that would cross the target ends on it, at rest.
    Returns (y, ẏ) after the step."""
    e = target - y
    if e == 0.0 and y_dot == 0.0:
        return y, y_dot
    unit = accel * dt
    wanted = min(speed, unit * (math.sqrt(0.25 + 2.0 * abs(e) / (unit * dt)) - 0.5))
    if e < 0.0:
        wanted = -wanted
    change = min(max(wanted - y_dot, -unit), unit)
    rate = y_dot + change
    after = y + rate * dt
    if (target - after) * e <= 0.0:
        return target, 0.0
    return after, rate


def left_jacobian_inverse(rotation: Array, vector: Array) -> list[float]:
    """J_l(φ)⁻¹ x = x − ½ φ × x + c φ × (φ × x), c = (1 − (θ/2) cot(θ/2)) / θ² (finite up to θ = π; its series to
    θ⁶ below θ = 0.1)."""
    theta = portable.norm(rotation)
    if theta < 0.1:
        t2 = theta * theta
        c = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0 + t2 * t2 * t2 / 1209600.0
    else:
        half = 0.5 * theta
        c = (1.0 - half / math.tan(half)) / (theta * theta)
    once = portable.cross(rotation, vector)
    twice = portable.cross(rotation, once)
    return [float(x) - 0.5 * y + c * z for x, y, z in zip(vector, once, twice)]


def _log(q: Array) -> list[float]:
    """The rotation vector of a unit quaternion, the shorter way round (the kernel's ``quat_log``)."""
    sign = -1.0 if q[0] < 0.0 else 1.0
    w, v = sign * float(q[0]), [sign * float(x) for x in q[1:]]
    n = portable.norm(v)
    k = 2.0 / w if n < 1e-12 else 2.0 * math.atan2(n, w) / n
    return [k * x for x in v]


def _exp(phi: list[float]) -> list[float]:
    theta = portable.norm(phi)
    half = 0.5 * theta
    k = 0.5 if theta < 1e-8 else math.sin(half) / theta
    return [math.cos(half), k * phi[0], k * phi[1], k * phi[2]]


def timed_desired(limits: ApproachLimits, state: TimingState, start_position: Array, start_attitude: Array,
                  grasp_position: Array, grasp_attitude: Array, grasp_twist: Array) -> tuple[Array, Array, Array]:
    """Desired position [m], attitude (scalar first) and world twist [v; ω] of the commanded approach at ``state``
    for the grasp frame's pose and twist at that step (module docstring)."""
    rotation = quat.to_rotation(grasp_attitude)
    axis = [float(rotation[i][2]) for i in range(3)]
    omega = [float(x) for x in grasp_twist[3:]]
    spin = portable.cross(omega, axis)
    d, d_dot = limits.standoff_m * (1.0 - state.w), -limits.standoff_m * state.w_dot
    p_g = [float(p) - d * a for p, a in zip(grasp_position, axis)]
    v_g = [float(v) - d_dot * a - d * r for v, a, r in zip(grasp_twist[:3], axis, spin)]
    if state.s == 1.0 and state.s_dot == 0.0:
        return _array(p_g), _array(grasp_attitude), _array(v_g + omega)
    s, s_dot = state.s, state.s_dot
    chord = [g - float(p) for g, p in zip(p_g, start_position)]
    p_d = [float(p) + s * c for p, c in zip(start_position, chord)]
    v_d = [s_dot * c + s * v for c, v in zip(chord, v_g)]
    q0 = [float(x) for x in start_attitude]
    q0_conj = quat.conjugate(q0)
    b = _log(quat.multiply(q0_conj, grasp_attitude))
    local = portable.matvec(quat.to_rotation(q0_conj), omega)
    b_dot = left_jacobian_inverse(b, local)
    sb = [s * x for x in b]
    feed = [s_dot * x + s * y for x, y in zip(b, b_dot)]
    attitude = quat.multiply(q0, _exp(sb))
    rate = portable.matvec(quat.to_rotation(q0), left_jacobian_times(sb, feed))
    return _array(p_d), _array(attitude), _array(v_d + rate)


def _array(values) -> Array:
    return np.array([float(x) for x in values])


def approach_limits(approach: CommandedApproach, standoff_m: float) -> ApproachLimits:
    """The limits of a ``[commanded_approach]`` with the tumbling target's standoff [m]: each stage's top speed is
    1 / its time at that speed, its acceleration that speed / its ramp time."""
    approach_speed, insert_speed = 1.0 / approach.approach_time_s, 1.0 / approach.insertion_time_s
    return ApproachLimits(standoff_m, approach_speed, approach_speed / approach.approach_ramp_s, insert_speed,
                          insert_speed / approach.insertion_ramp_s)


@dataclass(frozen=True)
class TimedPath:
    """A commanded approach, read like a :class:`~ffsr_gym.planning.desired_path.DesiredPath`: :meth:`at` gives the
    desired pose and twist at the current :attr:`state`, which the rollout advances after every physics step and
    the method commands. A scenario's set-up holds one with the initial state; each rollout follows its own
    (:meth:`fresh`).

    Attributes:
        grasp: the grasp frame's samples; start_position [m], start_attitude: the end-effector's initial pose;
        limits: the speeds; state: the state this path reads; motion_time, accel_time: the approach's time at
            its top speed and its ramp [s] (what a scripted path's motion and acceleration times were).
    """

    grasp: GraspFrameMotion
    start_position: Array
    start_attitude: Array
    limits: ApproachLimits
    state: TimingState
    motion_time: float
    accel_time: float

    def fresh(self) -> TimedPath:
        """The same approach following a state of its own, a copy of this one's."""
        return replace(self, state=TimingState(*self.state.values()))

    @property
    def position_m(self) -> Array:
        """The grasp frame's positions [m] (what the kernel's frames hold for a commanded approach)."""
        return self.grasp.position_m

    @property
    def attitude(self) -> Array:
        """The grasp frame's attitudes (scalar first)."""
        return self.grasp.quaternion

    @property
    def twist(self) -> Array:
        """The grasp frame's world twists [v; ω] (N+1, 6)."""
        return np.hstack((self.grasp.velocity_m_s, self.grasp.omega_rad_s))

    def at(self, t: float) -> tuple[Array, Array, Array]:
        """Desired position [m], attitude (scalar first) and world twist at ``t`` [s] (a multiple of the step) and the
        current state."""
        k = self.grasp.index(t)
        twist = [*self.grasp.velocity_m_s[k], *self.grasp.omega_rad_s[k]]
        return timed_desired(self.limits, self.state, self.start_position, self.start_attitude,
                             self.grasp.position_m[k], self.grasp.quaternion[k], twist)
