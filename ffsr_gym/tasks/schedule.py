"""Action schedules: a time-varying env action given by a few knots, replayable like a certificate.

A :class:`Schedule` is the action sequence of one episode of a registered v2 environment:

* ``residual`` (``FFSR-Residual-v2``): 12 joint residuals in [-1, 1] at ``K`` knots spread evenly
  over the decisions that start before the end of the desired motion (after it the fade is 0, so
  the action no longer acts);
* ``parameters`` (``FFSR-v2``): the (m, T_c) action in [-1, 1]² at ``K`` knots spread evenly over
  all decisions;
* ``timed`` (a capture version's (m, T_c) id, ``FFSR-Capture-v1`` or ``-v2``): one knot (m, T_c, g): the
  (m, T_c) action throughout, the approach's command held (a = -1) before the decision g picks and the
  insertion commanded (a = +1) from it on; g in [-1, 1] spans the episode's decisions evenly
  (:func:`go_decision`).

Between knots the action is linear in the decision index, after the last knot it holds; the
values are computed in float64 and rounded to float32, as the env rounds its actions, so that
``env.step(schedule.actions(...)[k])`` replays the schedule exactly. :func:`replay_schedule`
plays it on a task scenario (any step, start or backend: the ensemble members of
:mod:`ffsr_gym.tasks.certificate`) the way the environments step, and scores the episode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.benchmark import Benchmark, action_to_parameters, residual_rates
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.planning.planner import planner_parameters
from ffsr_gym.scoring.score import EpisodeScore, score_episode
from ffsr_gym.sim.simulate import make_rollout
from ffsr_gym.sim.trajectory import Trajectory

#: Schedule families and the width of their actions.
FAMILIES = {"residual": 12, "parameters": 2, "timed": 3}
#: The registered env whose actions each family is (v2's, and capture v1's for ``timed``; a version's own ids:
#: ``ffsr_gym_lab.best_known.build.family_env_ids``).
ENV_IDS = {"residual": "FFSR-Residual-v2", "parameters": "FFSR-v2", "timed": "FFSR-Capture-v1"}


def version_families(version: str) -> tuple[str, ...]:
    """The schedule families a version's best-known search uses: ``timed`` where the action commands the approach
    (capture v1: the decision to go in is not a knot to interpolate), else ``residual`` and ``parameters``."""
    from ffsr_gym.versions.registry import spec_for_version

    return ("timed",) if spec_for_version(version).actions.command else ("residual", "parameters")


def go_decision(g: float, decisions: int) -> int:
    """The decision a timed schedule's g ∈ [-1, 1] commands the insertion at: g spans 0 ... ``decisions`` - 1."""
    return int(round((float(g) + 1.0) / 2.0 * (decisions - 1)))


def go_value(decision: int, decisions: int) -> float:
    """The float32-exact g whose :func:`go_decision` is ``decision`` (its inverse)."""
    g = float(np.float32(2.0 * decision / (decisions - 1) - 1.0))
    assert go_decision(g, decisions) == decision
    return g


@dataclass(frozen=True)
class Schedule:
    """Knots of a time-varying env action.

    Attributes:
        family: a key of :data:`FAMILIES` (which env's action it is).
        knots: (K, width) values in [-1, 1], exact in float32, K >= 1.
    """

    family: str
    knots: tuple[tuple[float, ...], ...]

    def __post_init__(self) -> None:
        if self.family not in FAMILIES:
            raise InvalidInputError(f"schedule family {self.family!r}; allowed: {list(FAMILIES)}")
        values = np.asarray(self.knots, dtype=float)
        if values.ndim != 2 or values.shape[0] < 1 or values.shape[1] != FAMILIES[self.family]:
            raise InvalidInputError(f"schedule knots of shape {values.shape}; allowed: (K >= 1, "
                                    f"{FAMILIES[self.family]}) for family {self.family!r}")
        if not np.all(np.abs(values) <= 1.0) or np.any(values.astype(np.float32).astype(float) != values):
            raise InvalidInputError("schedule knots must be numbers in [-1, 1], exact in float32 (env actions)")
        if self.family == "timed" and values.shape[0] != 1:
            raise InvalidInputError(f"a timed schedule has one knot (m, T_c, g); got {values.shape[0]}")

    @classmethod
    def from_vector(cls, family: str, vector: Any) -> Schedule:
        """The schedule of a flat search vector (clipped to [-1, 1], rounded to float32), knot after knot."""
        values = np.clip(np.asarray(vector, dtype=float), -1.0, 1.0).astype(np.float32).astype(float)
        return cls(family, tuple(tuple(row) for row in values.reshape(-1, FAMILIES[family])))

    @classmethod
    def constant(cls, family: str, action: Any, knots: int) -> Schedule:
        """A schedule that plays ``action`` at every decision."""
        return cls.from_vector(family, np.tile(np.asarray(action, dtype=float), knots))

    def vector(self) -> np.ndarray:
        """The flat search vector (inverse of :meth:`from_vector`)."""
        return np.asarray(self.knots, dtype=float).ravel()

    def span(self, task: Scenario) -> int:
        """Decisions the knots spread over: those starting before the motion ends (residual), or all."""
        interval = task.env.decision_interval_s
        decisions = round(task.simulation.duration_s / interval)
        if self.family != "residual":
            return decisions
        return min(decisions, math.ceil(task.desired_path.motion_time_s / interval - 1e-9))

    def actions(self, task: Scenario) -> np.ndarray:
        """(decisions, width) float32: the env action of every decision of an episode of ``task``."""
        interval = task.env.decision_interval_s
        decisions = round(task.simulation.duration_s / interval)
        values = np.asarray(self.knots, dtype=float)
        span = self.span(task)
        at = np.minimum(np.arange(decisions), span - 1).astype(float)
        where = np.linspace(0.0, span - 1.0, len(values)) if len(values) > 1 else np.zeros(1)
        out = np.stack([np.interp(at, where, values[:, j]) for j in range(values.shape[1])], axis=1)
        if self.family == "timed":  # hold, then the insertion from the knot's decision on
            out[:, 2] = np.where(np.arange(decisions) >= go_decision(values[0, 2], decisions), 1.0, -1.0)
        return np.clip(out, -1.0, 1.0).astype(np.float32)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict; each knot as the shortest decimal that reads back as its float32 (:meth:`from_dict`)."""
        return {"family": self.family,
                "knots": [[float(np.format_float_positional(np.float32(x), unique=True, trim="-")) for x in row]
                          for row in self.knots]}

    @classmethod
    def from_dict(cls, data: Any) -> Schedule:
        """Inverse of :meth:`as_dict` (values rounded to float32, as env actions are).

        Raises:
            InvalidInputError: not a dict with ``family`` and ``knots`` (values as above).
        """
        if not isinstance(data, dict) or set(data) != {"family", "knots"}:
            raise InvalidInputError(f"schedule must be a dict with keys family, knots; got {data!r}")
        try:
            knots = tuple(tuple(float(np.float32(float(x))) for x in row) for row in data["knots"])
        except (TypeError, ValueError, OverflowError) as exc:
            raise InvalidInputError(f"schedule knots {data['knots']!r}: {exc}") from None
        return cls(data["family"], knots)


def replay_schedule(task: Scenario, schedule: Schedule, benchmark: Benchmark, *, backend: str = "auto") -> EpisodeScore:
    """Play ``schedule`` on ``task`` the way the environments step (decisions of the env's interval, stop
    at the first violation; residuals faded, on top of the default planner; a timed schedule's command set before
    each decision's steps), and score the episode (a capture v1 episode up to its capture)."""
    return score_episode(schedule_run(task, schedule, benchmark, backend=backend), task, benchmark)


def schedule_run(task: Scenario, schedule: Schedule, benchmark: Benchmark, *, backend: str = "auto") -> Trajectory:
    """The run :func:`replay_schedule` scores: to the end of the episode or its first violation (past a capture)."""
    actions = schedule.actions(task)
    residual = schedule.family == "residual"
    m, T_c = planner_parameters(task, "predefined_time", benchmark.planner.m, benchmark.planner.T_c_s)
    rollout = make_rollout(task, backend=backend, m=m, T_c=T_c)  # (m, T_c) family: reset at every decision
    per_decision = max(1, round(task.env.decision_interval_s / task.simulation.dt_s))
    motion_time, k = task.desired_path.motion_time_s, 0
    while rollout.k < rollout.n_steps:
        action = actions[min(k, len(actions) - 1)]
        rates = None
        if residual:
            rates = benchmark.residual_fade(rollout.t, motion_time) * residual_rates(action, task.env.residual_rate_deg_s)
        else:
            rollout.set_parameters(*action_to_parameters(action[:2], task))
            if schedule.family == "timed":
                rollout.set_command(float(action[2]) + 1.0)
        _, status = rollout.advance(per_decision, rates, stop_on_violation=True)
        k += 1
        if status != "ok":
            break
    rollout.finish()
    return rollout.trajectory()
