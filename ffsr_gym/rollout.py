"""The closed loop: ``simulate`` runs a planner on the robot for one scenario."""

from __future__ import annotations

import dataclasses

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.collision import CollisionModel, SphereObstacle
from ffsr_gym.exceptions import FFSRError
from ffsr_gym.planner import Planner
from ffsr_gym.robot import Robot, check_state, load_robot
from ffsr_gym.scenario import Scenario, load_scenario
from ffsr_gym.trajectory import Trajectory
from ffsr_gym.types import Array


def initial_configuration(robot: Robot, scenario: Scenario) -> Array:
    """Pinocchio configuration ``q`` of the scenario's initial state."""
    initial = scenario.initial
    return robot.configuration(
        base_position_m=np.array(initial.base_position_m),
        base_quaternion_wxyz=np.array(initial.base_quaternion_wxyz),
        joints_rad=np.radians(np.array(initial.mission_joints_deg + initial.balance_joints_deg)),
    )


def obstacles_of(scenario: Scenario) -> list[SphereObstacle]:
    """The scenario's obstacle as a collision sphere (empty list in free space)."""
    if scenario.obstacle is None:
        return []
    return [SphereObstacle(np.array(scenario.obstacle.position_m), scenario.obstacle.radius_m)]


def simulate(scenario: Scenario | str, *, method: str = "predefined_time", m: float | None = None,
             T_c: float | None = None, dt: float | None = None, q0: Array | None = None,
             progress: bool = False) -> Trajectory:
    """Run the closed loop planner → robot for one scenario (the project's only closed loop).

    Args:
        scenario: a :class:`Scenario` or a scenario name/path.
        method: planning method, one of :data:`ffsr_gym.planner.METHODS`.
        m: predefined-time shape parameter in (0, 1); default: the scenario's.
        T_c: predefined time [s]; default: the scenario's.
        dt: time step [s]; default: the scenario's ``simulation.dt_s``.
        q0: start from this configuration (19,) instead of the scenario's initial state. The
            desired path and the base set-point still come from the scenario's initial state, so
            this is how an initial pose error is imposed.
        progress: show a progress bar.

    Returns:
        The :class:`Trajectory`, sampled at every step.
    """
    scenario = load_scenario(scenario)
    if dt is not None:
        scenario = scenario.replace(simulation=dataclasses.replace(scenario.simulation, dt_s=float(dt)))
    robot = load_robot(scenario.robot)
    collision = CollisionModel(robot)
    obstacles = obstacles_of(scenario)
    q = initial_configuration(robot, scenario)
    planner = Planner(robot, scenario, method=method, m=m, T_c=T_c, initial_q=q)
    if q0 is not None:
        check_state(q0)
        q = np.array(q0, dtype=float)
    h = np.array(scenario.initial.momentum)
    step_dt, n = scenario.simulation.dt_s, scenario.n_steps
    log: dict[str, list] = {key: [] for key in _LOGGED}
    for k in tqdm(range(n + 1), disable=not progress, desc=f"{scenario.name}/{method}", unit="step"):
        plan = planner(k * step_dt, q)
        if not np.all(np.isfinite(plan.dq_joints)):
            raise FFSRError(f"planner produced non-finite joint rates at t = {k * step_dt:.3f} s")
        v = robot.velocity(q, plan.dq_joints, h)
        collision.place(q)
        clear = collision.obstacle_proximity(q, obstacles, place=False).distance_m if obstacles else np.inf
        self_clear = collision.self_proximity(q, place=False).distance_m
        for key, value in zip(_LOGGED, (q, v, plan.dq_joints, np.linalg.norm(plan.ee_error[:3]),
                                        np.linalg.norm(plan.ee_error[3:]), np.linalg.norm(plan.base_error[:3]),
                                        np.linalg.norm(plan.base_error[3:]), clear, self_clear, plan.mu,
                                        plan.cdf, plan.sigma_min)):
            log[key].append(value)
        if k < n:
            q, _ = robot.step(q, plan.dq_joints, step_dt, h)
    info = {"scenario": scenario.name, "scenario_sha256": scenario.sha256(), "method": method,
            "m": planner.m, "T_c_s": planner.T_c, "dt_s": step_dt, "duration_s": scenario.simulation.duration_s}
    return Trajectory(t=np.arange(n + 1) * step_dt, **{key: np.array(val) for key, val in log.items()}, info=info)


_LOGGED = ("q", "v", "dq_joints", "ee_position_error_m", "ee_attitude_error", "base_position_error_m",
           "base_attitude_error", "clearance_m", "self_clearance_m", "mu", "cdf", "sigma_min")
