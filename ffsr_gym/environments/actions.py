"""What the environments do with an action and how they show the state: the action check, its
mapping ((m, T_c) or residual rates, with the spec's fade), the observation, and the compiled
decision's settings of a task."""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym import _native
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.benchmark import (
    CaptureRule,
    action_to_parameters,  # noqa: F401 - the environments' mapping, re-exported
)
from ffsr_gym.model.benchmark import residual_rates as scaled_residual
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.scoring.capture import QUANTITIES
from ffsr_gym.scoring.score import cost_settings

OBS_CLIP = {"rates": 20.0, "errors": 10.0, "relative": 10.0, "clearance": 10.0, "twist": 10.0}


def assemble_observation(angles: np.ndarray, last_rates: np.ndarray, ee_error: np.ndarray, base_error: np.ndarray,
                         relative: np.ndarray, clearance: Any, time_fraction: Any,
                         twist: np.ndarray | None = None) -> np.ndarray:
    """The 53-dim float32 observation from its parts (docs/envs.md), 59-dim with ``twist``; leading batch axes
    allowed.

    Args:
        angles: joint angles [rad] (..., 12). last_rates: joint rates applied last [rad/s] (..., 12).
        ee_error, base_error: pose errors (..., 6). relative: obstacle relative to the nearest robot
        point [m] (..., 3). clearance: robot–obstacle clearance [m] (...). time_fraction: t / duration (...).
        twist: the desired end-effector twist [m/s, rad/s] (..., 6) of a spec with ``target_twist``, or None.
    """
    parts = [
        np.sin(angles), np.cos(angles),
        np.clip(last_rates, -OBS_CLIP["rates"], OBS_CLIP["rates"]),
        np.clip(np.concatenate((ee_error, base_error), axis=-1), -OBS_CLIP["errors"], OBS_CLIP["errors"]),
        np.clip(relative, -OBS_CLIP["relative"], OBS_CLIP["relative"]),
        np.clip(np.asarray(clearance, dtype=float), -OBS_CLIP["clearance"], OBS_CLIP["clearance"])[..., None],
        np.minimum(1.0, np.asarray(time_fraction, dtype=float))[..., None],
    ]
    if twist is not None:
        parts.append(np.clip(twist, -OBS_CLIP["twist"], OBS_CLIP["twist"]))
    return np.concatenate(parts, axis=-1).astype(np.float32)


def observation_bounds(target_twist: bool = False, grasp: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) of the observation's box (float32); ``target_twist`` appends the twist's six bounds, ``grasp``
    (with it) the grasp frame's relative position and rotation (6), its twist (6) and the approach's state (5:
    command u in [0, 2], s and w in [0, 1], their rates clipped as joint rates)."""
    extra = [np.full(3, OBS_CLIP["relative"]), np.full(3, OBS_CLIP["errors"]), np.full(6, OBS_CLIP["twist"]),
             [2.0, 1.0, OBS_CLIP["rates"], 1.0, OBS_CLIP["rates"]]] if grasp else []
    high = np.concatenate([np.ones(24), np.full(12, OBS_CLIP["rates"]), np.full(12, OBS_CLIP["errors"]),
                           np.full(3, OBS_CLIP["relative"]), [OBS_CLIP["clearance"]], [1.0],
                           np.full(6 if target_twist or grasp else 0, OBS_CLIP["twist"]), *extra]).astype(np.float32)
    low = -high
    low[52] = 0.0
    if grasp:
        low[[71, 72, 74]] = 0.0  # u, s, w
    return low, high


def check_action(action: Any, shape: tuple[int, ...]) -> tuple[np.ndarray, Any]:
    """An action of ``shape`` (a batch of them: leading axis = copies) clipped to [-1, 1] as float32.

    Returns the clipped action and whether it (each row of a batch) was clipped.

    Raises:
        InvalidInputError: wrong shape, or a NaN/inf entry (naming the copies of a batch).
    """
    try:
        raw = np.asarray(action)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"action must be an array of real numbers of shape {shape} ({exc})") from None
    if raw.dtype.kind not in "iuf":
        kind = {"c": "complex", "b": "bool"}.get(raw.dtype.kind, "not numeric")
        raise InvalidInputError(f"action must hold real numbers (int or float) of shape {shape}, got dtype "
                                f"{raw.dtype} ({kind})")
    a = raw.astype(np.float64)
    if a.shape != shape:
        raise InvalidInputError(f"action must have shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        if a.ndim == 2:
            bad = sorted({int(i) for i in np.argwhere(~np.isfinite(a))[:, 0]})
            raise InvalidInputError(f"actions of copies {bad} are not finite; allowed range [-1, 1] per entry")
        raise InvalidInputError(f"action must be finite, got {a}; allowed range [-1, 1] per entry")
    clipped = np.clip(a, -1.0, 1.0)
    return clipped.astype(np.float32), np.any(clipped != a, axis=-1)


def physical_parameters(m: Any, T_c: Any) -> tuple[float, float]:
    """(m, T_c [s]) given to ``step_with_parameters`` as floats.

    Raises:
        InvalidInputError: not real numbers, or not finite (the planner checks the ranges m ∈ (0, 1), T_c > 0).
    """
    values = []
    for name, value in (("m", m), ("T_c", T_c)):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                or not np.isfinite(value):
            raise InvalidInputError(f"{name} = {value!r}; allowed: a finite real number (m in (0, 1), T_c > 0 [s])")
        values.append(float(value))
    return values[0], values[1]


def physical_command(command: Any, commanded: bool) -> float:
    """The approach's command u given to ``step_with_parameters`` (capture v1) as a float.

    Raises:
        InvalidInputError: an env without a commanded approach (``commanded`` False), or not a real number in
            [0, 2] (0 holds the start pose, 1 the pre-grasp frame, 2 the grasp frame).
    """
    if not commanded:
        raise InvalidInputError("command: this env's action has no approach command; allowed: the capture-v1 ids")
    if isinstance(command, bool) or not isinstance(command, (int, float, np.integer, np.floating)) \
            or not 0.0 <= float(command) <= 2.0:
        raise InvalidInputError(f"command = {command!r}; allowed: a real number in [0, 2] (0 holds the start pose, "
                                "1 the pre-grasp frame, 2 the grasp frame)")
    return float(command)


def residual_rates(action: np.ndarray, task: Scenario, rule: Any, fades: bool, t: float) -> np.ndarray:
    """Residual joint rates [rad/s] of a (clipped) residual action at time ``t`` [s].

    ± ``env.residual_rate_deg_s`` per unit of action, times the rule file's fade f(t) of the
    task's desired motion when the spec's residual fades.
    """
    rates = scaled_residual(action, task.env.residual_rate_deg_s)
    if not fades:
        return rates
    return rule.benchmark.residual_fade(t, task.desired_path.motion_time_s) * rates


def decision_settings(task: Scenario, rule: Any, fades: bool, command: bool = False) -> _native.DecisionSettings:
    """The native decision's settings of a task under a score rule: the residual's scale and fade, the (m, T_c)
    action box, whether the action's last entry commands the approach (``command``), the rate limit, the violation
    cost's clearance scale, the smoothness cost's settings, and what the episode's score totals need (the paper
    objective's danger rate, the end-effector position tolerance).

    Without a fade the residual's weight stays 1 (the fade starts at +inf). A rule whose increment
    and cost are not the kernel's (``compiled_terms`` False) gets neutral score settings: its terms
    are computed from the applied rates.
    """
    settings = _native.DecisionSettings()
    (settings.m_lo, settings.m_hi), (settings.T_lo, settings.T_hi) = task.env.m_bounds, task.env.T_c_bounds_s
    benchmark = rule.benchmark
    settings.fade_s, settings.motion_s = ((benchmark.action.residual_fade_s, task.desired_path.motion_time_s) if fades
                                          else (1.0, np.inf))
    settings.rate_scale = float(np.radians(task.env.residual_rate_deg_s))
    settings.command_action = bool(command)
    settings.rate_limit_deg_s = task.objective.max_rate_deg_s
    settings.clear_scale = benchmark.action.cost_clearance_scale_m if rule.compiled_terms else 1.0
    settings.danger_rate_deg_s = task.objective.danger_rate_deg_s  # the episode's totals (paper_B, convergence)
    settings.tolerance_m = (benchmark.score if rule.compiled_terms else task.objective).ee_position_tolerance_m
    if rule.compiled_terms:
        return cost_settings(benchmark.score, settings)
    settings.alpha, settings.beta, settings.E_ref, settings.V_ref = 0.0, 0.0, 1.0, 1.0
    return settings


def judge_capture(episode: _native.Episode, rule: CaptureRule) -> None:
    """Have a native episode judge capture under ``rule`` (a rule file's ``[capture]``) sample by sample, read the
    speed of first contact, and end at the capture (capture v1)."""
    episode.judge_capture(np.array([getattr(rule, name) for name in QUANTITIES]), rule.hold_s, rule.contact_m, True)
