"""The native planner's settings, by name, from a scenario's setup (what :func:`ffsr_gym.sim.compiled.settings_vectors`
packs for the numba kernel, field by field)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym._native import Method, PlannerSettings
from ffsr_gym.model import portable
from ffsr_gym.model.tumbling import rotations


def _target_row(target: Any) -> np.ndarray:
    return np.concatenate((target.target_position, target.axis, [target.angle])).astype(float)


def planner_settings(setup: Any, *, method: str, m: float, T_c: float) -> PlannerSettings:
    """The :class:`ffsr_gym._native.PlannerSettings` of a scenario's setup (``ffsr_gym.sim.setup.ScenarioSetup``),
    a method and (m, T_c [s]).

    Raises:
        ValueError: a method the planner does not know (named, with the allowed ones).
    """
    if method not in Method.__members__:
        raise ValueError(f"method {method!r}; allowed: {sorted(Method.__members__)}")
    scenario, path, body = setup.scenario, setup.path, setup.scenario.tumbling_target
    planner, settings = scenario.planner, PlannerSettings()
    settings.method, settings.m, settings.T_c, settings.K = Method.__members__[method], m, T_c, \
        planner.proportional_gain_per_s
    settings.phi_printed, settings.phi_split = planner.phi_form == "printed", bool(planner.phi_split)
    settings.body_attitude_error, settings.mu_distance = planner.attitude_error == "body", planner.mu_law == "distance"
    settings.balance_avoids = bool(planner.balance_avoids)
    settings.lambda_mission, settings.lambda_balance = planner.lambda_max_mission, planner.lambda_max_balance
    settings.eps_mission, settings.eps_balance = planner.epsilon_mission, planner.epsilon_balance
    settings.xi, settings.delta, settings.k1 = planner.cdf_xi, planner.cdf_delta, planner.cdf_k1
    settings.motion_time, settings.accel_time = path.motion_time, path.accel_time
    settings.estimate_interval, settings.dt = setup.estimate_interval_s, scenario.simulation.dt_s
    settings.rate_max_deg_s = scenario.objective.max_rate_deg_s
    settings.rate_limit_balance_only = scenario.objective.rate_limit_scope == "balance_arm"
    settings.substeps = scenario.physics_substeps
    settings.set_start(np.asarray(path.start_position, float), np.asarray(path.start_attitude, float))
    settings.set_base_target(*(np.asarray(part, float) for part in setup.base_target))
    settings.set_momentum(np.asarray(scenario.initial.momentum, float))
    if scenario.obstacle is not None:
        settings.danger_radius = scenario.obstacle.danger_radius_m
    settings.keep_out = scenario.objective.keep_out_m
    field = setup.obstacles
    settings.set_obstacles(np.asarray(field.positions_m, float).reshape(-1, 3),
                           np.asarray(field.velocities_m_s, float).reshape(-1, 3), np.asarray(field.radii_m, float))
    if body is None:
        settings.set_truth(_target_row(path))
        settings.set_estimates(np.array([_target_row(e) for e in setup.estimates]))
    else:
        motion = setup.target_motion
        settings.set_frames(np.concatenate((path.position_m, path.attitude, path.twist, motion.position_m,
                                            rotations(motion.quaternion).reshape(-1, 9)), axis=1))
        settings.set_body_half(np.array(body.size_m, float) / 2.0)
        settings.body_radius, settings.body_danger = 0.5 * portable.norm(body.size_m), body.danger_radius_m
        settings.body_collides = True
    return settings
