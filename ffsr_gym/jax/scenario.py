"""A scenario as the JAX loop takes it: its robot's :class:`~ffsr_gym.jax.physics.Model`, the planner's
:class:`~ffsr_gym.jax.planner.PlanTask` (numbers) and :class:`~ffsr_gym.jax.planner.PlanRules` (choices), and its
initial state, all read from the same :func:`ffsr_gym.sim.setup.prepare` as the other backends."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.jax.episode import PARAMETERS, RESIDUAL, EpisodeTask, settings_vector
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
                  T_c: float | None = None, obstacles: int | None = None) -> tuple[Model, PlanTask, PlanRules,
                                                                                  jnp.ndarray]:
    """``(model, task, rules, x0)`` of a scenario for :func:`ffsr_gym.jax.planner.plan`; ``obstacles``: pad the
    obstacle arrays to this many rows (masked), so that the tasks of a pool stack.

    Raises:
        InvalidInputError: what the JAX loop does not cover yet: the printed form of φ, a tumbling target, a noisy
            target estimate, a changed plant (inertials or servo drives).
    """
    m, T_c = planner_parameters(scenario, method, m, T_c)
    s = scenario.planner
    unsupported = [name for name, present in (("planner.phi_form = 'printed'", s.phi_form != "sanchez_torres"),
                                              ("[tumbling_target]", scenario.tumbling_target is not None),
                                              ("[target_noise]", scenario.target_noise is not None),
                                              ("[servo]", scenario.servo is not None)) if present]
    if unsupported:
        raise InvalidInputError(f"scenario {scenario.name!r}: the JAX loop does not cover {', '.join(unsupported)} "
                                "yet; allowed: the kinematic plant of FFSR-v2's tiers")
    setup = prepare(scenario)
    path = setup.path
    if not isinstance(path, DesiredPath):
        raise InvalidInputError(f"scenario {scenario.name!r}: a moving target's path; allowed: a still target")
    model = robot_model(scenario.robot)
    field = setup.obstacles
    n = len(field) if obstacles is None else obstacles
    if n < len(field):
        raise InvalidInputError(f"obstacles = {obstacles}; allowed: at least the scenario's {len(field)}")
    positions, velocities = np.full((n, 3), 1e3), np.zeros((n, 3))  # padding rows: far away, still, masked
    positions[:len(field)], velocities[:len(field)] = field.positions_m, field.velocities_m_s
    f = lambda v: jnp.asarray(np.asarray(v, dtype=np.float64))  # noqa: E731
    task = PlanTask(
        start_position=f(path.start_position), target_position=f(path.target_position),
        start_attitude=f(path.start_attitude), axis=f(path.axis), angle=f(path.angle),
        motion_time=f(path.motion_time), accel_time=f(path.accel_time),
        base_position=f(setup.base_target[0]), base_attitude=f(setup.base_target[1]),
        obstacle_position=f(positions), obstacle_velocity=f(velocities), obstacle_mask=f(np.arange(n) < len(field)),
        danger_radius=f(scenario.obstacle.danger_radius_m if scenario.obstacle is not None else 1.0),
        momentum=f(scenario.initial.momentum), m=f(m), T_c=f(T_c), gain=f(s.proportional_gain_per_s),
        lambda_max=f([s.lambda_max_mission, s.lambda_max_balance]), epsilon=f([s.epsilon_mission, s.epsilon_balance]),
        cdf_k1=f(s.cdf_k1), cdf_xi=f(s.cdf_xi), cdf_delta=f(s.cdf_delta), n_obstacles=n)
    rules = PlanRules(method=method, phi_split=s.phi_split, attitude_error=s.attitude_error, mu_law=s.mu_law,
                      balance_avoids=s.balance_avoids, segments=segments_used(model))
    q0 = setup.q0
    x0 = np.concatenate((q0[:7], q0[robot_assets(scenario.robot).kernel.q_index]))
    return model, task, rules, f(x0)


def episode_task(scenario: Scenario, *, residual: bool = True, version: str = "v2", m: float | None = None,
                 T_c: float | None = None, obstacles: int | None = None) -> tuple[Model, PlanRules, EpisodeTask]:
    """``(model, rules, task)`` of a version's task (a scenario as its environments play it: ``task_scenario``)
    for :mod:`ffsr_gym.jax.episode`: residual actions (``FFSR-Residual-v2``) or (m, T_c) actions (``FFSR-v2``).
    ``m``, ``T_c``: the planner's (a certificate's), default the task's; ``obstacles``: see :func:`from_scenario`."""
    from ffsr_gym.environments.actions import decision_settings
    from ffsr_gym.scoring.rules import score_rule
    from ffsr_gym.versions.registry import spec_for_version

    spec = spec_for_version(version)
    rule = score_rule(spec)
    model, plan_task, rules, x0 = from_scenario(scenario, m=m, T_c=T_c, obstacles=obstacles)
    setup = prepare(scenario)
    mass, lever, inertia, _ = setup.plant_arrays
    plant = Model(model.parent, model.ee_parent, model.placement_R, model.placement_p, model.axis,
                  jnp.asarray(mass), jnp.asarray(lever), jnp.asarray(inertia), model.ee_R, model.ee_p)
    radii = np.zeros(plan_task.n_obstacles)
    radii[:len(setup.obstacles)] = setup.obstacles.radii_m
    score = rule.benchmark.score
    task = EpisodeTask(
        plan=plan_task, plant=plant, obstacle_radius=jnp.asarray(np.asarray(radii, dtype=np.float64)),
        keep_out=jnp.asarray(scenario.objective.keep_out_m),
        settings=jnp.asarray(settings_vector(decision_settings(scenario, rule, spec.actions.residual_fades))),
        tolerances=jnp.asarray([score.ee_position_tolerance_m, score.ee_attitude_tolerance]), x0=x0,
        dt=float(scenario.simulation.dt_s), n_steps=int(scenario.n_steps),
        steps_per_decision=max(1, int(round(scenario.env.decision_interval_s / scenario.simulation.dt_s))),
        mode=RESIDUAL if residual else PARAMETERS, balance_scope=scenario.objective.rate_limit_scope == "balance_arm")
    return model, rules, task
