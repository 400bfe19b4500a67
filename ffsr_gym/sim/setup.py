"""What a closed loop needs from a robot and a scenario, built once and shared by both backends.

A :class:`RobotAssets` (Pinocchio model, collision model, kernel arrays, native robot) is built once per robot
and process; a :class:`ScenarioSetup` (initial configuration, obstacles, desired path, base
set-point) once per scenario. The Pinocchio rollout, the kernel rollout, the task generator and
the report all take them from here instead of rebuilding them.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np

from ffsr_gym import _native
from ffsr_gym.exceptions import ScenarioError
from ffsr_gym.kernel.arrays import KernelModel, extract
from ffsr_gym.kernel.robot import native_plant, native_robot
from ffsr_gym.model.collision import BoxObstacle, CollisionModel, Obstacle
from ffsr_gym.model.drives import drive_array, drives_path, load_drives
from ffsr_gym.model.obstacles import ObstacleField, obstacle_field
from ffsr_gym.model.quaternion import to_rotation
from ffsr_gym.model.resources import is_shipped_robot, robot_dir, robot_files
from ffsr_gym.model.robot import Robot, files_stamp, load_robot
from ffsr_gym.model.robot_check import check_robot_folder
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.model.scenario_sections import TumblingTarget
from ffsr_gym.model.tumbling import TargetMotion
from ffsr_gym.planning.desired_path import DesiredPath
from ffsr_gym.planning.moving_target import (
    BodyField,
    GraspFrameMotion,
    MovingTargetPath,
    approach_frame,
    grasp_motion,
)
from ffsr_gym.planning.planner import reference_targets
from ffsr_gym.planning.target_estimate import estimated_paths
from ffsr_gym.planning.timed_approach import TimedPath, TimingState, approach_limits
from ffsr_gym.types import Array


class RobotAssets:
    """One robot's models, shared by every rollout of this process (see :func:`robot_assets`).

    Attributes:
        robot: the Pinocchio model (its ``data`` is scratch space, overwritten by every call).
        collision: the collision model (placed per query, so also scratch space).
    """

    def __init__(self, name: str) -> None:
        self.name = name
        check_robot_folder(name)
        self.robot: Robot = load_robot(name)
        self.collision = CollisionModel(self.robot)

    @cached_property
    def kernel(self) -> KernelModel:
        """The kernel's arrays, extracted on first use."""
        return extract(self.robot, self.collision)

    def __reduce__(self) -> tuple:
        """Pickle as the robot's name: the process's shared assets of that robot on load."""
        return (robot_assets, (self.name,))

    @cached_property
    def native(self) -> _native.Robot:
        """The native kernel's typed robot (:func:`~ffsr_gym.kernel.robot.native_robot`), built on first use."""
        return native_robot(self.kernel)


def robot_assets(name: str) -> RobotAssets:
    """The shared :class:`RobotAssets` of a robot, shipped or a folder's (cached per process and files' version).

    Raises:
        RobotFileError: the robot's files are missing or fail :func:`~ffsr_gym.model.robot_check.check_robot`.
    """
    urdf = robot_files(name)[0]
    return _assets(name, files_stamp(urdf.parent))


@lru_cache(maxsize=8)
def _assets(name: str, stamp: tuple) -> RobotAssets:
    return RobotAssets(name)


def initial_configuration(robot: Robot, scenario: Scenario) -> Array:
    """Pinocchio configuration ``q`` (19,) of the scenario's initial state."""
    initial = scenario.initial
    return robot.configuration(
        base_position_m=np.array(initial.base_position_m),
        base_quaternion_wxyz=np.array(initial.base_quaternion_wxyz),
        joints_rad=np.radians(np.array(initial.mission_joints_deg + initial.balance_joints_deg)),
    )


@dataclass(frozen=True)
class ScenarioSetup:
    """A scenario with everything derived from it that both backends use.

    Attributes:
        scenario: the scenario.
        assets: its robot's shared models.
        q0: the nominal initial configuration (19,), Pinocchio order.
        obstacles: the obstacles (``[obstacle]`` and ``[debris]``), positions at any time.
        plant: the robot the physics integrates (``[plant]``; the nominal robot without it).
        plant_arrays: the plant's (mass, lever, inertia, drive) kernel arrays (the nominal inertials
            without ``[plant]``; ``drive`` (12, 4) the servo plant's drives, zeros for the kinematic plant).
        native_plant: the native robot the physics integrates when it is not the planner's own (``[plant]``, or
            the servo plant's drives); None when it is.
        path: the desired end-effector path (to the true target).
        estimates: the planner's desired paths, one per target estimate (``(path,)`` without
            ``[target_noise]``; :mod:`ffsr_gym.planning.target_estimate`).
        estimate_interval_s: how long each estimate holds [s] (0 without ``[target_noise]``).
        base_target: the base set-point ``(r0d [m], sigma_bd (4,) wxyz)``.
        target_motion: the tumbling target's body at every step (``[tumbling_target]``; None without one).
        grasp: its grasp frame at every step (what capture is judged against; None without one).
        body_field: the body in the danger field (None without one, or with its ``danger_radius_m`` 0).
    """

    scenario: Scenario
    assets: RobotAssets
    q0: Array
    obstacles: ObstacleField
    plant: Robot
    plant_arrays: tuple
    native_plant: _native.Robot | None
    path: DesiredPath | MovingTargetPath | TimedPath
    estimates: tuple[DesiredPath | MovingTargetPath | TimedPath, ...]
    estimate_interval_s: float
    base_target: tuple[Array, Array]
    target_motion: TargetMotion | None = None
    grasp: GraspFrameMotion | None = None
    body_field: BodyField | None = None

    @property
    def robot(self) -> Robot:
        """The scenario's robot model."""
        return self.assets.robot

    def __reduce__(self) -> tuple:
        """Pickle as the scenario: :func:`prepare` builds the same setup (or finds it cached) on load."""
        return (prepare, (self.scenario,))

    def obstacles_at(self, k: int) -> tuple[Obstacle, ...]:
        """Every obstacle where it is at step ``k``: the scenario's spheres and, with ``[tumbling_target]``, its
        body as a box."""
        spheres, motion = self.obstacles.spheres(k * self.scenario.simulation.dt_s), self.target_motion
        if motion is None:
            return spheres
        k = min(k, len(motion.position_m) - 1)
        return (*spheres, BoxObstacle(motion.position_m[k], np.array(self.scenario.tumbling_target.size_m),
                                      to_rotation(motion.quaternion[k]), name="target body"))


def prepare(scenario: Scenario) -> ScenarioSetup:
    """The :class:`ScenarioSetup` of a scenario (cached per process; scenarios are frozen, and a robot folder of
    one's own is keyed by its files' version too, so an edited robot is never simulated from a stale cache)."""
    stamp = () if is_shipped_robot(scenario.robot) else files_stamp(robot_dir(scenario.robot))
    return _prepare(scenario, stamp)


def _drive(scenario: Scenario) -> Array:
    """The kernel's drive array of the scenario's plant (zeros for the kinematic plant)."""
    if scenario.simulation.plant != "servo":
        return np.zeros((12, 4))
    settings = scenario.servo_settings
    drives = load_drives(drives_path(robot_dir(scenario.robot)))
    return drive_array(drives, gain_scale=settings.gain_scale, torque_limited=settings.torque_limited)


@lru_cache(maxsize=256)  # a training and a validation pool (200 + 50 tasks; a capture task's setup is about 1 MB at dt)
def _prepare(scenario: Scenario, stamp: tuple) -> ScenarioSetup:
    assets = robot_assets(scenario.robot)
    q0 = initial_configuration(assets.robot, scenario)
    q0.flags.writeable = False  # shared by every rollout of this scenario
    path, base_target = reference_targets(assets.robot, scenario, q0)
    target, grasp, field = None, None, None
    body = scenario.tumbling_target
    if body is not None:  # the approach onto its moving grasp frame (docs/model.md §22)
        target = compiled_body_motion(body, dt_s=scenario.simulation.dt_s, steps=scenario.n_steps)
        grasp = grasp_motion(body, target)
        if scenario.commanded_approach is not None:  # the method's timing (docs/model.md §23)
            approach = scenario.commanded_approach
            path = TimedPath(grasp, path.start_position, path.start_attitude,
                             approach_limits(approach, body.standoff_m), TimingState(approach.command),
                             approach.approach_time_s, approach.approach_ramp_s)
        else:
            path = MovingTargetPath.onto(path.start_position, path.start_attitude,
                                         approach_frame(body, grasp, path.motion_time), motion_time=path.motion_time,
                                         accel_time=path.accel_time)
        field = BodyField.of(body, target, scenario.simulation.dt_s)
    plant, kernel = assets.robot, assets.kernel
    if scenario.plant is not None:
        changes = scenario.plant
        plant = assets.robot.with_inertial_changes(changes.mass_scale, changes.inertia_scale,
                                                   changes.com_offset_m or np.zeros((12, 3)))
        kernel = extract(plant, assets.collision)
    plant_arrays = (kernel.mass, kernel.lever, kernel.inertia, _drive(scenario))
    own = scenario.plant is None and scenario.simulation.plant != "servo"
    setup = ScenarioSetup(scenario=scenario, assets=assets, q0=q0, obstacles=obstacle_field(scenario), plant=plant,
                          plant_arrays=plant_arrays, native_plant=None if own else native_plant(kernel, plant_arrays),
                          path=path, estimates=estimated_paths(scenario, path),
                          estimate_interval_s=0.0 if scenario.target_noise is None else scenario.target_noise.interval_s,
                          base_target=base_target, target_motion=target, grasp=grasp, body_field=field)
    return setup


def check_start(setup: ScenarioSetup) -> None:
    """Refuse a scenario whose start state already breaks the rules an episode is judged by (``_violation`` in the
    kernel's loop): two of the robot's parts overlapping (self clearance below 0), or an obstacle (a tumbling
    target's body included) closer than the keep-out distance at t = 0. A randomised family's own obstacle is a
    placeholder that every draw replaces, so only its robot is checked. The environments call it before they play a
    scenario; ``simulate`` does not (the paper reproduction runs the paper's printed obstacle, inside the base, to
    show that it is).

    Raises:
        ScenarioError: naming the two bodies, the clearance [mm] and what is allowed.
    """
    scenario, collision, q0 = setup.scenario, setup.assets.collision, setup.q0
    where = f"scenario {scenario.name!r} with robot {scenario.robot!r}"
    own = collision.self_proximity(q0)
    if own.distance_m < 0.0:
        raise ScenarioError(f"{where}: at the start pose {own.pair[0]!r} and {own.pair[1]!r} overlap (clearance "
                            f"{own.distance_m * 1e3:.1f} mm); allowed: a start whose parts are apart (clearance >= 0), "
                            "else the episode fails at its first step (the robot's collision radii, or its start "
                            "joint angles)")
    if scenario.randomization is not None:
        return
    keep_out, obstacles = scenario.objective.keep_out_m, setup.obstacles_at(0)
    near = collision.obstacle_proximity(q0, obstacles) if obstacles else None
    if near is not None and near.distance_m < keep_out:
        raise ScenarioError(f"{where}: at t = 0 {near.pair[1]!r} is {near.distance_m * 1e3:.1f} mm from {near.pair[0]!r}; "
                            f"allowed: at least the keep-out distance, {keep_out * 1e3:g} mm, else the episode "
                            "fails at its first step (move the obstacle or the robot's start)")


def compiled_body_motion(body: TumblingTarget, *, dt_s: float, steps: int) -> TargetMotion:
    """The motion of a ``[tumbling_target]``'s body at every step of ``dt_s`` [s] over ``steps`` steps:
    :func:`ffsr_gym.model.tumbling.propagate` on the native integrator (the same RK4, agreeing to 1e-13;
    ``tests/library/model/test_tumbling.py``), so a 20 s episode at dt / 4 costs milliseconds instead of seconds."""
    quats, omegas = _native.propagate_tumbling(np.array(body.quaternion_wxyz, dtype=float),
                                               np.deg2rad(np.array(body.omega_body_deg_s, dtype=float)),
                                               np.array(body.inertia_kg_m2, dtype=float), dt_s, 4, steps)
    return TargetMotion.drifting(body.position_m, body.velocity_m_s, dt_s, quats, omegas)
