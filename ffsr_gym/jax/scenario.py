"""A scenario as the JAX loop takes it: its robot's :class:`~ffsr_gym.jax.physics.Model`, the planner's
:class:`~ffsr_gym.jax.planner.PlanTask` (numbers) and :class:`~ffsr_gym.jax.planner.PlanRules` (choices), and its
initial state, all read from the same :func:`ffsr_gym.sim.setup.prepare` as the other backends."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.jax.physics import Model, jnp, model_of
from ffsr_gym.jax.planner import PlanRules, PlanTask
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.planning.desired_path import DesiredPath
from ffsr_gym.planning.planner import planner_parameters
from ffsr_gym.sim.setup import prepare, robot_assets


@lru_cache(maxsize=8)
def robot_model(name: str) -> Model:
    """The :class:`Model` of a robot (shipped name or folder), from its kernel arrays."""
    return model_of(robot_assets(name).kernel)


def segments_used(model: Model) -> tuple[tuple[bool, ...], ...]:
    """Which of each arm's six segments (joint origin to the next, the last to the end-effector) are longer than
    1e-12 m: a segment's length is fixed by the robot, so the danger field skips the short ones statically."""
    lengths = np.linalg.norm(np.asarray(model.placement_p), axis=1)
    ee = np.linalg.norm(np.asarray(model.ee_p), axis=1)
    return tuple(tuple(bool(v) for v in np.concatenate((lengths[6 * a + 1:6 * a + 6], [ee[a]])) > 1e-12)
                 for a in range(2))


def from_scenario(scenario: Scenario, *, method: str = "predefined_time", m: float | None = None,
                  T_c: float | None = None) -> tuple[Model, PlanTask, PlanRules, jnp.ndarray]:
    """``(model, task, rules, x0)`` of a scenario for :func:`ffsr_gym.jax.planner.plan`.

    Raises:
        InvalidInputError: what the JAX loop does not cover yet: the printed form of φ, a tumbling target, a noisy
            target estimate, a changed plant (inertials or servo drives).
    """
    m, T_c = planner_parameters(scenario, method, m, T_c)
    s = scenario.planner
    unsupported = [name for name, present in (("planner.phi_form = 'printed'", s.phi_form != "sanchez_torres"),
                                              ("[tumbling_target]", scenario.tumbling_target is not None),
                                              ("[target_noise]", scenario.target_noise is not None),
                                              ("[plant]", scenario.plant is not None),
                                              ("[servo]", scenario.servo is not None)) if present]
    if unsupported:
        raise InvalidInputError(f"scenario {scenario.name!r}: the JAX loop does not cover {', '.join(unsupported)} "
                                "yet; allowed: the kinematic plant of FFSR-v2's tiers")
    setup = prepare(scenario)
    path = setup.path
    if not isinstance(path, DesiredPath):
        raise InvalidInputError(f"scenario {scenario.name!r}: a moving target's path; allowed: a still target")
    model = robot_model(scenario.robot)
    obstacles = setup.obstacles
    f = lambda v: jnp.asarray(np.asarray(v, dtype=np.float64))  # noqa: E731
    task = PlanTask(
        start_position=f(path.start_position), target_position=f(path.target_position),
        start_attitude=f(path.start_attitude), axis=f(path.axis), angle=f(path.angle),
        motion_time=f(path.motion_time), accel_time=f(path.accel_time),
        base_position=f(setup.base_target[0]), base_attitude=f(setup.base_target[1]),
        obstacle_position=f(obstacles.positions_m).reshape(-1, 3), obstacle_velocity=f(obstacles.velocities_m_s).reshape(-1, 3),
        danger_radius=f(scenario.obstacle.danger_radius_m if scenario.obstacle is not None else 1.0),
        momentum=f(scenario.initial.momentum), m=f(m), T_c=f(T_c), gain=f(s.proportional_gain_per_s),
        lambda_max=f([s.lambda_max_mission, s.lambda_max_balance]), epsilon=f([s.epsilon_mission, s.epsilon_balance]),
        cdf_k1=f(s.cdf_k1), cdf_xi=f(s.cdf_xi), cdf_delta=f(s.cdf_delta), n_obstacles=len(obstacles))
    rules = PlanRules(method=method, phi_split=s.phi_split, attitude_error=s.attitude_error, mu_law=s.mu_law,
                      balance_avoids=s.balance_avoids, segments=segments_used(model))
    q0 = setup.q0
    x0 = np.concatenate((q0[:7], q0[robot_assets(scenario.robot).kernel.q_index]))
    return model, task, rules, f(x0)
