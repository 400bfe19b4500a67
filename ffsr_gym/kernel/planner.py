"""The native planner's settings, by name, from a scenario's setup: the method and (m, T_c), the planner's gains and
laws, the desired path (or a tumbling target's frames, and a commanded approach's limits), the base set-point, the
momentum and the obstacles."""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym._native import Method, PlannerSettings
from ffsr_gym.model import portable
from ffsr_gym.model.tumbling import rotations

#: The fields set through a method of :class:`ffsr_gym._native.PlannerSettings` (``set_<name>(*value)``), not by
#: assignment.
SET_BY_METHOD = ("start", "base_target", "momentum", "obstacles", "truth", "estimates", "frames", "body_half",
                 "timing")


def _target_row(target: Any) -> np.ndarray:
    return np.concatenate((target.target_position, target.axis, [target.angle])).astype(float)


def settings_fields(setup: Any, *, method: str, m: float, T_c: float) -> dict[str, Any]:
    """Every field of the native planner's settings of a scenario's setup (``ffsr_gym.sim.setup.ScenarioSetup``),
    a method and (m, T_c [s]), by name: a number, or the arguments of its ``set_`` method (:data:`SET_BY_METHOD`).

    Raises:
        ValueError: a method the planner does not know (named, with the allowed ones).
    """
    if method not in Method.__members__:
        raise ValueError(f"method {method!r}; allowed: {sorted(Method.__members__)}")
    scenario, path, body = setup.scenario, setup.path, setup.scenario.tumbling_target
    planner, field = scenario.planner, setup.obstacles
    fields: dict[str, Any] = {
        "method": Method.__members__[method], "m": m, "T_c": T_c, "K": planner.proportional_gain_per_s,
        "phi_printed": planner.phi_form == "printed", "phi_split": bool(planner.phi_split),
        "body_attitude_error": planner.attitude_error == "body", "mu_distance": planner.mu_law == "distance",
        "balance_avoids": bool(planner.balance_avoids), "lambda_mission": planner.lambda_max_mission,
        "lambda_balance": planner.lambda_max_balance, "eps_mission": planner.epsilon_mission,
        "eps_balance": planner.epsilon_balance, "xi": planner.cdf_xi, "delta": planner.cdf_delta, "k1": planner.cdf_k1,
        "motion_time": path.motion_time, "accel_time": path.accel_time,
        "estimate_interval": setup.estimate_interval_s, "dt": scenario.simulation.dt_s,
        "rate_max_deg_s": scenario.objective.max_rate_deg_s,
        "rate_limit_balance_only": scenario.objective.rate_limit_scope == "balance_arm",
        "substeps": scenario.physics_substeps, "keep_out": scenario.objective.keep_out_m,
        "start": (np.asarray(path.start_position, float), np.asarray(path.start_attitude, float)),
        "base_target": tuple(np.asarray(part, float) for part in setup.base_target),
        "momentum": (np.asarray(scenario.initial.momentum, float),),
        "obstacles": (np.asarray(field.positions_m, float).reshape(-1, 3),
                      np.asarray(field.velocities_m_s, float).reshape(-1, 3), np.asarray(field.radii_m, float)),
    }
    if scenario.obstacle is not None:
        fields["danger_radius"] = scenario.obstacle.danger_radius_m
    if body is None:
        fields["truth"] = (_target_row(path),)
        fields["estimates"] = (np.array([_target_row(e) for e in setup.estimates]),)
        return fields
    motion = setup.target_motion
    fields["frames"] = (np.concatenate((path.position_m, path.attitude, path.twist, motion.position_m,
                                        rotations(motion.quaternion).reshape(-1, 9)), axis=1),)
    fields["body_half"] = (np.array(body.size_m, float) / 2.0,)
    fields |= {"body_radius": 0.5 * portable.norm(body.size_m), "body_danger": body.danger_radius_m,
               "body_collides": True}
    if scenario.commanded_approach is not None:  # the frames hold the grasp frame; the kernel derives the approach
        fields["timing"] = path.limits.kernel_values()
    return fields


def planner_settings(setup: Any, *, method: str, m: float, T_c: float) -> PlannerSettings:
    """The :class:`ffsr_gym._native.PlannerSettings` of :func:`settings_fields`.

    Raises:
        ValueError: a method the planner does not know (named, with the allowed ones).
    """
    settings = PlannerSettings()
    for name, value in settings_fields(setup, method=method, m=m, T_c=T_c).items():
        if name in SET_BY_METHOD:
            getattr(settings, f"set_{name}")(*value)
        else:
            setattr(settings, name, value)
    return settings
