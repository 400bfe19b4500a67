"""The desired end-effector motion onto a moving grasp frame (docs/model.md §22): the paper's straight-line and
great-arc approach (§5), made to converge onto a frame that drifts and turns with a tumbling target.

With the trapezoidal s(t) of §5, the grasp frame's pose (p_h(t), σ_h(t)) and twist (v_h, ω_h) in the world frame,
and the end-effector's initial pose (p_e0, σ_e0):

.. math::
    p_d = p_{e0} + s\\,(p_h(t) - p_{e0}), \\qquad \\dot p_d = \\dot s\\,(p_h - p_{e0}) + s\\, v_h,

    \\sigma_d = \\sigma_h(t) \\otimes \\exp\\big((1 - s)\\, a\\big), \\qquad
    \\omega_d = \\omega_h - \\dot s\\, R(\\sigma_h)\\, a,

with ``a`` the rotation vector of σ_h(0)* ⊗ σ_e0 (the initial attitude seen from the grasp frame at t = 0). At
s = 0 the desired pose is the initial one; from the end of the motion on (s = 1) it is the grasp frame itself, and
V_ed is the grasp frame's twist: the planner's feedforward J_ed V_ed carries the target's motion, and the
predefined-time feedback φ(e₁) removes what is left within T_c. A still grasp frame gives §5's path back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model import quaternion as quat
from ffsr_gym.model.scenario_sections import TumblingTarget
from ffsr_gym.model.tumbling import TargetMotion, point_motion, propagate, rotations
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
    """The approach onto a moving grasp frame, with the same ``at(t)`` as
    :class:`~ffsr_gym.planning.desired_path.DesiredPath`.

    Attributes:
        start_position: p_e0 [m]; start_attitude: σ_e0; offset: the rotation vector ``a`` [rad];
        grasp: the grasp frame's samples; motion_time, accel_time: t_f, t_a [s].
    """

    start_position: Array
    start_attitude: Array
    offset: Array
    grasp: GraspFrameMotion
    motion_time: float
    accel_time: float

    @classmethod
    def onto(cls, start_position: Array, start_attitude: Array, grasp: GraspFrameMotion, *, motion_time: float,
             accel_time: float) -> MovingTargetPath:
        """The approach from the end-effector's initial pose onto ``grasp``."""
        offset = quat.rotation_vector(quat.multiply(quat.conjugate(grasp.quaternion[0]), np.asarray(start_attitude)))
        return cls(np.asarray(start_position, float), np.asarray(start_attitude, float), offset, grasp, motion_time,
                   accel_time)

    def at(self, t: float) -> tuple[Array, Array, Array]:
        """Desired position [m], attitude (scalar first) and world twist V_ed = [v_d; ω_d] at ``t`` [s]."""
        s, s_dot = trapezoid(t, self.motion_time, self.accel_time)
        k, g = self.grasp.index(t), self.grasp
        chord = g.position_m[k] - self.start_position
        position = self.start_position + s * chord
        attitude = quat.multiply(g.quaternion[k], quat.from_rotation_vector((1.0 - s) * self.offset))
        omega = g.omega_rad_s[k] - s_dot * quat.to_rotation(g.quaternion[k]) @ self.offset
        return position, attitude, np.concatenate((s_dot * chord + s * g.velocity_m_s[k], omega))


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


def body_motion(body: TumblingTarget, *, dt_s: float, steps: int) -> TargetMotion:
    """The motion of a ``[tumbling_target]``'s body at every step of ``dt_s`` [s] over ``steps`` steps."""
    return propagate(position_m=np.array(body.position_m), velocity_m_s=np.array(body.velocity_m_s),
                     quaternion=np.array(body.quaternion_wxyz), omega_body_rad_s=np.deg2rad(body.omega_body_deg_s),
                     inertia_kg_m2=np.array(body.inertia_kg_m2), dt_s=dt_s, steps=steps)


def grasp_motion(body: TumblingTarget, motion: TargetMotion) -> GraspFrameMotion:
    """The grasp frame of a ``[tumbling_target]`` along its body's ``motion`` (:func:`body_motion`)."""
    position, velocity = point_motion(motion, np.array(body.handle_position_m))
    handle = np.array(body.handle_quaternion_wxyz) / np.linalg.norm(body.handle_quaternion_wxyz)
    attitude = np.stack([quat.multiply(q, handle) for q in motion.quaternion])
    dt_s = float(motion.time_s[1] - motion.time_s[0]) if len(motion.time_s) > 1 else 1.0
    return GraspFrameMotion(dt_s, position, attitude, velocity, motion.omega_world_rad_s())
