"""The desired end-effector motion onto a moving grasp frame (docs/model.md §22): the paper's straight-line and
great-arc approach (§5), made to converge onto a frame that drifts and turns with a tumbling target.

With the trapezoidal s(t) of §5, the grasp frame's pose (p_h(t), σ_h(t)) and twist (v_h, ω_h) in the world frame,
and the end-effector's initial pose (p_e0, σ_e0):

.. math::
    p_d = p_{e0} + s\\,(p_h(t) - p_{e0}), \\qquad \\dot p_d = \\dot s\\,(p_h - p_{e0}) + s\\, v_h,

    \\sigma_d = \\exp(s\\,\\delta(t)) \\otimes \\sigma_h(0) \\otimes \\exp\\big((1 - s)\\, a\\big),

    \\omega_d = J_l(s\\delta)\\,(\\dot s\\,\\delta + s\\,\\dot\\delta)
               - \\dot s\\, R(\\exp(s\\delta))\\, R(\\sigma_h(0))\\, a,

with ``a`` the rotation vector of σ_h(0)* ⊗ σ_e0 (the initial attitude seen from the grasp frame at t = 0), δ(t) the
rotation vector of the frame's turn since t = 0, σ_h(t) ⊗ σ_h(0)* (δ̇ = J_l(δ)⁻¹ ω_h), and J_l the left Jacobian of
SO(3). The end-effector takes on the frame's turn as it arrives (s of it): at s = 0 the desired pose is the initial
one and still; from the end of the motion on (s = 1) it is the grasp frame itself, and V_ed its twist, so the
planner's feedforward J_ed V_ed carries the target's motion and the predefined-time feedback φ(e₁) removes what is
left within T_c. A still grasp frame gives §5's path back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model import portable
from ffsr_gym.model import quaternion as quat
from ffsr_gym.model.scenario_sections import TumblingTarget
from ffsr_gym.model.tumbling import TargetMotion, point_motion, rotations
from ffsr_gym.planning.desired_path import trapezoid
from ffsr_gym.types import Array


@dataclass(frozen=True)
class GraspFrameMotion:
    """A grasp frame sampled at every physics step from t = 0 (world frame).

    Attributes:
        dt_s: the step [s].
        position_m: (N+1, 3) [m]; quaternion: (N+1, 4) scalar first; velocity_m_s: (N+1, 3) [m/s];
        omega_rad_s: (N+1, 3) angular velocity [rad/s].
    """

    dt_s: float
    position_m: Array
    quaternion: Array
    velocity_m_s: Array
    omega_rad_s: Array

    def index(self, t: float) -> int:
        """The sample at ``t`` [s], a multiple of the step.

        Raises:
            InvalidInputError: ``t`` is off the grid or beyond the samples.
        """
        k = int(round(t / self.dt_s))
        if abs(k * self.dt_s - t) > 1e-9 * max(1.0, abs(t)) or not 0 <= k < len(self.position_m):
            raise InvalidInputError(f"t = {t!r} s; allowed: a multiple of {self.dt_s} s in [0, "
                                    f"{(len(self.position_m) - 1) * self.dt_s:g}] s (the grasp frame's samples)")
        return k


@dataclass(frozen=True)
class MovingTargetPath:
    """The approach onto a moving grasp frame, sampled at every physics step, with the same ``at(t)`` as
    :class:`~ffsr_gym.planning.desired_path.DesiredPath` (module docstring).

    Attributes:
        start_position: p_e0 [m]; start_attitude: σ_e0; grasp: the approached frame's samples;
        motion_time, accel_time: t_f, t_a [s];
        position_m: (N+1, 3) p_d [m]; attitude: (N+1, 4) σ_d; twist: (N+1, 6) V_ed = [v_d; ω_d] (world).
    """

    start_position: Array
    start_attitude: Array
    grasp: GraspFrameMotion
    motion_time: float
    accel_time: float
    position_m: Array
    attitude: Array
    twist: Array

    @classmethod
    def onto(cls, start_position: Array, start_attitude: Array, grasp: GraspFrameMotion, *, motion_time: float,
             accel_time: float) -> MovingTargetPath:
        """The approach from the end-effector's initial pose onto ``grasp``.

        Raises:
            InvalidInputError: the frame turns by 177 deg or more before the end of the motion (near half a
                turn its rotation since t = 0 has no unique rotation vector).
        """
        p0, q0 = np.asarray(start_position, float), np.asarray(start_attitude, float)
        t = np.arange(len(grasp.position_m)) * grasp.dt_s
        law = np.array([trapezoid(x, motion_time, accel_time) for x in t])
        s, s_dot = law[:, :1], law[:, 1:]
        chord = grasp.position_m - p0
        position, velocity = p0 + s * chord, s_dot * chord + s * grasp.velocity_m_s
        first = grasp.quaternion[0]
        offset = quat.rotation_vector(quat.multiply(quat.conjugate(first), q0))
        moving = np.flatnonzero((s[:, 0] != 1.0) | (t < motion_time))  # the rows before arrival
        turned_rows = quat.multiply_rows(grasp.quaternion[moving], quat.conjugate(first))
        turn = np.zeros((len(t), 3))  # δ: the frame's turn since t = 0 (needed before arrival only)
        turn[moving] = [quat.rotation_vector(q) for q in turned_rows]
        turned = max((portable.norm(row) for row in turn[t < motion_time]), default=0.0)
        if turned > math.pi - 0.05:
            raise InvalidInputError(f"the grasp frame turns by {math.degrees(turned):.0f} deg before the end of the "
                                    f"motion ({motion_time:g} s); allowed: less than 177 deg (a slower spin or a "
                                    "shorter trajectory.motion_time_s)")
        attitude, omega = grasp.quaternion.copy(), grasp.omega_rad_s.copy()  # arrived (s = 1): the frame itself
        offset_world = portable.matvec(quat.to_rotation(first), offset)  # R(σ_h(0)) a
        for k in moving:
            sk, sdk = float(s[k, 0]), float(s_dot[k, 0])
            if sk == 1.0:
                continue
            synced = quat.from_rotation_vector(sk * turn[k])  # exp(s δ): the frame's turn since t = 0, s of it
            still = quat.multiply(first, quat.from_rotation_vector((1.0 - sk) * offset))
            attitude[k] = quat.multiply(synced, still)
            turn_rate = left_jacobian_inverse_times(turn[k], grasp.omega_rad_s[k])  # δ̇ = J_l(δ)⁻¹ ω_h
            feed = [sdk * float(d) + sk * r for d, r in zip(turn[k], turn_rate)]
            carried = portable.matvec(quat.to_rotation(synced), offset_world)
            omega[k] = [a - sdk * b for a, b in zip(left_jacobian_times(sk * turn[k], feed), carried)]
        return cls(p0, q0, grasp, motion_time, accel_time, position, attitude, np.hstack((velocity, omega)))

    def at(self, t: float) -> tuple[Array, Array, Array]:
        """Desired position [m], attitude (scalar first) and world twist V_ed = [v_d; ω_d] at ``t`` [s], a
        multiple of the step."""
        k = self.grasp.index(t)
        return self.position_m[k], self.attitude[k], self.twist[k]


def left_jacobian_times(rotation: Array, vector: Array) -> list[float]:
    """J_l(φ) x for the left Jacobian of SO(3) at the rotation vector φ (the world angular velocity of exp(φ(t)) is
    J_l(φ) φ̇): x + (1 − cos θ)/θ² φ × x + (θ − sin θ)/θ³ φ × (φ × x), θ = |φ| (their series to θ⁶ below
    θ = 0.1, where they are the more accurate). Scalar arithmetic in a fixed order (``ffsr_gym.model.portable``): no BLAS."""
    theta = portable.norm(rotation)
    if theta < 0.1:
        t2 = theta * theta
        a = 0.5 - t2 / 24.0 + t2 * t2 / 720.0 - t2 * t2 * t2 / 40320.0
        b = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0 - t2 * t2 * t2 / 362880.0
    else:
        a, b = (1.0 - math.cos(theta)) / (theta * theta), (theta - math.sin(theta)) / (theta * theta * theta)
    return _plus_crosses(rotation, vector, a, b)


def left_jacobian_inverse_times(rotation: Array, vector: Array) -> list[float]:
    """J_l(φ)⁻¹ x in closed form: x − ½ φ × x + (1/θ² − (1 + cos θ)/(2 θ sin θ)) φ × (φ × x), θ = |φ| < π (its
    series to θ⁶ below θ = 0.1); no linear solve, so no LAPACK kernel the CPU chooses."""
    theta = portable.norm(rotation)
    if theta < 0.1:
        t2 = theta * theta
        c = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0 + t2 * t2 * t2 / 1209600.0
    else:
        c = 1.0 / (theta * theta) - (1.0 + math.cos(theta)) / (2.0 * theta * math.sin(theta))
    return _plus_crosses(rotation, vector, -0.5, c)


def _plus_crosses(rotation: Array, vector: Array, a: float, b: float) -> list[float]:
    """x + a φ × x + b φ × (φ × x), in Python floats."""
    once = portable.cross(rotation, vector)
    twice = portable.cross(rotation, once)
    return [float(x) + a * y + b * z for x, y, z in zip(vector, once, twice)]


def pre_grasp(grasp: GraspFrameMotion, *, standoff_m: float, insert_start_s: float, insert_time_s: float,
              axis: int = 2) -> GraspFrameMotion:
    """The grasp frame moved back along its approach axis (column ``axis`` of its rotation, the tool's z by
    default) by a standoff that closes to 0 over the insertion: d(t) = standoff (1 − s_i(t)), s_i the trapezoid of
    §5 over [insert_start_s, insert_start_s + insert_time_s] (acceleration time a quarter of it). Approaching this
    frame brings the tool in along the grasp axis instead of across the body (docs/model.md §22).

    Its velocity is v_h − ḋ a − d ω_h × a for the approach axis a = R(σ_h) e_axis; its attitude and angular
    velocity are the grasp frame's.
    """
    t = np.arange(len(grasp.position_m)) * grasp.dt_s - insert_start_s
    profile = np.array([trapezoid(x, insert_time_s, insert_time_s / 4.0) for x in t])
    distance, rate = standoff_m * (1.0 - profile[:, 0]), -standoff_m * profile[:, 1]
    approach = rotations(grasp.quaternion)[:, :, axis]
    position = grasp.position_m - distance[:, None] * approach
    velocity = (grasp.velocity_m_s - rate[:, None] * approach
                - distance[:, None] * np.cross(grasp.omega_rad_s, approach))
    return GraspFrameMotion(grasp.dt_s, position, grasp.quaternion, velocity, grasp.omega_rad_s)


def grasp_motion(body: TumblingTarget, motion: TargetMotion) -> GraspFrameMotion:
    """The grasp frame of a ``[tumbling_target]`` along its body's ``motion`` (``ffsr_gym.sim.setup``)."""
    position, velocity = point_motion(motion, np.array(body.handle_position_m))
    handle = np.array(body.handle_quaternion_wxyz) / portable.norm(body.handle_quaternion_wxyz)
    attitude = quat.multiply_rows(motion.quaternion, handle)
    dt_s = float(motion.time_s[1] - motion.time_s[0]) if len(motion.time_s) > 1 else 1.0
    return GraspFrameMotion(dt_s, position, attitude, velocity, motion.omega_world_rad_s())


def approach_frame(body: TumblingTarget, grasp: GraspFrameMotion, motion_time_s: float) -> GraspFrameMotion:
    """The frame the planner approaches: the grasp frame itself, or with ``standoff_m`` > 0 its :func:`pre_grasp`
    frame, inserted over ``insertion_time_s`` from the end of the desired motion (``motion_time_s`` [s]) on."""
    if body.standoff_m <= 0.0:
        return grasp
    return pre_grasp(grasp, standoff_m=body.standoff_m, insert_start_s=motion_time_s,
                     insert_time_s=body.insertion_time_s)


@dataclass(frozen=True)
class BodyField:
    """The tumbling body as the danger field sees it (docs/model.md §22): its centre at every step (a point of the
    field, like an obstacle's), the radius of its bounding sphere and the danger radius beyond that sphere [m].

    The field acts on every arm segment but the tool's (the tool must come close: it grasps the handle); the
    blend's distance is the arm's distance to the centre minus ``bounding_radius_m``, over ``danger_radius_m``.
    """

    centre_m: Array
    dt_s: float
    bounding_radius_m: float
    danger_radius_m: float

    @classmethod
    def of(cls, body: TumblingTarget, motion: TargetMotion, dt_s: float) -> BodyField | None:
        """The field of a ``[tumbling_target]`` moving as ``motion`` (None when its ``danger_radius_m`` is 0)."""
        if body.danger_radius_m <= 0.0:
            return None
        return cls(motion.position_m, dt_s, 0.5 * portable.norm(body.size_m), body.danger_radius_m)

    def centre(self, t: float) -> Array:
        """The centre [m] at ``t`` [s] (the sample of the step ``t`` falls on)."""
        k = min(int(math.floor(t / self.dt_s + 0.5)), len(self.centre_m) - 1)
        return self.centre_m[k]
