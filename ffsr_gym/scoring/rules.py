"""The score rules a benchmark spec names: what an episode is worth, decision by decision and at its end.

A rule turns the applied rates of a decision into the reward's increment and the info's cost, a
finished trajectory into the episode's result, that result into the episode-end info, the
reward's penalty and a leaderboard row, and rows into the aggregate metrics. The engine, the
environments, ``evaluate`` and the leaderboard renderer all go through :func:`score_rule`, so one
code path computes every version's score:

* ``paper_objective`` (v0): B of the paper (:mod:`ffsr_gym.scoring.objective`) from the
  scenario's ``[objective]`` section; reward = −(B's finite-part increment) − penalties.
* ``bounded_smoothness`` (v2): 1 / (1 + C) on success (:mod:`ffsr_gym.scoring.score`) from the
  spec's rule file; reward = the change of the episode's value.
* ``capture_smoothness`` (capture-v0): the same, with success a capture of the tumbling target's grasp frame.
* ``capture_quality`` (capture-v1): a capture's worth (time, contact speed, smoothness); the episode ends at the
  capture; reward = the change of the episode's value.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ffsr_gym import _native
from ffsr_gym.exceptions import ScenarioError
from ffsr_gym.model.benchmark import Benchmark
from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym.scoring.aggregate import bootstrap_ci, iqm
from ffsr_gym.scoring.capture import capture_of_judge
from ffsr_gym.scoring.objective import ObjectiveTerms, objective_terms, rate_terms, smooth_part
from ffsr_gym.scoring.score import (
    EpisodeScore,
    running_reward,
    score_episode,
    score_of_totals,
    score_reward,
    smoothness_cost,
    smoothness_terms,
)
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.types import Array


class PaperObjective:
    """The paper's B: lower is better, +inf when infeasible (``FFSR-v0``)."""

    name = "paper_objective"
    increment_key = "objective_increment"
    #: Episode-end ``info`` keys (attributes of :class:`ObjectiveTerms`) and their dtypes in a batch.
    end_keys: dict[str, type] = {"objective": float, "feasible": bool, "score": float, "rate_violation": bool,
                                 "collided": bool}
    #: Whether the compiled decision's increment and cost are this rule's (else recomputed from the rates).
    compiled_terms = False
    shaping = False
    row_needs_trajectory = True  # :meth:`row` adds trajectory metrics
    benchmark = None  # its numbers are the scenario's own sections

    def __init__(self, spec: BenchmarkSpec) -> None:
        self.spec = spec

    def task(self, scenario: Scenario) -> Scenario:
        """The scenario as this version plays it (v0: as it is)."""
        return scenario

    def increment(self, applied: Array, dt: float, last_rates: Array, scenario: Scenario) -> Any:
        """γ (α ∫Ψ¹ + β ∫Ψ²) of the applied rates (n, 12), or of a batch (N, n, 12) (zero rows add nothing)."""
        objective = scenario.objective
        return smooth_part(*rate_terms(applied, dt, objective)[:2], objective)

    def cost(self, applied: Array, min_margin: float, terminated: bool, scenario: Scenario) -> float:
        """The safety cost of a decision: 1.0 when it ended the episode by a violation."""
        return 1.0 if terminated else 0.0

    def result(self, traj: Trajectory, scenario: Scenario) -> ObjectiveTerms:
        """B, feasibility and score of a trajectory; one cut short without a violation is infeasible."""
        terms = objective_terms(traj, scenario.objective)
        if incomplete(len(traj.t), scenario, terms.rate_violation or terms.collided):
            return dataclasses.replace(terms, feasible=False, score=math.inf)
        return terms

    def reward(self, cost_before: float, increment: float, result: ObjectiveTerms | None, *, terminated: bool,
               truncated: bool, scenario: Scenario, started_s: float = 0.0) -> tuple[float, float]:
        """(reward, penalty): −increment − penalty; a violation and a missed final tolerance are penalised
        (``started_s``, the decision's start [s], is not needed)."""
        env = scenario.env
        penalty = env.violation_penalty if terminated else 0.0
        if truncated and result is not None and not result.final_errors_ok:
            penalty += env.tolerance_penalty
        return -increment - penalty, penalty

    @staticmethod
    def running_rewards(cost_before: Array, increments: Array) -> Array:
        """Rewards of decisions that did not end their episodes: −increment."""
        return -increments

    def row(self, result: ObjectiveTerms, traj: Trajectory) -> dict[str, Any]:
        """The leaderboard row of an episode (besides its seed)."""
        metrics = traj.metrics()
        return {**result.as_dict(), "final_ee_position_error_m": metrics["final_ee_position_error_m"],
                "max_joint_rate_deg_s": metrics["max_joint_rate_deg_s"], "min_clearance_m": metrics["min_clearance_m"],
                "duration_s": float(traj.t[-1])}

    def row_values(self, rows: Sequence[dict[str, Any]]) -> tuple[Array, Array]:
        """(scores, feasible flags) of rows (a JSON null score is +inf)."""
        scores = np.array([math.inf if row["score"] is None else float(row["score"]) for row in rows])
        return scores, np.array([bool(row["feasible"]) for row in rows])

    def aggregate(self, rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
        """Mean, IQM, seeded-bootstrap 95 % CI of the IQM, feasible rate (metric names of the spec)."""
        scores, rates = self.row_values(rows)
        names = self.spec.leaderboard
        return {"score_mean": float(np.mean(scores)), names.iqm: _iqm_or_inf(scores),
                names.ci: bootstrap_ci(scores, _iqm_or_inf), names.rate: float(np.mean(rates.astype(float))),
                "episodes": len(scores)}


class BoundedSmoothness:
    """1 / (1 + C) on success, 0 on failure: higher is better (``FFSR-v2``)."""

    name = "bounded_smoothness"
    increment_key = "smoothness_increment"
    end_keys: dict[str, type] = {"score": float, "success": bool, "failure": object, "smoothness_cost": float,
                                 "paper_B": float}
    compiled_terms = True
    shaping = True
    row_needs_trajectory = False  # :meth:`row` reads the result only

    def __init__(self, spec: BenchmarkSpec) -> None:
        self.spec = spec
        self.benchmark: Benchmark = spec.rules

    def task(self, scenario: Scenario) -> Scenario:
        """``scenario`` with the rule file's planner defaults, tolerances, rate limit and action box."""
        return self.benchmark.task(scenario)

    def increment(self, applied: Array, dt: float, last_rates: Array, scenario: Scenario) -> float:
        """The smoothness cost C of the applied rates (n, 12), continuing from ``last_rates``."""
        return smoothness_cost(*smoothness_terms(applied, dt, last_rates), self.benchmark.score)

    def cost(self, applied: Array, min_margin: float, terminated: bool, scenario: Scenario) -> float:
        """0 without violation; depth of the violation (``min_margin`` [m], negative inside the keep-out distance
        or in contact) / scale + relative excess of the peak rate."""
        limit = self.benchmark.score.max_rate_deg_s
        peak = float(np.degrees(np.max(np.abs(applied)))) if len(applied) else 0.0
        depth = max(0.0, -min_margin) / self.benchmark.action.cost_clearance_scale_m
        return depth + max(0.0, peak / limit - 1.0)

    def result(self, traj: Trajectory, scenario: Scenario) -> EpisodeScore:
        """The episode score of a trajectory (:func:`ffsr_gym.scoring.score.score_episode`); one cut short
        without a violation fails as ``incomplete``."""
        return self._complete(score_episode(traj, scenario, self.benchmark), len(traj.t), scenario)

    def result_of_totals(self, totals: _native.ScoreTotals, scenario: Scenario) -> EpisodeScore:
        """:meth:`result` of an environment episode that kept its score's totals only (no trajectory); the same
        numbers (the totals are the trajectory's sums, :func:`~ffsr_gym.scoring.score.trajectory_totals`)."""
        dt = scenario.simulation.dt_s
        return self._complete(score_of_totals(totals, scenario, self.benchmark, dt, lambda k: k * dt),
                              totals.samples, scenario)

    @staticmethod
    def _complete(result: EpisodeScore, samples: int, scenario: Scenario) -> EpisodeScore:
        """``result``, or a failure as ``incomplete`` when the episode was cut short without a violation."""
        if incomplete(samples, scenario, result.failure in ("rate_limit", "collision")):
            return dataclasses.replace(result, score=0.0, success=False, failure="incomplete")
        return result

    def reward(self, cost_before: float, increment: float, result: EpisodeScore | None, *, terminated: bool,
               truncated: bool, scenario: Scenario, started_s: float = 0.0) -> tuple[float, float]:
        """(reward, penalty) of :func:`ffsr_gym.scoring.score.score_reward` (``started_s`` is not needed)."""
        return score_reward(cost_before, cost_before + increment, result)

    @staticmethod
    def running_rewards(cost_before: Array, increments: Array) -> Array:
        """Rewards of decisions that did not end their episodes (elementwise, as one at a time)."""
        return running_reward(cost_before, cost_before + increments)

    def row(self, result: EpisodeScore, traj: Trajectory | None) -> dict[str, Any]:
        """The leaderboard row of an episode (besides its seed and task)."""
        return result.as_dict()

    def row_values(self, rows: Sequence[dict[str, Any]]) -> tuple[Array, Array]:
        """(scores, success flags) of rows."""
        return (np.array([float(row["score"]) for row in rows]), np.array([bool(row["success"]) for row in rows]))

    def aggregate(self, rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
        """Mean, the spec's statistic (IQM or mean) and its seeded-bootstrap 95 % CI, success rate (metric names
        of the spec)."""
        scores, rates = self.row_values(rows)
        names = self.spec.leaderboard
        centre = iqm if names.statistic == "iqm" else _mean
        return {"score_mean": float(np.mean(scores)), "score_iqm": iqm(scores), names.iqm: centre(scores),
                names.ci: bootstrap_ci(scores, centre), names.rate: float(np.mean(rates.astype(float))),
                "episodes": len(scores)}


class CaptureSmoothness(BoundedSmoothness):
    """v2's bounded score with success a capture (a rule file with ``[capture]``; ``FFSR-Capture-v0``): the same
    :func:`~ffsr_gym.scoring.score.score_episode`, whose failure is then ``no_capture`` instead of
    ``final_error``; the episode's end also says when the capture happened and its margin."""

    name = "capture_smoothness"
    end_keys: dict[str, type] = {**BoundedSmoothness.end_keys, "capture_time_s": float, "capture_ratio": float}

    def __init__(self, spec: BenchmarkSpec) -> None:
        super().__init__(spec)
        if self.benchmark.capture is None:
            raise ScenarioError(f"{spec.source}: score rule 'capture_smoothness' needs a rule file with a [capture] "
                                f"section; {spec.score.rules_file!r} has none")


class CaptureQuality(CaptureSmoothness):
    """A capture's worth (a rule file with ``[quality]``; ``FFSR-Capture-v1``; docs/model.md §24): on capture,
    w_t (1 − t / T) + w_v / (1 + v_contact / v_ref) + w_s / (1 + C) (:func:`~ffsr_gym.scoring.score.quality_terms`),
    0 otherwise. The episode ends at its capture (an environment episode there, a longer trajectory is scored up
    to it).

    The reward is the change of the episode's value V(t, C) = w_t (1 − t / T) + w_v + w_s / (1 + C), the score it
    would get were it captured now with a contact at rest: rewards sum to the score minus 1, a decision costs the
    time it takes and the smoothness it spends, and a failure loses the whole remaining value (the penalty)."""

    name = "capture_quality"
    end_keys: dict[str, type] = {**CaptureSmoothness.end_keys, "contact_speed_m_s": float}

    def __init__(self, spec: BenchmarkSpec) -> None:
        super().__init__(spec)
        self.quality = self.benchmark.quality
        family = load_scenario(self.benchmark.tasks.family)
        self.duration_s, self.interval_s = family.simulation.duration_s, family.env.decision_interval_s

    def result_of_totals(self, totals: _native.ScoreTotals, scenario: Scenario,
                         capture: dict | None = None) -> EpisodeScore:
        """:meth:`result` of an environment episode from its totals and its native judge (``capture``:
        ``Episode.capture``); the same numbers."""
        if capture is None:
            raise ScenarioError("a capture v1 episode's result needs its native judge (Episode.capture)")
        dt = scenario.simulation.dt_s
        judged = capture_of_judge(capture, dt)
        result = score_of_totals(totals, scenario, self.benchmark, dt, lambda k: k * dt, judged)
        return self._complete(result, totals.samples, scenario)

    def _complete(self, result: EpisodeScore, samples: int, scenario: Scenario) -> EpisodeScore:
        """As v2's, with a capture a complete episode however early it ends."""
        return result if result.success else super()._complete(result, samples, scenario)

    def value(self, elapsed_s: Any, cost: Any) -> Any:
        """V(t, C) (floats or arrays)."""
        q = self.quality
        return (q.time_weight * (1.0 - elapsed_s / self.duration_s) + q.contact_weight
                + q.smoothness_weight / (1.0 + cost))

    def reward(self, cost_before: float, increment: float, result: EpisodeScore | None, *, terminated: bool,
               truncated: bool, scenario: Scenario, started_s: float = 0.0) -> tuple[float, float]:
        """(reward, penalty): V after − V before while the episode runs; at its end, score − V before, and a
        failure's penalty V(t_end, C_end) (what it lost)."""
        before = self.value(started_s, cost_before)
        if result is None:
            return self.value(started_s + self.interval_s, cost_before + increment) - before, 0.0
        ended_s = min(started_s + self.interval_s, self.duration_s)
        penalty = 0.0 if result.success else self.value(ended_s, cost_before + increment)
        return result.score - before, penalty

    def running_rewards(self, cost_before: Array, increments: Array) -> Array:
        """Rewards of decisions that did not end their episodes: each costs one decision's time and its
        smoothness (the time at which it started does not enter: V is linear in t)."""
        q = self.quality
        return (q.smoothness_weight * running_reward(cost_before, cost_before + increments)
                - q.time_weight * self.interval_s / self.duration_s)


def incomplete(samples: int, scenario: Scenario, violated: bool) -> bool:
    """Whether an episode ended before its horizon without a violation (cut short by a wrapper, a time limit
    or a caller): such an episode is never scored as complete. A complete one holds every step's sample
    and the final one (``n_steps + 1`` rows)."""
    return not violated and samples < scenario.n_steps + 1


def _iqm_or_inf(values: Array) -> float:
    """The IQM, or +inf when an infinite (infeasible) score lies in the middle half."""
    v = np.sort(values)
    lo, hi = int(math.floor(0.25 * len(v))), int(math.ceil(0.75 * len(v)))
    middle = v[lo:hi] if hi > lo else v
    return float(np.mean(middle)) if np.all(np.isfinite(middle)) else math.inf


RULES = {PaperObjective.name: PaperObjective, BoundedSmoothness.name: BoundedSmoothness,
         CaptureSmoothness.name: CaptureSmoothness, CaptureQuality.name: CaptureQuality}
ScoreRule = PaperObjective | BoundedSmoothness | CaptureSmoothness | CaptureQuality


def score_rule(spec: BenchmarkSpec) -> ScoreRule:
    """The score rule ``spec`` names, with its numbers."""
    return RULES[spec.score.rule](spec)


def _mean(values: Array) -> float:
    """The mean, as a float (the statistic of a spec with ``statistic = "mean"``)."""
    return float(np.mean(values))
