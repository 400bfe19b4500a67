"""Batched ``FFSR-v1`` / ``FFSR-Residual-v1``: the v1 episodes, stepped by one kernel call for all copies.

``gymnasium.make_vec("FFSR-Residual-v1", num_envs=64, task="easy", vectorization_mode="vector_entry_point")``
gives the same episodes as 64 single environments seeded ``seed, seed + 1, ...`` (tested bit for
bit): each copy draws its tasks from the pool with its own generator, the residual fades with
the copy's own time, every copy's decision runs the single environment's compiled decision
(:func:`ffsr_gym.kernel.batch.decide_batch` over :func:`ffsr_gym.kernel.decision.decide`), and
rewards and episode scores come from :mod:`ffsr_gym.scoring.score`, called per copy exactly as
the single environment calls them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode

from ffsr_gym.environments.env import assemble_observation, check_action
from ffsr_gym.environments.env_v1 import END_INFO_V1, FFSRResidualV1Env, FFSRV1Env, decision_settings
from ffsr_gym.environments.vector_env import FFSRVectorEnv
from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.kernel import batch as kernel_batch
from ffsr_gym.kernel import decision
from ffsr_gym.kernel import planner as kp
from ffsr_gym.model import portable
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.scoring.score import running_reward, score_episode, score_reward
from ffsr_gym.sim.compiled import LOG_FIELDS, KernelRollout


class FFSRV1VectorEnv(FFSRVectorEnv):
    """``num_envs`` copies of :class:`~ffsr_gym.environments.env_v1.FFSRV1Env` (spaces, rewards, info keys: see there).

    Arguments as the single environment (``task``, ``split``, ``dense_shaping``) plus ``threads``;
    ``terminate_on_violation`` must stay True (the batched kernel stops a copy at its first
    violation). Autoreset is Gymnasium's next-step mode, or with
    ``autoreset_mode=AutoresetMode.DISABLED`` none: a copy whose episode ended holds (not stepped,
    reward 0, its end reported once) until the next ``reset()``, which resets every copy (no
    ``reset_mask``); scoring one episode per task wastes no physics that way. ``reset(seed=s)``
    seeds copy i with s + i. ``reset``'s info has ``task_index`` and ``task_seed`` per copy (-1 on ``paper``);
    episode-end keys (``score``, ``success``, ``failure``, ``smoothness_cost``, ``paper_B``) come
    with their ``_key`` masks.
    """

    single_env_class: type[FFSRV1Env] = FFSRV1Env
    end_keys = END_INFO_V1

    def __init__(self, num_envs: int, task: str | Scenario = "paper", split: str = "train", *, threads: int | None = None,
                 backend: str = "kernel", render_mode: str | None = None, max_episode_steps: int | None = None,
                 terminate_on_violation: bool = True, dense_shaping: bool = False,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP) -> None:
        modes = {mode.value: mode for mode in (AutoresetMode.NEXT_STEP, AutoresetMode.DISABLED)}
        mode = modes.get(autoreset_mode.value if isinstance(autoreset_mode, AutoresetMode) else autoreset_mode)
        if mode is None:
            raise InvalidInputError(f"autoreset_mode {autoreset_mode!r}; allowed: {list(modes)}")
        self.metadata = {**self.metadata, "autoreset_mode": mode}
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
        self._DS = np.zeros((self.num_envs, decision.N_DS))
        self._SCRATCH = np.zeros((self.num_envs, decision.N_SCRATCH))
        self._workspaces = None  # one kernel workspace per copy, made at the first step
        self._OBS = np.zeros((self.num_envs, decision.N_OBS), dtype=np.float32)
        self._out = np.zeros((self.num_envs, 7))

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
        if isinstance(options, dict) and "reset_mask" in options:
            raise InvalidInputError("options['reset_mask']: partial resets are not supported; reset() resets every copy")
        self._forced_index = self._task_indices(options)
        try:
            super().reset(seed=seed, options=options)
        finally:
            self._forced_index = None
        self._cost_so_far[:] = 0.0
        return self._OBS.copy(), {"task_index": self._task_index.copy(), "task_seed": self._task_seed.copy()}

    def _reset_one(self, i: int) -> None:
        """Copy ``i``'s next episode, its decision settings and its first observation."""
        super()._reset_one(i)
        rollout = self._rollouts[i]
        decision.forget_plan(self._SCRATCH[i])
        self._DS[i] = decision_settings(rollout.scenario, self._template.benchmark)
        angles, e1, e0, rel, clear = rollout.observation()
        self._OBS[i] = assemble_observation(angles, self._last_rates[i], e1, e0, rel, clear, 0.0)
        self._out[i, 5], self._out[i, 6] = clear, portable.norm(e1[:3])
        self._potential[i] = -self._out[i, 6] / self._template.benchmark.action.shaping_position_scale_m

    def __getstate__(self) -> dict:
        """Pickled without the per-copy kernel workspaces (numba structures): the clone makes new ones
        and its copies' next decisions plan afresh (same numbers)."""
        state = self.__dict__.copy()
        state["_workspaces"], state["_SCRATCH"] = None, self._SCRATCH.copy()
        decision.forget_plan(state["_SCRATCH"])
        return state

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

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        if self._mdl is None:
            raise InvalidInputError("call reset() before step()")
        a, was_clipped = check_action(actions, self.action_space.shape)
        active = ~self._needs_reset
        restarted = self._needs_reset.copy() if self.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP \
            else np.zeros(self.num_envs, dtype=bool)
        self._clipped += was_clipped
        for i in np.flatnonzero(restarted):
            self._reset_one(i)
        out, mode = self._out, self._mode(active)
        out[~active, :5] = 0.0  # no steps, no cost; clearance and EE error of the reset (or held) state stay
        if self._workspaces is None:
            self._workspaces = kernel_batch.workspaces(self.num_envs, len(self._mdl[13]))
        kernel_batch.decide_batch(self._mdl, self._plants, self._workspaces, self._X, self._K, active, self.n_steps,
                                  self.steps_per_decision, self._FP, self._IP, self._DS, a, mode,
                                  tuple(self._logs[key] for key in LOG_FIELDS), self._last_rates, self._SCRATCH,
                                  self._OBS, out, kernel_batch.groups(self.num_envs))
        self._rows, self._status = out[:, 0].astype(np.int64), out[:, 1].astype(np.int64)
        if np.any(self._status == 3):
            raise FFSRError(f"planner produced non-finite joint rates in copies {np.flatnonzero(self._status == 3).tolist()}")
        N, increments, costs = self.num_envs, out[:, 3].copy(), out[:, 4].copy()
        terminated = active & (self._status != 0)
        truncated = active & ~terminated & (self._K >= self.n_steps)
        infos = self._end_episodes(terminated, truncated, np.zeros(N))
        self._cost_so_far[restarted] = 0.0
        before = self._cost_so_far
        after = before + increments  # inactive copies: increment 0
        rewards, penalties = np.where(active, running_reward(before, after), 0.0), np.zeros(N)
        for i in np.flatnonzero(terminated | truncated):
            rewards[i], penalties[i] = score_reward(before[i], after[i], self._ended[i])
        self._cost_so_far = np.where(active, after, before)
        self._needs_reset = (self._needs_reset & ~restarted) | terminated | truncated
        clearance, ee_error = out[:, 5].copy(), out[:, 6].copy()
        potential = -ee_error / self._template.benchmark.action.shaping_position_scale_m
        shaping = np.where(active, potential - self._potential, 0.0) if self._dense_shaping else np.zeros(N)
        self._potential = np.where(active, potential, self._potential)
        infos.update({"smoothness_increment": increments, "penalty": penalties, "shaping": shaping, "cost": costs,
                      "clearance_m": clearance, "ee_position_error_m": ee_error, "clipped_actions": self._clipped.copy()})
        return self._OBS.copy(), np.where(active, rewards + shaping, 0.0), terminated, truncated, infos

    def _mode(self, active: np.ndarray) -> int:
        """The compiled decision's action mode; sets (m, T_c) for ``step_with_parameters`` (validated per copy)."""
        if self._template.residual:
            return decision.MODE_RESIDUAL
        if self._parameters is None:
            return decision.MODE_PARAMETERS
        for i in np.flatnonzero(active):
            rollout = self._rollouts[i]
            rollout.set_parameters(*self._parameters)
            self._FP[i, kp.F_M], self._FP[i, kp.F_TC] = rollout.fp[kp.F_M], rollout.fp[kp.F_TC]
        return decision.MODE_SET

    def _score_end(self, i: int, rollout: KernelRollout, truncated: bool) -> tuple[Any, float]:
        """The v1 score of copy ``i``'s finished episode (kept for its last reward); no extra penalty here."""
        self._ended[i] = score_episode(rollout.trajectory(), rollout.scenario, self._template.benchmark)
        return self._ended[i], 0.0


class FFSRResidualV1VectorEnv(FFSRV1VectorEnv):
    __doc__ = FFSRV1VectorEnv.__doc__
    single_env_class = FFSRResidualV1Env
