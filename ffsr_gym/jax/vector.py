"""The JAX episode as a Gymnasium ``VectorEnv``: N copies of a tier's pool stepped by one compiled call.

The same spaces, rewards and info keys as ``gymnasium.make_vec("FFSR-Residual-v2", ...)`` (or ``FFSR-v2`` with
``residual=False``), with Gymnasium's next-step autoreset. What differs: tasks are drawn from a JAX key (the reset
seed), so the sequence of tasks is not the kernel environments'; the episode-end ``paper_B`` is not computed by the
JAX loop (NaN); a copy runs to its end inside the compiled step, so nothing of the trajectory is kept.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode

from ffsr_gym.environments.actions import observation_bounds
from ffsr_gym.environments.info import blank, failure_code, with_masks
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.jax.brax_env import FFSRBraxEnv
from ffsr_gym.jax.copies import over_copies
from ffsr_gym.jax.episode import STATUS_COLLISION, STATUS_RATE
from ffsr_gym.jax.physics import jax, jnp
from ffsr_gym.model.spec import spec_for_version
from ffsr_gym.scoring.rules import score_rule


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
        self.env = FFSRBraxEnv(task, split, residual=residual)
        self.rule = score_rule(spec_for_version("v2"))
        low, high = observation_bounds()
        self.single_observation_space = gymnasium.spaces.Box(low, high, dtype=np.float32)
        size = self.env.action_size
        self.single_action_space = gymnasium.spaces.Box(-1.0, 1.0, (size,), dtype=np.float32)
        self.observation_space = gymnasium.vector.utils.batch_space(self.single_observation_space, self.num_envs)
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, self.num_envs)
        self._reset = jax.jit(over_copies(self.env.reset))  # slices of at most 512 copies: ffsr_gym.jax.copies
        self._step = jax.jit(over_copies(self.env.step))
        self._key, self._state, self._ended = jax.random.PRNGKey(0), None, np.zeros(self.num_envs, bool)
        self._clipped = np.zeros(self.num_envs, np.int64)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        if seed is not None:
            self._key = jax.random.PRNGKey(int(seed))
        self._key, sub = jax.random.split(self._key)
        self._state = self._reset(jax.random.split(sub, self.num_envs))
        self._ended[:], self._clipped[:] = False, 0
        arrays = self._info(self._state, np.zeros(self.num_envs, bool))
        return np.asarray(self._state.obs), with_masks(arrays, np.ones(self.num_envs, bool))

    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        if self._state is None:
            raise InvalidInputError("step before reset; call reset() first")
        actions = np.asarray(actions, dtype=np.float64)
        if actions.shape != self.action_space.shape or not np.all(np.isfinite(actions)):
            raise InvalidInputError(f"actions must be finite, of shape {self.action_space.shape}; allowed range "
                                    f"[-1, 1] per entry, got shape {actions.shape}")
        clipped = np.any(np.abs(actions) > 1.0, axis=1)
        if np.any(self._ended):  # Gymnasium's next-step autoreset: those copies start anew, ignoring the action
            self._key, sub = jax.random.split(self._key)
            fresh = self._reset(jax.random.split(sub, self.num_envs))
            mask = jnp.asarray(self._ended)
            self._state = jax.tree.map(lambda new, old: jnp.where(mask.reshape((-1,) + (1,) * (old.ndim - 1)), new,
                                                                  old), fresh, self._state)
            self._clipped[self._ended] = 0
        was_reset = self._ended.copy()
        stepped = self._step(self._state, jnp.asarray(actions))
        self._state = jax.tree.map(lambda new, old: jnp.where(
            jnp.asarray(was_reset).reshape((-1,) + (1,) * (old.ndim - 1)), old, new), stepped, self._state)
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
