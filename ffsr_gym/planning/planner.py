"""The four planning methods of the paper's Section 5 behind one interface (docs/model.md §8).

At each step the planner maps the time and the state to the joint rates of both arms:

* mission arm (19c): Θ̇¹ = μ₁ (J_m¹)^# x₁ + [E − μ₁ (J_m¹)⁺ J_m¹] Θ̇_c¹,
  x₁ = J_e⁻¹ (J_ed V_ed − φ(e₁)) − J₀ V₀*, V₀* = −J_b⁻¹ φ(e₀);
* balance arm (20c): Θ̇² = μ₂ (J_c²)^# x₂ + [E − μ₂ (J_c²)⁺ J_c²] Θ̇_c²,
  x₂ = J_c¹ Θ̇¹ − H₀ J_b⁻¹ φ(e₀) − C, with J_c¹ = H_bm1, J_c² = −H_bm2, H₀ = H_b.

Methods: ``predefined_time`` (φ the predefined-time function, CDF avoidance),
``proportional`` (φ(x) = K x), ``no_feedback`` (φ ≡ 0) and ``no_avoidance`` (predefined-time φ,
μ ≡ 1: the planner ignores the obstacle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.obstacles import obstacle_field
from ffsr_gym.model.quaternion import from_rotation, skew
from ffsr_gym.model.robot import Robot
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.planning import ptsf
from ffsr_gym.planning.avoidance import blend_factor, danger_field, danger_field_gradient
from ffsr_gym.planning.desired_path import DesiredPath
from ffsr_gym.planning.inverse import filtered_inverse
from ffsr_gym.planning.moving_target import BodyField
from ffsr_gym.planning.pose_error import pose_error
from ffsr_gym.planning.target_estimate import estimate_index
from ffsr_gym.types import Array

METHODS = ("no_avoidance", "no_feedback", "proportional", "predefined_time")


@dataclass(frozen=True)
class PlanStep:
    """What the planner decided at one instant, with the quantities it used.

    Attributes:
        dq_joints: (12,) joint rates [rad/s], mission arm first.
        ee_error: (6,) e₁ = [p_e − p_d [m]; e_o].
        base_error: (6,) e₀ = [r₀ − r₀d [m]; e_o].
        mu: (2,) blend factors (mission, balance).
        cdf: (2,) danger field of each arm at the obstacle (0 without obstacle).
        arm_distance_m: (2,) distance from the obstacle point to each arm's segments [m].
        sigma_min: (2,) smallest singular values of J_m¹ and J_c².
        true_ee_error: (6,) e₁ to the true desired pose (``ee_error`` itself unless the planner
            sees a noisy target estimate).
    """

    dq_joints: Array
    ee_error: Array
    base_error: Array
    mu: Array
    cdf: Array
    arm_distance_m: Array
    sigma_min: Array
    true_ee_error: Array


def reference_targets(robot: Robot, scenario: Scenario, initial_q: Array) -> tuple[DesiredPath, tuple[Array, Array]]:
    """The desired end-effector path and the base set-point of a scenario (docs/model.md §5; base set-point: its initial pose).

    Args:
        robot: the robot model.
        scenario: the scenario (target pose and timing of the path).
        initial_q: the nominal initial configuration (19,); the path starts at its end-effector
            pose and the base set-point is its base pose.

    Returns:
        ``(path, (r0d [m], sigma_bd (4,) wxyz))``.
    """
    ee = robot.transform_ee_to_world(initial_q, 0)
    path = DesiredPath.between(
        ee.translation, from_rotation(ee.rotation), np.array(scenario.target.position_m),
        np.array(scenario.target.quaternion_wxyz),
        motion_time=scenario.desired_path.motion_time_s, accel_time=scenario.desired_path.accel_time_s,
    )
    return path, robot.base_pose(initial_q)


def planner_parameters(scenario: Scenario, method: str, m: float | None, T_c: float | None) -> tuple[float, float]:
    """Validated (m, T_c [s]) of a run: the given values, else the scenario's.

    Raises:
        InvalidInputError: ``method`` not in :data:`METHODS`, m outside (0, 1), T_c not in (0, inf).
    """
    if method not in METHODS:
        raise InvalidInputError(f"method {method!r}; allowed: {list(METHODS)}")
    m = scenario.planner.m if m is None else m
    T_c = scenario.planner.T_c_s if T_c is None else T_c
    ptsf.check_parameters(float(T_c), float(m), scenario.planner.phi_form)
    return float(m), float(T_c)


class Planner:
    """Joint-rate planner for one scenario and method.

    Args:
        robot: the robot model.
        scenario: scenario (target, obstacle and planner settings).
        method: one of :data:`METHODS`.
        m: predefined-time shape parameter, overrides the scenario's.
        T_c: predefined time [s], overrides the scenario's.
        path: the desired end-effector path (:func:`reference_targets`).
        base_target: the base set-point ``(r0d [m], sigma_bd wxyz)`` (:func:`reference_targets`).
        estimates: the paths the planner follows, one per target estimate, each held for
            ``estimate_interval_s`` (:mod:`ffsr_gym.planning.target_estimate`; default: ``(path,)``).
        body: a tumbling target's body in the danger field (:class:`~ffsr_gym.planning.moving_target.BodyField`).
    """

    def __init__(self, robot: Robot, scenario: Scenario, *, method: str = "predefined_time",
                 m: float | None = None, T_c: float | None = None, path: DesiredPath,
                 base_target: tuple[Array, Array], estimates: tuple[DesiredPath, ...] | None = None,
                 estimate_interval_s: float = 0.0, body: BodyField | None = None) -> None:
        self.m, self.T_c = planner_parameters(scenario, method, m, T_c)
        self.robot, self.scenario, self.method = robot, scenario, method
        self.settings = scenario.planner
        self.centroidal_momentum = np.array(scenario.initial.momentum)
        self.path, self.base_target = path, base_target
        self.estimates, self.estimate_interval_s = estimates or (path,), estimate_interval_s
        self.obstacles = obstacle_field(scenario)
        self.body = body

    def set_parameters(self, m: float, T_c: float) -> None:
        """Change the predefined-time parameters m ∈ (0, 1) and T_c [s] > 0 from now on."""
        ptsf.check_parameters(float(T_c), float(m), self.settings.phi_form)
        self.m, self.T_c = float(m), float(T_c)

    def feedback(self, error: Array) -> Array:
        """The pose feedback φ(e) of this method (6,) [error units per s]."""
        if self.method == "no_feedback":
            return np.zeros(6)
        if self.method == "proportional":
            return self.settings.proportional_gain_per_s * error
        form = self.settings.phi_form
        if self.settings.phi_split:
            return np.concatenate([ptsf.phi(part, self.T_c, self.m, form=form) for part in (error[:3], error[3:])])
        return ptsf.phi(error, self.T_c, self.m, form=form)

    def _avoidance(self, arm: int, t: float) -> tuple[float, Array, float, float]:
        """μ, Θ̇_c [rad/s], CDF and distance [m] for ``arm`` at time ``t`` [s] (R16-R18).

        With several obstacles the CDF and its gradient are sums over them and the distance is
        the smallest (docs/model.md §10).
        """
        body = self.body
        if not len(self.obstacles) and body is None:
            return 1.0, np.zeros(6), 0.0, np.inf
        points, axes = self.robot.joint_points(arm)
        s = self.settings
        positions = self.obstacles.at(t)
        cdf, distance = 0.0, math.inf
        for p_o in positions:
            part, nearest = danger_field(points, p_o, s.cdf_k1)
            cdf, distance = cdf + part, min(distance, nearest)
        ratio = distance / self.scenario.obstacle.danger_radius_m if len(positions) else math.inf
        if body is not None:  # the tumbling body: every segment but the tool's, seen from its bounding sphere (§22)
            part, nearest = danger_field(points[:6], body.centre(t), s.cdf_k1)
            cdf, ratio = cdf + part, min(ratio, (nearest - body.bounding_radius_m) / body.danger_radius_m)
        mu = blend_factor(cdf, ratio, law=s.mu_law, delta=s.cdf_delta, danger_radius=1.0)
        if self.method == "no_avoidance" or (arm == 1 and not s.balance_avoids):
            mu = 1.0
        if mu >= 1.0:
            return 1.0, np.zeros(6), cdf, distance
        gradient = sum((danger_field_gradient(points, axes, p_o, s.cdf_k1) for p_o in positions), np.zeros(6))
        if body is not None:
            gradient = gradient + danger_field_gradient(points[:6], axes, body.centre(t), s.cdf_k1)
        return mu, -s.cdf_xi * gradient, cdf, distance

    def __call__(self, t: float, q: Array) -> PlanStep:
        """Joint rates at time ``t`` [s] and configuration ``q`` (docs/model.md §8 steps 1-8)."""
        robot, s = self.robot, self.settings
        robot.update_kinematics(q)
        mats = robot.momentum_matrices(q)
        r0, sigma_b = robot.base_pose(q)
        e0, J_b, _ = pose_error(r0, sigma_b, *self.base_target, s.attitude_error)
        V0_cmd = -np.linalg.solve(J_b, self.feedback(e0))

        ee = robot.data.oMf[int(robot.ee_frame_ids[0])]
        pose = ee.translation, from_rotation(ee.rotation)
        seen = self.estimates[estimate_index(t, self.estimate_interval_s, len(self.estimates))]
        p_d, sigma_d, V_ed = seen.at(t)
        e1, J_e, J_ed = pose_error(*pose, p_d, sigma_d, s.attitude_error)
        true_e1 = e1 if len(self.estimates) == 1 else pose_error(*pose, *self.path.at(t)[:2], s.attitude_error)[0]
        J_0 = np.eye(6)
        J_0[:3, 3:] = -skew(ee.translation - r0)
        x1 = np.linalg.solve(J_e, J_ed @ V_ed - self.feedback(e1)) - J_0 @ V0_cmd

        mu1, dq_c1, cdf1, d1 = self._avoidance(0, t)
        J_sharp, P, smin1 = filtered_inverse(robot.arm_jacobian(0), lambda_max=s.lambda_max_mission, epsilon=s.epsilon_mission)
        dq1 = mu1 * J_sharp @ x1 + (dq_c1 - mu1 * P @ dq_c1)

        C = robot.momentum_about_base(q, self.centroidal_momentum)
        x2 = mats.H_bm[0] @ dq1 + mats.H_b @ V0_cmd - C
        mu2, dq_c2, cdf2, d2 = self._avoidance(1, t)
        J_sharp, P, smin2 = filtered_inverse(-mats.H_bm[1], lambda_max=s.lambda_max_balance, epsilon=s.epsilon_balance)
        dq2 = mu2 * J_sharp @ x2 + (dq_c2 - mu2 * P @ dq_c2)
        return PlanStep(np.concatenate((dq1, dq2)), e1, e0, np.array([mu1, mu2]), np.array([cdf1, cdf2]),
                        np.array([d1, d2]), np.array([smin1, smin2]), true_e1)
