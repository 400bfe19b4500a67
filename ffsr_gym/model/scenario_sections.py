"""The sections of a scenario file, one frozen dataclass each (:class:`ffsr_gym.model.scenario.Scenario` holds
them). Each field's metadata gives its key's type and range, which the loader checks, naming the key, the value
and what is allowed (:class:`~ffsr_gym.exceptions.ScenarioError`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ffsr_gym.model.schema import (
    BOOL,
    MAX_DRAW_ATTEMPTS,
    Vec,
    choice,
    count,
    interval,
    natural,
    number,
    rows,
    vector,
)
from ffsr_gym.model.tumbling import grasp_pose


@dataclass(frozen=True)
class Simulation:
    """Time settings and plant. ``duration_s`` [s] is the episode length, ``dt_s`` [s] the planner step.

    ``plant``: ``"kinematic"`` (the default: the joints move exactly at the planned rates, the base by
    momentum conservation) or ``"servo"`` (the planned rates command torque-limited joint servos
    driving the free-floating multibody dynamics; section ``[servo]``, docs/model.md "Dynamics").
    """

    duration_s: float = field(metadata=number(0.0, 3600.0, lo_open=True))
    dt_s: float = field(metadata=number(1e-5, 0.1))
    plant: str = field(default="kinematic", metadata=choice("kinematic", "servo"))


@dataclass(frozen=True)
class ServoSettings:
    """The servo plant (beyond the paper; docs/model.md "Dynamics"); used with ``simulation.plant = "servo"``.

    The drives are the robot's ``drives/servo.toml``. ``physics_step_s`` [s]: the longest physics
    step; the plant takes ``dt_s / n`` with the smallest whole n that is no longer (so a planner
    step of another length, ``Scenario.at_step``, keeps a whole number of them); ``gain_scale``
    multiplies every servo gain;
    ``torque_limited = false`` lifts the torque limits (a study of the kinematic limit).
    """

    physics_step_s: float = field(default=0.001, metadata=number(1e-6, 0.1))
    gain_scale: float = field(default=1.0, metadata=number(0.0, 1e6, lo_open=True))
    torque_limited: bool = field(default=True, metadata=BOOL)


@dataclass(frozen=True)
class InitialState:
    """Initial base pose [m, wxyz], joint angles [deg] and centroidal momentum.

    ``momentum`` is ``[P; L_G]``: linear momentum [kg m/s] and angular momentum about the
    system centre of mass [kg m^2/s], both in the inertial frame. The paper sets it to zero.
    """

    base_position_m: Vec = field(metadata=vector(3, -100.0, 100.0))
    base_quaternion_wxyz: Vec = field(metadata=vector(4, -1.01, 1.01))
    mission_joints_deg: Vec = field(metadata=vector(6, -360.0, 360.0))
    balance_joints_deg: Vec = field(metadata=vector(6, -360.0, 360.0))
    momentum: Vec = field(default=(0.0,) * 6, metadata=vector(6, -1e3, 1e3))


@dataclass(frozen=True)
class Target:
    """Target end-effector pose: position [m] and scalar-first attitude (normalised on load)."""

    position_m: Vec = field(metadata=vector(3, -100.0, 100.0))
    quaternion_wxyz: Vec = field(metadata=vector(4, -1.01, 1.01))


@dataclass(frozen=True)
class ReferencePath:
    """The desired end-effector path (file section ``[trajectory]``): trapezoidal velocity, motion time t_f [s],
    acceleration time t_a [s] (docs/model.md)."""

    motion_time_s: float = field(metadata=number(0.0, 3600.0, lo_open=True))
    accel_time_s: float = field(metadata=number(0.0, 1800.0, lo_open=True))


@dataclass(frozen=True)
class Obstacle:
    """A point obstacle: position [m], physical radius [m] (0 = a point) and danger radius [m]."""

    position_m: Vec = field(metadata=vector(3, -100.0, 100.0))
    radius_m: float = field(default=0.0, metadata=number(0.0, 2.0))
    danger_radius_m: float = field(default=0.2, metadata=number(0.0, 5.0, lo_open=True))


#: Most obstacles besides ``[obstacle]`` a scenario may list in ``[debris]`` (the kernel's fixed slots).
MAX_DEBRIS = 7


@dataclass(frozen=True)
class Debris:
    """Further obstacles, and straight-line drift of every obstacle (beyond the paper; docs/model.md §14).

    An obstacle at ``p`` drifting at ``v`` is at ``p + v t`` at time t [s]. ``obstacle_velocity_m_s``
    is the drift of ``[obstacle]``; ``positions_m``, ``radii_m`` and ``velocities_m_s`` list up to
    :data:`MAX_DEBRIS` further obstacles (one row each, equally long lists). They share
    ``[obstacle]``'s danger radius. The danger field is the sum over all obstacles (the CDF is
    cumulative), the μ distance the smallest, and clearance is taken to the nearest one.
    """

    obstacle_velocity_m_s: Vec = field(default=(0.0,) * 3, metadata=vector(3, -1.0, 1.0))
    positions_m: tuple[Vec, ...] = field(default=(), metadata=rows(3, -100.0, 100.0, MAX_DEBRIS))
    radii_m: Vec = field(default=(), metadata=rows(0, 0.0, 2.0, MAX_DEBRIS))
    velocities_m_s: tuple[Vec, ...] = field(default=(), metadata=rows(3, -1.0, 1.0, MAX_DEBRIS))


@dataclass(frozen=True)
class Plant:
    """The robot the physics integrates, where it differs from the planner's model (docs/model.md §15).

    Bodies in kernel order: 0 the base, 1-6 the mission links, 7-12 the balance links. Each
    body's mass and its rotational inertia about its centre of mass are multiplied by the
    factors; each link's centre of mass moves by ``com_offset_m`` in its joint frame (12 rows, or
    none: the base's frame is its centre of mass and stays so). The planner keeps the nominal
    model (the robot's URDF); momentum is conserved for the plant's parameters.
    """

    mass_scale: Vec = field(default=(1.0,) * 13, metadata=vector(13, 0.5, 2.0))
    inertia_scale: Vec = field(default=(1.0,) * 13, metadata=vector(13, 0.5, 2.0))
    com_offset_m: tuple[Vec, ...] = field(default=(), metadata=rows(3, -0.1, 0.1, 12))


@dataclass(frozen=True)
class TargetNoise:
    """What the planner sees of the target pose (beyond the paper; docs/model.md §16).

    The planner's estimate is held over each ``interval_s`` (row k for t in [k, k + 1) · interval):
    position p_t + b_p + σ_p n_k, attitude exp(b_θ + σ_θ n'_k) ⊗ σ_t (a rotation vector in the
    world frame), with n_k, n'_k standard normal 3-vectors drawn once per task from
    ``numpy.random.default_rng(seed)``. The planner's desired path runs from the start pose to the
    current estimate; the logged end-effector errors and the success test use the true target.
    """

    position_bias_m: Vec = field(default=(0.0,) * 3, metadata=vector(3, -0.01, 0.01))
    attitude_bias_rad: Vec = field(default=(0.0,) * 3, metadata=vector(3, -0.01, 0.01))
    position_sigma_m: float = field(default=0.0, metadata=number(0.0, 0.01))
    attitude_sigma_rad: float = field(default=0.0, metadata=number(0.0, 0.01))
    interval_s: float = field(default=0.1, metadata=number(0.001, 100.0))
    seed: int = field(default=0, metadata=natural(2**63 - 1))


@dataclass(frozen=True)
class PlannerSettings:
    """Planner parameters (docs/model.md §3-8). Symbols follow the paper; see docs/model.md."""

    m: float = field(metadata=number(0.0, 1.0, lo_open=True, hi_open=True))
    T_c_s: float = field(metadata=number(0.0, 1000.0, lo_open=True))
    phi_form: str = field(default="sanchez_torres", metadata=choice("sanchez_torres", "printed"))
    phi_split: bool = field(default=False, metadata=BOOL)
    attitude_error: str = field(default="world", metadata=choice("world", "body"))
    lambda_max_mission: float = field(default=0.08, metadata=number(0.0, 10.0))
    lambda_max_balance: float = field(default=0.08, metadata=number(0.0, 10.0))
    epsilon_mission: float = field(default=0.02, metadata=number(0.0, 10.0))
    epsilon_balance: float = field(default=0.02, metadata=number(0.0, 10.0))
    proportional_gain_per_s: float = field(default=1.0, metadata=number(0.0, 1e3, lo_open=True))
    cdf_xi: float = field(default=0.1, metadata=number(0.0, 1e3))
    cdf_delta: float = field(default=17.25, metadata=number(0.0, 1e6, lo_open=True))
    cdf_k1: float = field(default=1.0, metadata=number(0.0, 1e3, lo_open=True))
    mu_law: str = field(default="cdf", metadata=choice("cdf", "distance"))
    balance_avoids: bool = field(default=True, metadata=BOOL)


@dataclass(frozen=True)
class ObjectiveSettings:
    """The benchmark objective B (paper eqs. 21-22; docs/model.md §13) and the feasibility tolerances.

    Rates are compared in deg/s. ``rate_limit_scope``: ``"both_arms"`` (default) or the literal
    eq. (22) reading ``"balance_arm"``. ``keep_out_m``: a robot–obstacle clearance below it is a
    collision (0, the default: contact; benchmark v2 sets it). Arm-arm and arm-base contact stays
    the collision test of the robot's own parts.
    """

    alpha: float = field(default=0.35, metadata=number(0.0, 1e6))
    beta: float = field(default=0.65, metadata=number(0.0, 1e6))
    gamma: float = field(default=1e-4, metadata=number(0.0, 1e6))
    danger_rate_deg_s: float = field(default=150.0, metadata=number(0.0, 1e5))
    max_rate_deg_s: float = field(default=200.0, metadata=number(0.0, 1e5, lo_open=True))
    rate_limit_scope: str = field(default="both_arms", metadata=choice("both_arms", "balance_arm"))
    ee_position_tolerance_m: float = field(default=1e-6, metadata=number(0.0, 10.0, lo_open=True))
    ee_attitude_tolerance: float = field(default=1e-6, metadata=number(0.0, 1.0, lo_open=True))
    keep_out_m: float = field(default=0.0, metadata=number(0.0, 1.0))


@dataclass(frozen=True)
class EnvSettings:
    """Settings of the Gymnasium environments (bounds of the action mapping, decision interval)."""

    m_bounds: Vec = field(default=(0.05, 0.95), metadata=vector(2, 0.0, 1.0))
    T_c_bounds_s: Vec = field(default=(0.5, 10.0), metadata=vector(2, 1e-3, 1000.0))
    decision_interval_s: float = field(default=0.1, metadata=number(0.0, 3600.0, lo_open=True))
    residual_rate_deg_s: float = field(default=20.0, metadata=number(0.0, 1e4))
    violation_penalty: float = field(default=1.0, metadata=number(0.0, 1e9))
    tolerance_penalty: float = field(default=1.0, metadata=number(0.0, 1e9))


@dataclass(frozen=True)
class Randomization:
    """Ranges of the randomised scenario family (used by ``scenario="random"``).

    The target is the forward kinematics of the initial mission-arm angles plus offsets drawn
    uniformly in ``±mission_joint_offsets_deg``; it is kept when the end-effector travels at least
    ``min_travel_m`` and the target configuration has ``σ_min(J_m) >= min_sigma_target``. The
    obstacle is put on the desired straight path at a fraction drawn in ``path_fraction`` plus a
    lateral offset up to ``lateral_offset_m``; it is kept when both arms start at least the danger
    radius away and the target configuration clears it by ``min_final_distance_m``.
    """

    mission_joint_offsets_deg: Vec = field(metadata=vector(6, 0.0, 180.0))
    min_travel_m: float = field(default=0.2, metadata=number(0.0, 10.0))
    min_sigma_target: float = field(default=0.05, metadata=number(0.0, 10.0))
    path_fraction: Vec = field(default=(0.4, 0.7), metadata=interval(0.0, 1.0))
    lateral_offset_m: float = field(default=0.02, metadata=number(0.0, 1.0))
    min_final_distance_m: float = field(default=0.1, metadata=number(0.0, 10.0))
    min_self_clearance_m: float = field(default=0.02, metadata=number(0.0, 10.0))
    max_attempts: float = field(default=1000, metadata=count(1, MAX_DRAW_ATTEMPTS))


@dataclass(frozen=True)
class TumblingTarget:
    """A target body that drifts and tumbles, and the grasp frame on it (beyond the paper; docs/model.md §22).

    The body is a box of edges ``size_m`` [m] with its centre of mass at its centre, ``mass_kg`` [kg] and principal
    moments ``inertia_kg_m2`` [kg m²] about its body axes. At t = 0 its centre is at ``position_m`` [m] with attitude
    ``quaternion_wxyz`` (body → world); it drifts at ``velocity_m_s`` [m/s] and turns at ``omega_body_deg_s``
    [deg/s] (body frame), with no torque (:mod:`ffsr_gym.model.tumbling`). The grasp frame (the handle) is fixed on
    the body at ``handle_position_m`` [m] with attitude ``handle_quaternion_wxyz``, both in the body frame, outside
    the box. The scenario's ``[target]`` is the grasp frame at t = 0 (checked on load).

    How the planner comes in (docs/model.md §22): with ``standoff_m`` > 0 [m] it approaches a pre-grasp frame, the
    grasp frame backed off along its z axis (the tool's approach axis) by a distance that closes to 0 over
    ``insertion_time_s`` [s] from the end of the desired motion on (``trajectory.motion_time_s``), so the tool comes
    in along the grasp axis. With ``danger_radius_m`` > 0 [m] the body's centre is in every arm's danger field but
    the tool segment's, and the avoidance blend sees the arm's distance to the body's bounding sphere over it.
    """

    size_m: Vec = field(metadata=vector(3, 0.05, 5.0))
    mass_kg: float = field(metadata=number(1.0, 1e5))
    inertia_kg_m2: Vec = field(metadata=vector(3, 1e-3, 1e6))
    position_m: Vec = field(metadata=vector(3, -100.0, 100.0))
    quaternion_wxyz: Vec = field(metadata=vector(4, -1.01, 1.01))
    handle_position_m: Vec = field(metadata=vector(3, -5.0, 5.0))
    handle_quaternion_wxyz: Vec = field(default=(1.0, 0.0, 0.0, 0.0), metadata=vector(4, -1.01, 1.01))
    velocity_m_s: Vec = field(default=(0.0,) * 3, metadata=vector(3, -1.0, 1.0))
    omega_body_deg_s: Vec = field(default=(0.0,) * 3, metadata=vector(3, -90.0, 90.0))
    standoff_m: float = field(default=0.0, metadata=number(0.0, 1.0))
    insertion_time_s: float = field(default=4.0, metadata=number(0.5, 60.0))
    danger_radius_m: float = field(default=0.0, metadata=number(0.0, 1.0))


@dataclass(frozen=True)
class CommandedApproach:
    """A commanded approach onto a ``[tumbling_target]``'s grasp frame (beyond the paper; docs/model.md §23): the
    method decides when the end-effector closes in on the pre-grasp frame (the grasp frame backed off along its z
    axis by the target's ``standoff_m``) and when the tool goes in, through one command u in [0, 2]
    (:mod:`ffsr_gym.planning.timed_approach`): 0 holds the start pose, 1 the pre-grasp frame, 2 the grasp frame.

    The approach's progress runs from 0 to 1 in ``approach_time_s`` [s] at its top speed and reaches that speed
    from rest in ``approach_ramp_s`` [s]; the insertion's likewise with ``insertion_time_s`` and
    ``insertion_ramp_s``. ``command`` is the command until a method gives one. The scripted schedule
    (``trajectory.motion_time_s`` and ``tumbling_target.insertion_time_s``) is not used.
    """

    approach_time_s: float = field(metadata=number(0.5, 600.0))
    approach_ramp_s: float = field(metadata=number(0.01, 600.0))
    insertion_time_s: float = field(metadata=number(0.1, 600.0))
    insertion_ramp_s: float = field(metadata=number(0.01, 600.0))
    command: float = field(default=2.0, metadata=number(0.0, 2.0))


def tumbling_scenario_problems(body: TumblingTarget | None, approach: CommandedApproach | None, target: Target,
                               has_noise: bool, motion_time_s: float, duration_s: float) -> list[str]:
    """What makes a scenario's ``[tumbling_target]`` and ``[commanded_approach]`` impossible, key by key (empty when
    nothing): :func:`tumbling_problems`, a noisy target with it, a scripted insertion that ends after the episode,
    a commanded approach without a tumbling target."""
    if body is None:
        return ([] if approach is None else
                ["section 'commanded_approach' without 'tumbling_target'; allowed: a commanded approach onto a "
                 "tumbling target's grasp frame (add [tumbling_target], or remove [commanded_approach])"])
    problems = tumbling_problems(body, target)
    if has_noise:
        problems.append("sections 'tumbling_target' and 'target_noise' together: not supported yet (the noisy "
                        "estimate is of a still target)")
    end = motion_time_s + body.insertion_time_s
    if approach is None and body.standoff_m > 0.0 and end > duration_s + 1e-9:
        problems.append(f"key 'tumbling_target.insertion_time_s' = {body.insertion_time_s!r}: the insertion ends at "
                        f"t = {end:g} s, after the episode ({duration_s:g} s); allowed: at most "
                        f"{duration_s - motion_time_s:g} s (duration_s - motion_time_s)")
    return problems


def tumbling_problems(body: TumblingTarget, target: Target) -> list[str]:
    """What makes a ``[tumbling_target]`` section impossible, key by key (empty when nothing): moments no body has
    (beyond the triangle inequality, or beyond what its mass can have inside its box), a handle inside the box, a ``[target]`` that is not the grasp frame at t = 0 (its quaternions' norms are checked
    with the scenario's others)."""
    problems = []
    i1, i2, i3 = body.inertia_kg_m2
    for k, (moment, others) in enumerate(((i1, i2 + i3), (i2, i1 + i3), (i3, i1 + i2))):
        if moment > others * (1.0 + 1e-12):
            problems.append(f"key 'tumbling_target.inertia_kg_m2' = {list(body.inertia_kg_m2)}: moment {k + 1} exceeds "
                            "the sum of the other two; allowed: principal moments of a real body (each at most the "
                            "sum of the others)")
    a, b, c = body.size_m
    for k, (moment, (u, v)) in enumerate(zip(body.inertia_kg_m2, ((b, c), (a, c), (a, b)))):
        most = body.mass_kg * (u * u + v * v) / 4.0  # all the mass in the corners of the box
        if moment > most * (1.0 + 1e-12):
            problems.append(f"key 'tumbling_target.inertia_kg_m2' = {list(body.inertia_kg_m2)}: moment {k + 1} exceeds "
                            f"{most:.6g} kg m², the most {body.mass_kg:g} kg inside a box of edges {list(body.size_m)} m "
                            "can have about its centre (all of it in the corners); allowed: at most that (a uniform box "
                            "has a third of it)")
    if all(abs(h) <= e / 2.0 for h, e in zip(body.handle_position_m, body.size_m)):
        problems.append(f"key 'tumbling_target.handle_position_m' = {list(body.handle_position_m)} lies inside the "
                        f"body (edges {list(body.size_m)} m, centred on the body frame); allowed: a point outside it")
    if not problems:
        problems += _grasp_target_problems(body, target)
    return problems


def _grasp_target_problems(body: TumblingTarget, target: Target) -> list[str]:
    position, attitude = grasp_pose(body.position_m, body.quaternion_wxyz, body.handle_position_m,
                                    body.handle_quaternion_wxyz)
    wanted = np.array(target.quaternion_wxyz) / np.linalg.norm(target.quaternion_wxyz)
    off = max(np.abs(position - np.array(target.position_m)).max(),
              min(np.abs(attitude - wanted).max(), np.abs(attitude + wanted).max()))
    if off <= 1e-6:
        return []
    return [f"section 'target' ({list(target.position_m)}, {list(target.quaternion_wxyz)}) is not the grasp frame of "
            f"'tumbling_target' at t = 0 ({[round(float(x), 9) for x in position]}, "
            f"{[round(float(x), 9) for x in attitude]}); allowed: that pose, within 1e-6"]
