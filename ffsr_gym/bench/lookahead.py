"""A method that times each task by looking ahead (capture v1; docs/baselines.md): simulate first, then act.

Before its episode starts, :class:`Lookahead` simulates the task as the episode will play it (the robot's model and
the target's body and motion, which every pool task publishes) with the predefined-time planner at (m, T_c) going in
at every moment of a grid over [0, the episode's duration) with step ``step_s``, and plays the moment whose worst
score over itself and its grid neighbours is the highest: the middle of a window that stays open when the moment
moves by a step, not its edge (the earliest on ties; the best lone moment when no window is that wide; 0 s when no
moment captures). It is the simplest model-predictive method. What it has that the entries acting on observations
alone do not is the task's model; an episode plays the nominal target, so its simulation is exact, and it bounds
what timing alone earns at one (m, T_c), short of the best-known search, which also moves (m, T_c). It is measured
in a study (``experiments/lookahead_capture_v1.py``), not ranked: a ranked policy acts on the observation.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.benchmark import Benchmark
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.tasks.certificate import planner_episode

#: How a study's record of the method (:meth:`Lookahead.record`) states its rule.
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
        """What a study records of the method: its settings, its simulated episodes per task and its rule."""
        return {**asdict(self), "simulated_episodes_per_task": simulated_per_task, "rule": DESCRIPTION}
