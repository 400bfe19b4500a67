"""What a caller sets on an episode engine's running copies besides their actions: physical (m, T_c) and a
commanded approach's command (capture v1)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym.planning import ptsf


class EngineSettings:
    """The setters of :class:`~ffsr_gym.environments.engine.EpisodeEngine` (its ``rollouts``, ``episodes`` and
    ``scenarios`` per copy)."""

    def _set_parameters(self, i: int, parameters: tuple[float, float]) -> None:
        """Validated physical (m, T_c [s]) for copy ``i``'s next decisions."""
        rollout = self.rollouts[i]
        rollout.set_parameters(*parameters)
        self.episodes[i].set_parameters(rollout.m, rollout.T_c)

    def set_command(self, copies: Any, command: float) -> None:
        """The approach's command u of ``copies`` (indices) from their next decision on (a commanded approach)."""
        for i in copies:
            timing = self.episodes[i].timing
            timing[0] = command
            self.episodes[i].timing = timing

    def _set_parameters_of(self, active: np.ndarray, parameters: tuple[float, float]) -> None:
        """:meth:`_set_parameters` for every ``active`` copy at once (checked once per predefined-time form; the
        copies' rollouts read them from their episodes when next asked for, :meth:`rollout`)."""
        m, T_c = float(parameters[0]), float(parameters[1])
        chosen = np.flatnonzero(active)
        for form in {self.scenarios[i].planner.phi_form for i in chosen}:
            ptsf.check_parameters(T_c, m, form)
        for i in chosen:
            self.episodes[i].set_parameters(m, T_c)
