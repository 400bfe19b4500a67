"""A timing a practitioner would write for capture v1 (docs/model.md §24): watch the handle, go in at its slowest.

:class:`SlowestPass` is a policy of ``FFSR-Capture-v1`` (observation → (m, T_c, command) action) that knows
nothing of the task beyond what it sees: the default planner's (m, T_c) throughout; the start pose held while it
watches the handle's speed (its linear speed plus the standoff times its angular speed, from the observation's
grasp twist); after the first ``watch_s`` seconds, the insertion commanded at the first decision whose speed lies
more than ``tolerance`` above the slowest it has seen (the slowest moment is behind: at once when the speed has
risen since the start), at once when the speed has been steady (a regular sweep has no slowest point), and at the
latest when only the approach's time is left. Once going it keeps going.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Where the capture v1 observation holds the elapsed fraction of the episode and the grasp frame's twist
#: (docs/envs.md).
TIME_INDEX, TWIST = 52, slice(65, 71)


@dataclass
class PlannerTiming:
    """What a policy of ``FFSR-Capture-v1`` that only times the insertion needs: ``m``, ``T_c_s``: the planner's
    setting; ``duration_s``: the episode's length (the observation shows its elapsed fraction); ``approach_s``: the
    time an approach and insertion take from rest (7.49 s + 2.49 s) and the hold (1 s); ``m_bounds``,
    ``T_c_bounds_s``: capture-v1's action box (capture-v1.toml [action])."""

    m: float = 0.3
    T_c_s: float = 4.0
    duration_s: float = 60.0
    approach_s: float = 10.98
    m_bounds: tuple[float, float] = (0.05, 0.6)
    T_c_bounds_s: tuple[float, float] = (1.0, 10.0)
    _state: dict = field(default_factory=dict, repr=False)

    def episode(self, observation: np.ndarray, **fresh: object) -> tuple[np.ndarray, float, dict]:
        """The observation as float64, its moment t [s] (the episode's elapsed fraction times ``duration_s``) and the
        episode's state, which starts as ``fresh`` at an episode's first observation (t = 0)."""
        obs = np.asarray(observation, dtype=np.float64)
        t = float(obs[TIME_INDEX]) * self.duration_s
        if t == 0.0 or not self._state:  # a new episode
            self._state.clear()
            self._state.update(fresh)
        return obs, t, self._state

    def late(self, t: float) -> bool:
        """Whether only the approach's time is left at ``t`` [s]: the latest moment to go in."""
        return t >= self.duration_s - self.approach_s - 1e-9

    def action(self, command: float) -> np.ndarray:
        """The env action of the planner's (m, T_c) and the command u ∈ [0, 2]."""
        (m_lo, m_hi), (t_lo, t_hi) = self.m_bounds, self.T_c_bounds_s
        return np.array([2.0 * (self.m - m_lo) / (m_hi - m_lo) - 1.0, 2.0 * (self.T_c_s - t_lo) / (t_hi - t_lo) - 1.0,
                         command - 1.0], dtype=np.float32)


@dataclass
class SlowestPass(PlannerTiming):
    """See the module docstring and :class:`PlannerTiming`. ``standoff_m``: the lever that weighs the handle's
    angular speed."""

    standoff_m: float = 0.15
    watch_s: float = 2.0
    tolerance: float = 0.005

    def __call__(self, observation: np.ndarray) -> np.ndarray:
        twist = np.asarray(observation, dtype=np.float64)[TWIST]
        speed = float(np.linalg.norm(twist[:3]) + self.standoff_m * np.linalg.norm(twist[3:]))
        _, t, state = self.episode(observation, going=False, low=speed, high=speed)
        state["low"], state["high"] = min(state["low"], speed), max(state["high"], speed)
        if not state["going"]:
            watched = t >= self.watch_s
            steady = watched and state["high"] - state["low"] <= self.tolerance * state["high"]
            passed = watched and speed > state["low"] * (1.0 + self.tolerance)  # the slowest moment is behind
            state["going"] = steady or passed or self.late(t)
        return self.action(2.0 if state["going"] else 0.0)


#: The policy the leaderboard records and replays (``ffsr_gym.bench.capture_heuristic:slowest_pass``): one
#: instance, which starts afresh at every episode's first observation.
slowest_pass = SlowestPass()
