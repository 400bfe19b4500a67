"""A method that times each task by looking ahead (capture v1; docs/baselines.md): simulate first, then act.

Before its episode starts, :class:`Lookahead` simulates the task as the episode will play it (the robot's model and
the target's body and motion, which every pool task publishes) with the predefined-time planner at (m, T_c) going in
at every moment of a grid over [0, the episode's duration) with step ``step_s``, and plays the moment whose worst
score over itself and its grid neighbours is the highest: the middle of a window that stays open when the moment
moves by a step, not its edge (the earliest on ties; the best lone moment when no window is that wide; 0 s when no
moment captures). It is the simplest model-predictive method. What it has that the entries acting on observations
alone do not is the task's model; an episode plays the nominal target, so its simulation is exact, and it bounds
what timing alone earns at one (m, T_c), short of the best-known search, which also moves (m, T_c).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.bench.entry import EvalReport
from ffsr_gym.bench.planner_scores import check_in_box, evaluate_planner
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.benchmark import Benchmark
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.model.spec import spec_for_version
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.tasks.certificate import planner_episode
from ffsr_gym.tasks.splits import pool, task_scenario

#: What the entry's ``extra.planner.lookahead`` says of the method.
DESCRIPTION = ("the go moment of each task chosen by simulating the task before acting (its own model), at every "
               "moment of a grid: the one whose worst score over itself and its grid neighbours is highest")


@dataclass(frozen=True)
class Lookahead:
    """See the module docstring: the planner's (m, T_c [s]) and the grid's step [s]."""

    m: float = 0.3
    T_c_s: float = 4.0
    step_s: float = 0.5

    def __post_init__(self) -> None:
        step = self.step_s
        if isinstance(step, bool) or not isinstance(step, (int, float)) or not 0.01 <= step <= 10.0:
            raise InvalidInputError(f"step_s = {step!r}; allowed: a number in [0.01, 10] s")

    def grid(self, duration_s: float) -> np.ndarray:
        """The moments [s] it simulates: 0, step, ... below ``duration_s``."""
        return np.arange(int(np.ceil(duration_s / self.step_s - 1e-9))) * self.step_s

    def scores(self, played: Scenario, benchmark: Benchmark, duration_s: float) -> np.ndarray:
        """The episode's score going in at each moment of :meth:`grid`."""
        return np.array([planner_episode(played, benchmark, method="predefined_time", m=self.m, T_c=self.T_c_s,
                                         go_s=float(go)).score for go in self.grid(duration_s)])

    @staticmethod
    def choose(scores: np.ndarray) -> int:
        """The index of the moment it plays (module docstring) among a grid's ``scores``."""
        scores = np.asarray(scores, dtype=np.float64)
        padded = np.concatenate(([np.inf], scores, [np.inf]))
        worst = np.minimum(np.minimum(padded[:-2], padded[2:]), scores)
        return int(np.argmax(worst)) if worst.max() > 0.0 else int(np.argmax(scores))

    def record(self, simulated_per_task: int) -> dict:
        """What an entry records of the method (``extra.planner.lookahead``)."""
        return {**asdict(self), "simulated_episodes_per_task": simulated_per_task, "rule": DESCRIPTION}


def lookahead_report(tier: str, split: str, lookahead: Lookahead, *, version: str = "capture-v1",
                     name: str = "lookahead", progress: bool = False) -> EvalReport:
    """The entry of ``lookahead`` on a tier's pool: its moments chosen task by task, then played and scored as every
    planner entry is (:func:`~ffsr_gym.bench.planner_scores.evaluate_planner`, one moment per task); its compute is
    the simulated episodes and the time they took.

    Raises:
        InvalidInputError: a version whose action does not command the approach, (m, T_c) outside its action box.
    """
    spec = spec_for_version(version)
    if not spec.actions.command:
        raise InvalidInputError(f"version {version!r}; allowed: a version whose action commands the approach "
                                "(capture-v1)")
    rule = score_rule(spec)
    benchmark = rule.benchmark
    check_in_box((lookahead.m, lookahead.T_c_s), benchmark.action.m_bounds, benchmark.action.T_c_bounds_s)
    grid, start, moments = lookahead.grid(rule.duration_s), time.perf_counter(), []
    for task in tqdm(pool(tier, split, version=benchmark.version), disable=not progress, desc=f"{name} {tier}/{split}"):
        scores = lookahead.scores(task_scenario(tier, task.seed, benchmark), benchmark, rule.duration_s)
        moments.append(float(grid[lookahead.choose(scores)]))
    compute = {"objective_evaluations": len(grid) * len(moments), "wall_time_s": time.perf_counter() - start,
               "hardware": "1 CPU core"}
    return evaluate_planner("predefined_time", task=tier, split=split, m=lookahead.m, T_c=lookahead.T_c_s, go_s=moments,
                            name=name, compute=compute, version=version, lookahead=lookahead.record(len(grid)))
