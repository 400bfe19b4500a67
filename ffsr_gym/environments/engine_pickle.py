"""How an episode engine pickles: without its native episodes, which a clone rebuilds from each running copy's
state (the same numbers as the original would give)."""

from __future__ import annotations


class PicklableEngine:
    """The pickling of :class:`~ffsr_gym.environments.engine.EpisodeEngine` (its ``_load_copy`` rebuilds a copy)."""

    def __getstate__(self) -> dict:
        """Pickled without the native episodes: a clone builds them from each running copy's state (same numbers)."""
        state = self.__dict__.copy()
        state["batch"], state["episodes"] = None, [None] * self.n
        state["_episodes"] = [None if e is None else (e.state(), e.m, e.T_c, e.last_rates, e.totals, e.timing,
                                                      e.capture_state) for e in self.episodes]
        return state

    def __setstate__(self, state: dict) -> None:
        saved = state.pop("_episodes")
        self.__dict__.update(state)
        for i, episode in enumerate(saved):
            if episode is not None and not self.rollouts[i].finished:
                self._load_copy(i, self.scenarios[i], episode)
            elif self.rollouts[i] is not None and self.logs is not None:
                self.rollouts[i]._log = {key: rows[i] for key, rows in self.logs.items()}
