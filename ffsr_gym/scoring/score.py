"""The bounded episode score (v2, as v1): success, a smoothness cost without dead zone, and one bounded number.

For the applied joint rates Θ̇_k of each arm (held over [t_k, t_k + dt)):

.. math:: E = \\sum_k \\|\\dot\\Theta_k\\|^2 dt \\;[\\mathrm{rad^2/s}], \\qquad
          V = \\|\\dot\\Theta_0\\| + \\sum_k \\|\\dot\\Theta_{k+1} - \\dot\\Theta_k\\| \\;[\\mathrm{rad/s}]

          C = \\alpha\\,(E_1/E_{ref} + V_1/V_{ref}) + \\beta\\,(E_2/E_{ref} + V_2/V_{ref}),
          \\qquad s = \\frac{1}{1 + C} \\text{ on success, } 0 \\text{ otherwise.}

E is the size of the rates (the paper's ∫Ψ with its 150 deg/s dead zone removed and squared);
V is their total variation, which is ∫‖Θ̈‖ dt for smooth rates and grows by twice the amplitude
at every sign flip of a chatter. Success: no joint of either arm above the rate limit, no
collision (obstacle, arm-arm, arm-base), final end-effector errors within the tolerances. The
paper's B is reported next to it (``ffsr_gym.scoring.objective``). This module is the only place
the score is computed: the env reward, the optimisers and the leaderboards all use it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ffsr_gym import _native
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.benchmark import Benchmark, ScoreSettings
from ffsr_gym.model.scenario import ObjectiveSettings, Scenario
from ffsr_gym.scoring.capture import Capture, capture, episode_relative_motion, native_capture
from ffsr_gym.scoring.objective import smooth_part
from ffsr_gym.sim.setup import prepare
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.types import Array

#: Why an episode failed, in the order they are checked.
FAILURES = ("rate_limit", "collision", "final_error")
#: Why an episode of a capture rule file (``[capture]``) failed: its last check is capture, not the final errors.
CAPTURE_FAILURES = ("rate_limit", "collision", "no_capture")


def smoothness_terms(dq_joints: Array, dt: float, previous: Array | None = None) -> tuple[Array, Array]:
    """Rate energy E [rad²/s] and rate variation V [rad/s] of each arm for applied rates.

    Args:
        dq_joints: (n, 12) rates held over consecutive steps [rad/s], mission arm first.
        dt: step [s].
        previous: (12,) the rates applied just before (zeros: the robot starts at rest). Chunks
            of an episode, each with the previous chunk's last row, sum to the whole episode's terms.

    Returns:
        ``(E, V)``, each (2,) for (mission, balance). The sums run in the
        native kernel (``ffsr_gym._native.smoothness_terms``, shared with the environments' step).
    """
    rates = np.ascontiguousarray(dq_joints, dtype=float).reshape(-1, 12)
    before = np.zeros(12) if previous is None else np.ascontiguousarray(previous, dtype=float).reshape(12)
    return _native.smoothness_terms(rates, float(dt), before)


def smoothness_cost(energy: Array, variation: Array, settings: ScoreSettings) -> float:
    """C = α (E₁/E_ref + V₁/V_ref) + β (E₂/E_ref + V₂/V_ref) (dimensionless, ≥ 0)."""
    return float(_native.smoothness_cost(np.ascontiguousarray(energy, dtype=float),
                                         np.ascontiguousarray(variation, dtype=float), cost_settings(settings)))


def cost_settings(settings: ScoreSettings, into: _native.DecisionSettings | None = None) -> _native.DecisionSettings:
    """The cost's settings (α, β, E_ref, V_ref) in a native decision's settings (``into``, else new ones)."""
    out = _native.DecisionSettings() if into is None else into
    out.alpha, out.beta = settings.alpha, settings.beta
    out.E_ref, out.V_ref = settings.rate_energy_ref_rad2_s, settings.rate_variation_ref_rad_s
    return out


def bounded_score(success: bool, cost: float) -> float:
    """The episode score: 1 / (1 + C) ∈ (0, 1] on success, 0 on failure (and for an infinite C)."""
    if not success or not math.isfinite(cost):
        return 0.0
    return 1.0 / (1.0 + cost)


def score_reward(cost_before: float, cost_after: float, end: "EpisodeScore | None") -> tuple[float, float]:
    """The reward of one decision, and the part of it that is a failure penalty.

    The value of an unfinished episode is the score it would get if it succeeded now,
    1 / (1 + C_t); the value of a finished one is its score. The reward is the change of value,
    so an episode's rewards sum to its score minus 1 (the value at C = 0) and the return ranks
    episodes exactly as the score does. A failure loses the whole remaining value 1 / (1 + C_t):
    the ``penalty``.

    Args:
        cost_before, cost_after: the smoothness cost C accumulated before and after the decision.
        end: the finished episode's score (:func:`score_episode`), or None while it runs.
    """
    if end is None:
        return running_reward(cost_before, cost_after), 0.0
    penalty = 0.0 if end.success else 1.0 / (1.0 + cost_after)
    return end.score - 1.0 / (1.0 + cost_before), penalty


def running_reward(cost_before: Any, cost_after: Any) -> Any:
    """:func:`score_reward` of a decision that did not end its episode: 1 / (1 + C_after) − 1 / (1 + C_before).

    Floats or arrays (the batched environments reward every running copy at once; elementwise
    IEEE arithmetic, so the same numbers as one at a time).
    """
    return 1.0 / (1.0 + cost_after) - 1.0 / (1.0 + cost_before)


@dataclass(frozen=True)
class EpisodeScore:
    """Everything the pool leaderboards report of one episode.

    Attributes:
        score: 1 / (1 + C) on success, else 0.
        success: no rate violation, no collision, final errors within tolerance.
        failure: the first failed check of :data:`FAILURES`, or None.
        smoothness_cost: C.
        rate_energy: (mission, balance) E [rad²/s].
        rate_variation: (mission, balance) V [rad/s].
        paper_B: the paper's objective B (inf when a rate exceeds the limit).
        peak_rate_deg_s: (mission, balance) largest |Θ̇| of any joint [deg/s].
        final_ee_position_error_m, final_ee_attitude_error: at the last sample.
        min_clearance_m: smallest clearance to the obstacle (inf without one) and
            ``min_self_clearance_m`` arm-arm / arm-base [m].
        convergence_time_s: first time after which the EE position error stays below the
            position tolerance (None if it never does).
        capture_time_s: under a capture rule, when the first hold window ended (None: no capture, or no rule).
        capture_ratio: under a capture rule, the factor by which every capture tolerance could shrink and the
            episode still capture (:attr:`~ffsr_gym.scoring.capture.Capture.margin_ratio`; > 1: no capture;
            None: no rule).
        contact_speed_m_s: under a rule with ``[quality]`` (capture v1), the relative speed [m/s] when the tool
            first came within ``contact_m`` of the grasp frame (None: never).
        quality_terms: under such a rule, the score's three terms (time, contact, smoothness: each weight times
            its factor; zeros without a capture), which sum to ``score``; None without one.
    """

    score: float
    success: bool
    failure: str | None
    smoothness_cost: float
    rate_energy: tuple[float, float]
    rate_variation: tuple[float, float]
    paper_B: float
    peak_rate_deg_s: tuple[float, float]
    final_ee_position_error_m: float
    final_ee_attitude_error: float
    min_clearance_m: float
    min_self_clearance_m: float
    convergence_time_s: float | None
    capture_time_s: float | None = None
    capture_ratio: float | None = None
    contact_speed_m_s: float | None = None
    quality_terms: tuple[float, float, float] | None = None

    def as_dict(self) -> dict:
        """JSON-ready dict; infinite values become ``None``; the capture keys only under a capture rule, the
        quality's under a rule with ``[quality]``."""
        data = {k: (None if isinstance(v, float) and math.isinf(v) else v) for k, v in asdict(self).items()}
        if self.capture_ratio is None and self.capture_time_s is None:
            del data["capture_time_s"], data["capture_ratio"]
        if self.quality_terms is None:
            del data["contact_speed_m_s"], data["quality_terms"]
        else:
            data["quality_terms"] = list(self.quality_terms)
        return data


def trajectory_totals(traj: Trajectory, task: Scenario, benchmark: Benchmark) -> _native.ScoreTotals:
    """The score's terms of a recorded trajectory (the rates of its last sample are not applied), summed by the
    same native accumulator an environment episode sums them with as it runs (so the same bits)."""
    rows = len(traj.t)
    err = np.column_stack([traj.ee_position_error_m, traj.ee_attitude_error, traj.base_position_error_m,
                           traj.base_attitude_error])
    return _native.score_totals(np.ascontiguousarray(traj.dq_joints, dtype=float), np.ascontiguousarray(err),
                                np.ascontiguousarray(traj.clearance_m, dtype=float),
                                np.ascontiguousarray(traj.self_clearance_m, dtype=float), max(rows - 1, 0),
                                task.objective.danger_rate_deg_s, benchmark.score.ee_position_tolerance_m)


def score_episode(traj: Trajectory, task: Scenario, benchmark: Benchmark) -> EpisodeScore:
    """Score a complete trajectory of ``task`` under ``benchmark`` (the rates of the last sample are not applied).

    Under a rule with ``[quality]`` (capture v1) the episode ends at its capture: a trajectory that ran on is
    scored up to the sample that completed the capture, as the environments end it there, and the native judge
    (:func:`~ffsr_gym.scoring.capture.native_capture`) judges it, as theirs does."""
    judged = None
    if benchmark.quality is not None:
        setup = prepare(task)
        judged = native_capture(setup, traj, benchmark.capture)
        if judged.captured and judged.sample + 1 < len(traj.t):
            traj = traj.head(judged.sample + 1)
            judged = native_capture(setup, traj, benchmark.capture)
    elif benchmark.capture is not None:
        judged = capture(traj.t, episode_relative_motion(prepare(task), traj), benchmark.capture)
    times = traj.t
    return score_of_totals(trajectory_totals(traj, task, benchmark), task, benchmark, traj.dt,
                           lambda k: float(times[k]), judged)


def score_of_totals(totals: _native.ScoreTotals, task: Scenario, benchmark: Benchmark, dt: float,
                    time_of: Callable[[int], float], judged: Capture | None = None) -> EpisodeScore:
    """The episode score of an episode's totals (:func:`trajectory_totals`, or an environment episode's own):
    ``dt`` [s] the step, ``time_of(k)`` the time [s] of sample k; ``judged``: its capture, under a capture rule."""
    settings, objective = benchmark.score, task.objective
    energy, variation = np.array(totals.square) * dt, np.array(totals.variation)
    cost = smoothness_cost(energy, variation, settings)
    peak = peak_rates_deg_s(totals)
    min_clear, min_self = float(totals.min_clear), float(totals.min_self)
    final_p, final_o = (float(value) for value in totals.last_err[:2])
    checks = (bool(np.any(peak > settings.max_rate_deg_s)), min_clear < objective.keep_out_m or min_self < 0.0,
              not (final_p <= settings.ee_position_tolerance_m and final_o <= settings.ee_attitude_tolerance))
    names, captured = FAILURES, {}
    if benchmark.capture is not None:  # a capture rule: the hold window replaces the final errors
        if judged is None:
            raise InvalidInputError("a capture rule's score needs the episode's capture (its recorded trajectory)")
        names, checks = CAPTURE_FAILURES, (*checks[:2], not judged.captured)
        captured = {"capture_time_s": judged.time_s if judged.captured else None,
                    "capture_ratio": judged.margin_ratio}
    failure = next((name for name, failed in zip(names, checks) if failed), None)
    score = bounded_score(failure is None, cost)
    if benchmark.quality is not None:
        terms = quality_terms(benchmark, judged, cost, task.simulation.duration_s) if failure is None else (0.0,) * 3
        score = math.fsum(terms)
        contact = None if math.isnan(judged.contact_speed_m_s) else judged.contact_speed_m_s
        captured.update(contact_speed_m_s=contact, quality_terms=terms)
    return EpisodeScore(
        score=score, success=failure is None, failure=failure, smoothness_cost=cost,
        rate_energy=(float(energy[0]), float(energy[1])), rate_variation=(float(variation[0]), float(variation[1])),
        paper_B=paper_objective(totals, objective, dt, peak), peak_rate_deg_s=(float(peak[0]), float(peak[1])),
        final_ee_position_error_m=final_p, final_ee_attitude_error=final_o, min_clearance_m=min_clear,
        min_self_clearance_m=min_self, convergence_time_s=convergence_time(totals, time_of), **captured,
    )


def quality_terms(benchmark: Benchmark, judged: Capture, cost: float, duration_s: float) -> tuple[float, float, float]:
    """The three terms of a capture's worth under ``[quality]`` (capture v1; docs/model.md §24): time, contact
    and smoothness, each its weight times its factor (:class:`~ffsr_gym.model.benchmark.CaptureQuality`)."""
    q = benchmark.quality
    return (q.time_weight * (1.0 - judged.time_s / duration_s),
            q.contact_weight / (1.0 + judged.contact_speed_m_s / q.contact_speed_ref_m_s),
            q.smoothness_weight / (1.0 + cost))


def peak_rates_deg_s(totals: _native.ScoreTotals) -> Array:
    """Each arm's largest |Θ̇| [deg/s] over an episode's applied steps (zeros before any)."""
    return np.degrees(np.array(totals.peak)) if totals.applied else np.zeros(2)


def paper_objective(totals: _native.ScoreTotals, objective: ObjectiveSettings, dt: float,
                    peak: Array | None = None) -> float:
    """The paper's B of an episode's totals (:func:`ffsr_gym.scoring.objective.objective_terms`' ``objective``):
    +inf when a joint (of the scope's arms) exceeded the rate limit, else γ (α ∫Ψ¹ + β ∫Ψ²); ``peak``: the totals'
    :func:`peak_rates_deg_s`, when already at hand."""
    peak = peak_rates_deg_s(totals) if peak is None else peak
    checked = peak if objective.rate_limit_scope == "both_arms" else peak[1:]
    if bool(np.any(checked > objective.max_rate_deg_s)):
        return math.inf
    return smooth_part(float(totals.psi[0] * dt), float(totals.psi[1] * dt), objective)


def convergence_time(totals: _native.ScoreTotals, time_of: Callable[[int], float]) -> float | None:
    """:meth:`Trajectory.convergence_time` at the totals' tolerance: the time after the last sample at or above it
    (the first sample's time when none was; None when the last one was)."""
    if totals.last_above < 0:
        return time_of(0)
    if totals.last_above == totals.samples - 1:
        return None
    return time_of(totals.last_above + 1)
