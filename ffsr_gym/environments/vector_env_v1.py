"""Batched ``FFSR-v1`` / ``FFSR-Residual-v1``: the v1 episodes, stepped by one kernel call for all copies.

``gymnasium.make_vec("FFSR-Residual-v1", num_envs=64, task="easy", vectorization_mode="vector_entry_point")``
gives the same episodes as 64 single environments seeded ``seed, seed + 1, ...`` (tested bit for
bit): each copy draws its tasks from the pool with its own generator, the residual fades with
the copy's own time, and rewards and episode scores come from :mod:`ffsr_gym.scoring.score`,
called per copy exactly as the single environment calls it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym.environments.env_v1 import END_INFO_V1, FFSRResidualV1Env, FFSRV1Env
from ffsr_gym.environments.vector_env import FFSRVectorEnv
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.scenario import Scenario, residual_rates
from ffsr_gym.scoring.score import score_episode, score_reward, smoothness_cost, smoothness_terms
from ffsr_gym.sim.compiled import KernelRollout


class FFSRV1VectorEnv(FFSRVectorEnv):
    """``num_envs`` copies of :class:`~ffsr_gym.environments.env_v1.FFSRV1Env` (spaces, rewards, info keys: see there).

    Arguments as the single environment (``task``, ``split``, ``dense_shaping``) plus ``threads``;
    ``terminate_on_violation`` must stay True (the batched kernel stops a copy at its first
    violation). Autoreset is Gymnasium's next-step mode; ``reset(seed=s)`` seeds copy i with
    s + i. ``reset``'s info has ``task_index`` and ``task_seed`` per copy (-1 on ``paper``);
    episode-end keys (``score``, ``success``, ``failure``, ``smoothness_cost``, ``paper_B``) come
    with their ``_key`` masks.
    """

    single_env_class: type[FFSRV1Env] = FFSRV1Env
    end_keys = END_INFO_V1

    def __init__(self, num_envs: int, task: str | Scenario = "paper", split: str = "train", *, threads: int | None = None,
                 backend: str = "kernel", render_mode: str | None = None, max_episode_steps: int | None = None,
                 terminate_on_violation: bool = True, dense_shaping: bool = False) -> None:
        if terminate_on_violation is not True:
            raise InvalidInputError("terminate_on_violation: the batched v1 environments stop a copy at its first "
                                    "violation; use True, or the single environment for False")
        self._task, self._split, self._dense_shaping = task, split, dense_shaping
        per_decision = None if max_episode_steps is None else int(max_episode_steps)
        super().__init__(num_envs, task, threads=threads, backend=backend, render_mode=render_mode)
        decisions = self.n_steps // self.steps_per_decision
        if per_decision is not None and per_decision != decisions:
            raise InvalidInputError(f"max_episode_steps = {per_decision}; episodes have {decisions} decisions here")
        self._potential = np.zeros(self.num_envs)
        self._task_index = np.full(self.num_envs, -1, dtype=np.int64)
        self._task_seed = np.full(self.num_envs, -1, dtype=np.int64)
        self._cost_so_far = np.zeros(self.num_envs)
        self._forced_index: list[int] | None = None
        self._ended: dict[int, Any] = {}

    def _make_template(self, scenario: str | Scenario) -> FFSRV1Env:
        return self.single_env_class(self._task, self._split, backend="kernel", dense_shaping=self._dense_shaping)

    def _episode_scenario(self, i: int) -> Scenario:
        template = self._template
        template._np_random = self._rngs[i]
        forced = self._forced_index
        scenario, info = template._episode_scenario(None if forced is None else {"task_index": forced[i]})
        self._task_index[i], self._task_seed[i] = info.get("task_index", -1), info.get("task_seed", -1)
        return scenario

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """As the single env; ``options={"task_index": [i_0, ..., i_{N-1}]}`` picks each copy's task
        of this reset (later autoresets draw from the pool again)."""
        self._forced_index = self._task_indices(options)
        try:
            obs, _ = super().reset(seed=seed, options=options)
        finally:
            self._forced_index = None
        self._cost_so_far[:] = 0.0
        _, _, ee_error = self._observe()
        self._potential = -ee_error / self._template.benchmark.action.shaping_position_scale_m
        return obs, {"task_index": self._task_index.copy(), "task_seed": self._task_seed.copy()}

    def _task_indices(self, options: dict | None) -> list[int] | None:
        if options is not None and not isinstance(options, dict):
            raise InvalidInputError(f"options must be a dict or None, got {type(options).__name__}")
        indices = (options or {}).get("task_index")
        if indices is None:
            return None
        if self._template.pool is None or np.ndim(indices) != 1 or len(indices) != self.num_envs:
            raise InvalidInputError(f"options['task_index'] = {indices!r}; allowed: a list of {self.num_envs} pool "
                                    "indices, one per copy, on a tier's pool")
        return [int(i) if isinstance(i, (int, np.integer)) and not isinstance(i, bool) else i for i in indices]

    def _apply_actions(self, a: np.ndarray, active: np.ndarray) -> np.ndarray:
        if not self._template.residual:
            return super()._apply_actions(a, active)
        benchmark, residuals = self._template.benchmark, np.zeros((self.num_envs, 12))
        for i in np.flatnonzero(active):
            fade = benchmark.residual_fade(self._K[i] * self.dt, self._rollouts[i].scenario.trajectory.motion_time_s)
            residuals[i] = fade * residual_rates(a[i], self._rollouts[i].scenario.env)
        return residuals

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        restarted = self._needs_reset.copy()
        active = self._advance_batch(actions)
        settings, N = self._template.benchmark, self.num_envs
        increments, costs = np.zeros(N), np.zeros(N)
        for i in np.flatnonzero(active):
            rows = int(self._rows[i])
            applied = self._applied[i, :rows]
            increments[i] = smoothness_cost(*smoothness_terms(applied, self.dt, self._previous_rates[i]), settings.score)
            window = slice(int(self._K[i]) - rows, int(self._K[i]))
            clearance = min(np.min(self._logs["clear"][i, window]), np.min(self._logs["self"][i, window]))
            costs[i] = self._template._violation_cost(applied, float(clearance))
        terminated = active & (self._status != 0)
        truncated = active & ~terminated & (self._K >= self.n_steps)
        infos = self._end_episodes(terminated, truncated, np.zeros(N))
        self._cost_so_far[restarted] = 0.0
        rewards, penalties = np.zeros(N), np.zeros(N)
        for i in np.flatnonzero(active):
            end = self._ended[i] if terminated[i] or truncated[i] else None
            rewards[i], penalties[i] = score_reward(self._cost_so_far[i], self._cost_so_far[i] + increments[i], end)
            self._cost_so_far[i] += increments[i]
        self._needs_reset = terminated | truncated
        obs, clearance, ee_error = self._observe()
        shaping = np.zeros(N)
        potential = -ee_error / settings.action.shaping_position_scale_m
        if self._dense_shaping:
            shaping = np.where(active, potential - self._potential, 0.0)
        self._potential = np.where(active | restarted, potential, self._potential)
        infos.update({"smoothness_increment": increments, "penalty": penalties, "shaping": shaping, "cost": costs,
                      "clearance_m": clearance, "ee_position_error_m": ee_error, "clipped_actions": self._clipped.copy()})
        return obs, np.where(active, rewards + shaping, 0.0), terminated, truncated, infos

    def _score_end(self, i: int, rollout: KernelRollout, truncated: bool) -> tuple[Any, float]:
        """The v1 score of copy ``i``'s finished episode (kept for its last reward); no extra penalty here."""
        self._ended[i] = score_episode(rollout.trajectory(), rollout.scenario, self._template.benchmark)
        return self._ended[i], 0.0


class FFSRResidualV1VectorEnv(FFSRV1VectorEnv):
    __doc__ = FFSRV1VectorEnv.__doc__
    single_env_class = FFSRResidualV1Env
