"""The JAX episode as a Gymnasium ``VectorEnv``: N copies of a tier's pool stepped by one compiled call.

The same spaces, rewards and info keys as ``gymnasium.make_vec("FFSR-Residual-v2", ...)`` (or ``FFSR-v2`` with
``residual=False``), with Gymnasium's next-step autoreset. What differs: tasks are drawn from a JAX key (the reset
seed), so the sequence of tasks is not the kernel environments'; the episode-end ``paper_B`` is not computed by the
JAX loop (NaN); a copy runs to its end inside the compiled step, so nothing of the trajectory is kept.

Its inputs meet the kernel vector env's contract, checked by the same functions
(:mod:`ffsr_gym.environments.vector_inputs`, ``check_action``): seeds (an integer >= 0 or one per copy),
``options`` (``task_index``, one pool index per copy; ``reset_mask``; nothing else), actions (finite numbers of the
action's shape, clipped into [-1, 1] and counted), ``residual`` a bool; a closed env refuses to reset or step.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode

from ffsr_gym.environments.actions import check_action, observation_bounds
from ffsr_gym.environments.info import blank, failure_code, with_masks
from ffsr_gym.environments.vector_inputs import check_open, check_options, copy_seeds, reset_mask, task_indices
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.jax.copies import over_copies
from ffsr_gym.jax.episode import STATUS_COLLISION, STATUS_RATE
from ffsr_gym.jax.physics import jax, jnp
from ffsr_gym.jax.pool_env import PoolEnv
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.versions.registry import spec_for_version


class FFSRJaxVectorEnv(gymnasium.vector.VectorEnv):
    """``num_envs`` copies of a v2 tier's pool on the JAX loop.

    Args:
        num_envs: copies (>= 1).
        task: a kinematic tier (``easy``, ``medium``, ``hard``, ``debris``).
        split: pool (default ``train``).
        residual: residual actions (``FFSR-Residual-v2``), else (m, T_c) actions (``FFSR-v2``).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 8, *, task: str = "easy", split: str = "train", residual: bool = True) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise InvalidInputError(f"num_envs = {num_envs!r}; allowed: an integer >= 1")
        self.num_envs = int(num_envs)
        self.env = PoolEnv(task, split, residual=residual)
        self.spec_v2 = spec_for_version("v2")
        self.rule = score_rule(self.spec_v2)
        low, high = observation_bounds()
        self.single_observation_space = gymnasium.spaces.Box(low, high, dtype=np.float32)
        size = self.env.action_size
        self.single_action_space = gymnasium.spaces.Box(-1.0, 1.0, (size,), dtype=np.float32)
        self.observation_space = gymnasium.vector.utils.batch_space(self.single_observation_space, self.num_envs)
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, self.num_envs)
        self._reset = jax.jit(over_copies(self.env.reset))  # slices of at most 512 copies: ffsr_gym.jax.copies
        self._reset_task = jax.jit(over_copies(self.env.reset_task))
        self._step = jax.jit(over_copies(self.env.step))
        self._key, self._state, self._ended = jax.random.PRNGKey(0), None, np.zeros(self.num_envs, bool)
        self._clipped = np.zeros(self.num_envs, np.int64)

    def _forced(self, options: dict | None) -> list[int] | None:
        """``options["task_index"]``, each inside the pool, or None."""
        forced = task_indices(options, self.num_envs, pooled=True)
        bad = [i for i in forced or () if not (isinstance(i, int) and 0 <= i < self.env.n_tasks)]
        if bad:
            raise InvalidInputError(f"options['task_index'] = {str(bad[0])[:40]}; allowed: integers in "
                                    f"[0, {self.env.n_tasks - 1}] ({self.env.tier}/{self.env.split} holds "
                                    f"{self.env.n_tasks} tasks)")
        return forced

    def _fresh(self, seeds: list[int | None], per_copy: bool, forced: list[int] | None) -> Any:
        """New states of every copy: at the forced tasks when ``task_index`` names them, else drawn from keys: an
        integer seed starts the key stream, a list (``per_copy``) gives each copy its own key."""
        if not per_copy and seeds[0] is not None:
            self._key = jax.random.PRNGKey(seeds[0])
        self._key, sub = jax.random.split(self._key)
        if forced is not None:
            return self._reset_task(jnp.asarray(forced))
        keys = jax.random.split(sub, self.num_envs)
        if per_copy:
            keys = jnp.stack([keys[i] if s is None else jax.random.PRNGKey(s) for i, s in enumerate(seeds)])
        return self._reset(keys)

    @staticmethod
    def _merge(mask: np.ndarray, new: Any, old: Any) -> Any:
        where = jnp.asarray(mask)
        return jax.tree.map(lambda a, b: jnp.where(where.reshape((-1,) + (1,) * (b.ndim - 1)), a, b), new, old)

    def reset(self, *, seed: Any = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        check_open(self)
        check_options(options, ("reset_mask", "task_index"), self.spec_v2)
        mask = reset_mask(options, self.num_envs, self._state is not None)
        forced, seeds = self._forced(options), copy_seeds(seed, self.num_envs)  # every input checked before any state
        fresh = self._fresh(seeds, isinstance(seed, (list, tuple, np.ndarray)), forced)
        self._state = fresh if self._state is None else self._merge(mask, fresh, self._state)
        self._ended[mask], self._clipped[mask] = False, 0
        arrays = self._info(self._state, np.zeros(self.num_envs, bool))
        return np.asarray(self._state.obs), with_masks(arrays, mask)

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        check_open(self)
        if self._state is None:
            raise InvalidInputError("call reset() before step()")
        actions, clipped = check_action(actions, self.action_space.shape)
        actions = actions.astype(np.float64)
        if np.any(self._ended):  # Gymnasium's next-step autoreset: those copies start anew, ignoring the action
            self._key, sub = jax.random.split(self._key)
            self._state = self._merge(self._ended, self._reset(jax.random.split(sub, self.num_envs)), self._state)
            self._clipped[self._ended] = 0
        was_reset = self._ended.copy()
        self._state = self._merge(was_reset, self._state, self._step(self._state, jnp.asarray(actions)))
        self._clipped += np.where(was_reset, 0, clipped)
        done = np.asarray(self._state.done) > 0.5
        terminated = done & (np.asarray(self._state.pipeline_state.status) != 0) & ~was_reset
        truncated = done & ~terminated & ~was_reset
        reward = np.where(was_reset, 0.0, np.asarray(self._state.reward, dtype=np.float64))
        arrays = self._info(self._state, terminated | truncated)
        self._ended = terminated | truncated
        return (np.asarray(self._state.obs), reward, terminated, truncated, with_masks(arrays, np.ones(self.num_envs,
                                                                                                        bool)))

    def _info(self, state: Any, ended: np.ndarray) -> dict[str, np.ndarray]:
        """The info contract's arrays (``ffsr_gym.environments.info``) of the copies."""
        arrays = blank(self.rule, self.num_envs)
        episode = state.pipeline_state
        index = np.asarray(state.info["task_index"])
        arrays["task_index"][:] = index
        arrays["task_seed"][:] = [self.env.records[int(i)].seed for i in index]
        arrays["clipped_actions"][:] = self._clipped
        for key in ("clearance_m", "ee_position_error_m", "smoothness_increment", "cost", "penalty"):
            arrays[key][:] = np.asarray(state.info[key])
        arrays["episode_end"][:] = ended
        status = np.asarray(episode.status)
        success = np.asarray(state.metrics["success"]) > 0.5
        arrays["score"][:] = np.where(ended, np.asarray(state.metrics["score"], dtype=np.float64), 0.0)
        arrays["success"][:] = ended & success
        failure = np.where(status == STATUS_RATE, failure_code("rate_limit"), np.where(
            status == STATUS_COLLISION, failure_code("collision"), failure_code("final_error")))
        arrays["failure"][:] = np.where(ended & ~success, failure, 0)
        arrays["smoothness_cost"][:] = np.where(ended, np.asarray(episode.cost), 0.0)
        arrays["paper_B"][:] = np.where(ended, np.nan, 0.0)  # not computed by the JAX loop
        return arrays
