"""The benchmark objective B and the feasibility of an episode (paper eqs. 21-22; docs/model.md §13).

.. math:: B = \\gamma\\Big(\\alpha \\int \\Psi(\\|\\dot\\Theta^1\\|, \\dot\\Theta_{danger})\\,dt
          + \\beta \\int \\Psi(\\|\\dot\\Theta^2\\|, \\dot\\Theta_{danger})\\,dt\\Big) + \\Theta_b,
   \\qquad \\Psi(A, B) = A \\text{ if } A > B \\text{ else } 0

with rates in deg/s, integrals over the applied (zero-order-hold) steps, and Θ_b = +∞ when any
joint rate exceeds the limit at any step (both arms by default; ``rate_limit_scope =
"balance_arm"`` is the literal eq. 22). An episode is feasible when no rate limit is exceeded,
nothing collides (clearance to the obstacle, arm-arm and arm-base all ≥ 0) and the final
end-effector position and attitude errors are within the scenario's tolerances. The benchmark
score is B if feasible, else +∞. This module is the only place any of these are computed: the
env reward, the GA fitness and the leaderboard score all come from here.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ffsr_gym.model.scenario import ObjectiveSettings
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.types import Array


@dataclass(frozen=True)
class ObjectiveTerms:
    """The terms of B for one trajectory (or a slice of it), reported separately.

    Attributes:
        mission_integral: ∫ Ψ(||Θ̇¹||, danger) dt [deg].
        balance_integral: ∫ Ψ(||Θ̇²||, danger) dt [deg].
        smooth: γ (α mission_integral + β balance_integral), the finite part of B.
        rate_violation: whether Θ_b = +∞.
        objective: B (may be +inf).
        collided: an obstacle clearance below the keep-out distance, or arm-arm / arm-base contact.
        final_errors_ok: final EE position and attitude errors within tolerance.
        feasible: no violation, no collision, final errors within tolerance.
        score: B if feasible else +inf.
    """

    mission_integral: float
    balance_integral: float
    smooth: float
    rate_violation: bool
    objective: float
    collided: bool
    final_errors_ok: bool
    feasible: bool
    score: float

    def as_dict(self) -> dict:
        """JSON-ready dict; infinite values become ``None``."""
        return {k: (None if isinstance(v, float) and math.isinf(v) else v) for k, v in asdict(self).items()}


def rate_terms(dq_joints: Array, dt: float, settings: ObjectiveSettings) -> tuple[Any, Any, Any]:
    """Ψ-integrals [deg] of both arms and the rate-limit flag for applied rates ``dq_joints`` [rad/s].

    Args:
        dq_joints: (n, 12) rates held over each step, mission arm first; or (batch, n, 12) for
            several episodes at once (rows of zeros add nothing).
        dt: step [s].
        settings: the scenario's objective settings.

    Returns:
        Floats and a bool for one episode, arrays of shape (batch,) for a batch.
    """
    rates = np.degrees(np.asarray(dq_joints, dtype=float))
    single = rates.ndim < 3
    arms = rates.reshape((1, -1, 2, 6) if single else (*rates.shape[:-1], 2, 6))  # (batch, n, arm, joint)
    norms = np.sqrt(np.add.reduce(arms * arms, axis=-1))
    integrals = np.add.reduce(np.where(norms > settings.danger_rate_deg_s, norms, 0.0), axis=-2) * dt
    checked = arms if settings.rate_limit_scope == "both_arms" else arms[..., 1, :]
    violation = (np.abs(checked) > settings.max_rate_deg_s).reshape(len(arms), -1).any(axis=1)
    if single:
        return float(integrals[0, 0]), float(integrals[0, 1]), bool(violation[0])
    return integrals[:, 0], integrals[:, 1], violation


def smooth_part(mission_integral: float, balance_integral: float, settings: ObjectiveSettings) -> float:
    """γ (α ∫Ψ¹ + β ∫Ψ²), the finite part of B."""
    return settings.gamma * (settings.alpha * mission_integral + settings.beta * balance_integral)


def objective_terms(traj: Trajectory, settings: ObjectiveSettings) -> ObjectiveTerms:
    """Evaluate B, feasibility and score of a complete trajectory.

    The rates of the last sample (at the final time, never applied) are excluded from the
    integrals and the limit check; clearances and final errors use every sample.
    """
    mission, balance, violation = rate_terms(traj.dq_joints[:-1], traj.dt, settings)
    smooth = smooth_part(mission, balance, settings)
    objective = math.inf if violation else smooth
    collided = bool(np.min(traj.clearance_m) < settings.keep_out_m or np.min(traj.self_clearance_m) < 0.0)
    final_ok = bool(traj.ee_position_error_m[-1] <= settings.ee_position_tolerance_m
                    and traj.ee_attitude_error[-1] <= settings.ee_attitude_tolerance)
    feasible = not violation and not collided and final_ok
    return ObjectiveTerms(mission, balance, smooth, violation, objective, collided, final_ok, feasible,
                          objective if feasible else math.inf)
