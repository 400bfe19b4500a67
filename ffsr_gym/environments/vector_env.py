"""Batched ``FFSR-v0`` / ``FFSR-Residual-v0``: N episodes stepped by one thread-parallel kernel call.

``gymnasium.make_vec("FFSR-Residual-v0", num_envs=64, vectorization_mode="vector_entry_point")``
gives the same episodes as 64 single environments seeded ``seed, seed + 1, ...`` (tested step by
step), without one Python ``step`` per copy: the physics of all copies runs in
:func:`ffsr_gym.kernel.batch.run_batch`, rewards come from the batched objective terms, and only
episode ends (the objective of the whole trajectory) are handled per copy.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numba
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from ffsr_gym.environments.env import FFSREnv, FFSRResidualEnv, assemble_observation, check_action
from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.kernel import batch as kernel_batch
from ffsr_gym.kernel import planner as kp
from ffsr_gym.model.scenario import Scenario, load_scenario, residual_rates
from ffsr_gym.scoring.objective import objective_terms, rate_terms, smooth_part
from ffsr_gym.sim.compiled import LOG_FIELDS, KernelRollout, new_log
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.tasks.random_family import sample_scenario


class FFSRVectorEnv(gym.vector.VectorEnv):
    """``num_envs`` copies of :class:`~ffsr_gym.environments.env.FFSREnv` (spaces, rewards, info keys: see there).

    Autoreset is Gymnasium's next-step mode: the step after an episode ends resets that copy (its
    action is ignored, reward 0). ``reset(seed=s)`` seeds copy i with s + i. Episode-end info keys
    (``objective``, ``feasible``, ``score``, ``rate_violation``, ``collided``) come with their
    ``_key`` masks. ``threads`` sets numba's thread count (default: all cores). Memory: one
    full-episode trajectory buffer per copy (~1 MB at dt = 0.01 s, 20 s).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": ["rgb_array"], "render_fps": 10}
    single_env_class: type[FFSREnv] = FFSREnv
    #: Episode-end ``info`` keys (attributes of :meth:`_score_end`'s result) and their dtypes.
    end_keys: dict[str, type] = {"objective": float, "feasible": bool, "score": float, "rate_violation": bool,
                                 "collided": bool}

    def __init__(self, num_envs: int, scenario: str | Scenario = "paper", *, threads: int | None = None,
                 backend: str = "kernel", render_mode: str | None = None, max_episode_steps: int | None = None) -> None:
        if not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise InvalidInputError(f"num_envs must be a positive integer, got {num_envs!r}")
        if backend not in ("auto", "kernel"):
            raise InvalidInputError(f"backend {backend!r}; the batched environments run on the kernel: 'auto' or 'kernel'")
        if render_mode not in (None, "rgb_array"):
            raise InvalidInputError(f"render_mode {render_mode!r}; allowed: 'rgb_array' (draws copy 0 only) or None")
        self.render_mode, self._renderer = render_mode, None
        if max_episode_steps is not None:
            raise InvalidInputError("max_episode_steps: episodes end at the scenario's simulation.duration_s; use None")
        if threads is not None:
            if not 1 <= threads <= numba.config.NUMBA_NUM_THREADS:
                raise InvalidInputError(f"threads = {threads}; allowed: 1 to {numba.config.NUMBA_NUM_THREADS}")
            numba.set_num_threads(threads)
        self._template = self._make_template(scenario)
        self.family = self._template.family
        self.num_envs = int(num_envs)
        self.single_action_space = self._template.action_space
        self.single_observation_space = self._template.observation_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.steps_per_decision = self._template.steps_per_decision
        n, N = self.family.n_steps, self.num_envs
        self.n_steps, self.dt = n, self.family.simulation.dt_s
        self._X, self._K = np.zeros((N, 19)), np.zeros(N, dtype=np.int64)
        self._FP, self._IP = np.zeros((N, kp.N_FP)), np.zeros((N, kp.N_IP), dtype=np.int64)
        self._plants = (np.zeros((N, 13)), np.zeros((N, 13, 3)), np.zeros((N, 13, 3, 3)))  # each copy's plant inertias
        self._logs = new_log(n + 1, N)
        self._rows, self._status = np.zeros(N, dtype=np.int64), np.zeros(N, dtype=np.int64)
        self._applied = np.zeros((N, self.steps_per_decision, 12))
        self._last_rates, self._clipped = np.zeros((N, 12)), np.zeros(N, dtype=np.int64)
        self._rollouts: list[KernelRollout | None] = [None] * N
        self._rngs: list[np.random.Generator | None] = [None] * N
        self._needs_reset = np.zeros(N, dtype=bool)
        self._mdl = None
        self._parameters: tuple[float, float] | None = None

    def _make_template(self, scenario: str | Scenario) -> FFSREnv:
        """The single environment whose spaces, mapping and episode scenarios the copies share."""
        return self.single_env_class(load_scenario(scenario), backend="kernel")

    # ---------------------------------------------------------------------------- episodes
    def _episode_scenario(self, i: int) -> Scenario:
        """Copy ``i``'s next episode scenario, drawn from its own generator as the single env draws it."""
        return sample_scenario(self.family, self._rngs[i]) if self.family.randomization is not None else self.family

    def _reset_one(self, i: int) -> None:
        scenario = self._episode_scenario(i)
        if scenario.n_steps != self.n_steps or scenario.simulation.dt_s != self.dt:
            raise FFSRError("a randomised scenario changed dt_s or duration_s; the batch needs them fixed")
        rollout = KernelRollout(scenario, log={key: self._logs[key][i] for key in LOG_FIELDS})
        self._rollouts[i], self._mdl = rollout, rollout._mdl
        if len(rollout.fp) > self._FP.shape[1]:  # more target estimates than any copy so far: widen the rows
            wider = np.zeros((self.num_envs, len(rollout.fp)))
            wider[:, :self._FP.shape[1]] = self._FP
            self._FP = wider
        self._X[i], self._K[i], self._IP[i] = rollout.x, 0, rollout.ip
        self._FP[i, :len(rollout.fp)], self._FP[i, len(rollout.fp):] = rollout.fp, 0.0
        for stacked, own in zip(self._plants, rollout.plant):
            stacked[i] = own
        self._last_rates[i], self._clipped[i] = 0.0, 0

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        seeds = self._copy_seeds(seed)
        super().reset(seed=seeds[0] if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) else None)
        for i, s in enumerate(seeds):
            if s is not None or self._rngs[i] is None:
                self._rngs[i] = seeding.np_random(s)[0]
            self._reset_one(i)
        self._needs_reset[:] = False
        return self._observe()[0], {}

    def _advance_batch(self, actions: Any) -> np.ndarray:
        """Check the actions, reset the copies that ended, step the physics; returns the copies that moved.

        ``self._previous_rates`` keeps the rates applied before this step.
        """
        if self._mdl is None:
            raise InvalidInputError("call reset() before step()")
        a, was_clipped = check_action(actions, self.action_space.shape)
        self._clipped += was_clipped
        active = ~self._needs_reset
        for i in np.flatnonzero(self._needs_reset):
            self._reset_one(i)
        residuals = self._apply_actions(a, active)
        logs = tuple(self._logs[key] for key in LOG_FIELDS)
        kernel_batch.run_batch(self._mdl, self._plants, self._X, self._K, active, self.n_steps, self.steps_per_decision,
                               self._FP, self._IP, residuals, logs, self._rows, self._status, self._applied,
                               kernel_batch.groups(self.num_envs))
        if np.any(self._status == 3):
            raise FFSRError(f"planner produced non-finite joint rates in copies {np.flatnonzero(self._status == 3).tolist()}")
        moved = np.flatnonzero(active)
        self._previous_rates = self._last_rates.copy()
        self._last_rates[moved] = self._applied[moved, self._rows[moved] - 1]
        return active

    def _copy_seeds(self, seed: Any) -> list[int | None]:
        """Per-copy seeds of ``reset(seed=...)``: an int s gives s, s + 1, ...; a list gives one per copy.

        Raises:
            InvalidInputError: anything else, naming what is allowed.
        """
        def is_seed(x: Any) -> bool:
            return isinstance(x, (int, np.integer)) and not isinstance(x, bool) and int(x) >= 0

        if seed is None:
            return [None] * self.num_envs
        if is_seed(seed):
            return [int(seed) + i for i in range(self.num_envs)]
        if isinstance(seed, (list, tuple, np.ndarray)) and len(seed) == self.num_envs \
                and all(s is None or is_seed(s) for s in seed):
            return [None if s is None else int(s) for s in seed]
        raise InvalidInputError(f"seed = {seed!r}; allowed: None, a non-negative integer, or a list of {self.num_envs} "
                                "such integers (or None), one per copy")

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        active = self._advance_batch(actions)
        objective = self.family.objective
        increments = np.where(active, smooth_part(*rate_terms(self._applied, self.dt, objective)[:2], objective), 0.0)
        terminated = active & (self._status != 0)
        truncated = active & ~terminated & (self._K >= self.n_steps)
        penalties = np.where(terminated, self.family.env.violation_penalty, 0.0)
        infos = self._end_episodes(terminated, truncated, penalties)
        self._needs_reset = terminated | truncated
        obs, clearance, ee_error = self._observe()
        infos.update({"objective_increment": increments, "penalty": penalties, "cost": terminated.astype(float),
                      "clearance_m": clearance, "ee_position_error_m": ee_error, "clipped_actions": self._clipped.copy()})
        return obs, np.where(active, -increments - penalties, 0.0), terminated, truncated, infos

    def step_with_parameters(self, m: float, T_c: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """A step of every copy with physical (m, T_c [s]), no float32 rounding: the single env's
        ``step_with_parameters`` batched (the (m, T_c) ids only)."""
        if self._template.residual:
            raise InvalidInputError("step_with_parameters is for the (m, T_c) envs (FFSR-v0, FFSR-v1), not a residual env")
        self._parameters = (float(m), float(T_c))
        try:
            return self.step(np.zeros((self.num_envs, 2), dtype=np.float32))
        finally:
            self._parameters = None

    def _apply_actions(self, a: np.ndarray, active: np.ndarray) -> np.ndarray:
        """Residual joint rates [rad/s] (N, 12) for ``FFSR-Residual-v0``; sets (m, T_c) for ``FFSR-v0``."""
        if self._template.residual:
            return residual_rates(a, self.family.env)
        for i in np.flatnonzero(active):  # float64 parameters exactly as the single env maps them
            rollout = self._rollouts[i]
            rollout.set_parameters(*(self._parameters or self._template.action_to_parameters(a[i])))
            self._FP[i, kp.F_M], self._FP[i, kp.F_TC] = rollout.fp[kp.F_M], rollout.fp[kp.F_TC]
        return np.zeros((self.num_envs, 12))

    def _end_episodes(self, terminated: np.ndarray, truncated: np.ndarray, penalties: np.ndarray) -> dict[str, Any]:
        """Score every finished episode from its whole trajectory (:meth:`_score_end`); adds the horizon
        penalty to ``penalties`` in place; returns the ``end_keys`` info arrays with their masks."""
        ended = {key: np.zeros(self.num_envs, dtype=dtype) for key, dtype in self.end_keys.items()}
        for i in np.flatnonzero(terminated | truncated):
            rollout = self._synced_rollout(i)
            rollout.finish()
            result, penalty = self._score_end(i, rollout, bool(truncated[i]))
            penalties[i] += penalty
            for key in self.end_keys:
                ended[key][i] = getattr(result, key)
        mask = terminated | truncated
        infos: dict[str, Any] = {}
        for key, values in ended.items():
            infos[key], infos[f"_{key}"] = values, mask.copy()
        return infos

    def _score_end(self, i: int, rollout: KernelRollout, truncated: bool) -> tuple[Any, float]:
        """Copy ``i``'s finished episode's score terms, and the horizon penalty to add (as the single env)."""
        terms = objective_terms(rollout.trajectory(), rollout.scenario.objective)
        return terms, self.family.env.tolerance_penalty if truncated and not terms.final_errors_ok else 0.0

    def _observe(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        N = self.num_envs
        E1, E0, REL, CLEAR = np.zeros((N, 6)), np.zeros((N, 6)), np.zeros((N, 3)), np.zeros(N)
        kernel_batch.observe_batch(self._mdl, self._X, self._K, self._FP, self._IP, E1, E0, REL, CLEAR,
                                   kernel_batch.groups(N))
        obs = assemble_observation(self._X[:, 7:19], self._last_rates, E1, E0, REL, CLEAR, self._K / self.n_steps)
        return obs, CLEAR, np.linalg.norm(E1[:, :3], axis=1)

    def trajectory(self, i: int) -> Trajectory:
        """The :class:`~ffsr_gym.sim.trajectory.Trajectory` of copy ``i``'s current episode (samples so far)."""
        if not 0 <= i < self.num_envs:
            raise InvalidInputError(f"copy {i}; allowed: 0 to {self.num_envs - 1}")
        if self._rollouts[i] is None:
            raise InvalidInputError("no episode yet: call reset()")
        return self._synced_rollout(i).trajectory()

    def render(self) -> tuple[np.ndarray, ...] | None:
        """Copy 0's current frame, as a tuple of one (H, W, 3) array; the other copies are not drawn
        (drawing is ~10 ms per frame). None, with a warning, without ``render_mode="rgb_array"``."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' to make_vec")
            return None
        if self._rollouts[0] is None:
            raise InvalidInputError("call reset() before render()")
        from ffsr_gym.environments.render import SceneRenderer

        if self._renderer is None:
            self._renderer = SceneRenderer()
        rollout = self._synced_rollout(0)
        return (self._renderer.draw(rollout, rollout.scenario),)

    def close_extras(self, **kwargs: Any) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def _synced_rollout(self, i: int) -> KernelRollout:
        """Copy ``i``'s rollout with the batch's state (an unfinished episode: one logged row per step)."""
        rollout = self._rollouts[i]
        if not rollout.finished:
            rollout.x, rollout.k, rollout.rows = self._X[i].copy(), int(self._K[i]), int(self._K[i])
            rollout.fp[:] = self._FP[i, :len(rollout.fp)]  # (m, T_c) the batch set
        return rollout



class FFSRResidualVectorEnv(FFSRVectorEnv):
    __doc__ = FFSRVectorEnv.__doc__
    single_env_class = FFSRResidualEnv
