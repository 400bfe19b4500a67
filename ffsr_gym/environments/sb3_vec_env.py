"""stable-baselines3 on the batched kernel: a ``VecEnv`` over one :class:`FFSRVectorEnv`.

SB3 trains on a ``VecEnv``; Gymnasium's vector environments are not one (``PPO("MlpPolicy",
gymnasium.make_vec(...))`` is refused). :class:`BatchedVecEnv` speaks SB3's interface over the
batched environment in same-step autoreset mode: ``terminal_observation`` and
``TimeLimit.truncated`` in each copy's info, an ``episode`` record (return, length, time) as SB3's
``Monitor`` writes it, and ``seed(s)`` seeding copy i with s + i. Copy i then plays exactly what a
``make_vec_env`` of single environments plays in its i-th env (same tasks, observations, rewards;
tested through a whole PPO update), in one thread-parallel kernel call per step.

Importing this module needs stable-baselines3 (``pip install "ffsr-gym[rl]"``).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env import VecEnv

from ffsr_gym.environments.vector_env import FFSRVectorEnv, copy_info
from ffsr_gym.exceptions import InvalidInputError


class BatchedVecEnv(VecEnv):
    """An SB3 ``VecEnv`` of ``n_envs`` copies of a registered FFSR id, stepped by the batched kernel.

    Args:
        env_id: a registered id of a version with the batched environment (``ffsr-gym list``).
        n_envs: copies.
        threads: threads of the batched kernel (default: FFSR_GYM_THREADS, else every core).
        **env_kwargs: the id's ``gymnasium.make`` arguments (``task``, ``split``, ...).
    """

    def __init__(self, env_id: str, n_envs: int, *, threads: int | None = None, **env_kwargs: Any) -> None:
        from ffsr_gym.versions.registry import spec_of

        spec = spec_of(env_id)
        self.env_id = env_id
        self.venv = FFSRVectorEnv(n_envs, spec.version, spec.is_residual(env_id), threads=threads,
                                  autoreset_mode=AutoresetMode.SAME_STEP, **env_kwargs)
        super().__init__(self.venv.num_envs, self.venv.single_observation_space, self.venv.single_action_space)
        self._actions: np.ndarray | None = None
        self._returns = np.zeros(self.num_envs)
        self._lengths = np.zeros(self.num_envs, dtype=np.int64)
        self._start = time.time()

    def reset(self) -> np.ndarray:
        """Reset every copy: with the seeds of the last ``seed()`` (copy i: seed + i) once, then unseeded."""
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        options = self._options[0] if self._options and self._options[0] else None
        if options is not None and any(o != options for o in self._options):
            raise InvalidInputError("reset options differ between copies; the batched env takes one options dict")
        obs, _ = self.venv.reset(seed=seeds, options=options)
        self._reset_seeds()
        self._reset_options()
        self._returns[:], self._lengths[:] = 0.0, 0
        return obs

    def seed(self, seed: int | None = None) -> Sequence[None | int]:
        """Seed copy i with ``seed + i`` at the next reset (SB3's rule), after checking ``seed``.

        Raises:
            InvalidInputError: a seed that is not None or an integer >= 0.
        """
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
            raise InvalidInputError(f"seed = {seed!r}; allowed: None or an integer >= 0")
        return super().seed(None if seed is None else int(seed))

    def step_async(self, actions: np.ndarray) -> None:
        """Take one action per copy (checked for shape and values at ``step_wait``, as the batched env checks them)."""
        if actions is None:
            raise InvalidInputError(f"actions = None; allowed: an array of shape ({self.num_envs}, "
                                    f"{self.action_space.shape[0]}), one action per copy")
        self._actions = actions

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        dones = terminated | truncated
        self._returns += rewards
        self._lengths += 1
        infos = []
        for i in range(self.num_envs):
            if dones[i]:
                item = copy_info(info["final_info"], i)
                item["terminal_observation"] = info["final_obs"][i]
                item["episode"] = {"r": float(self._returns[i]), "l": int(self._lengths[i]),
                                   "t": round(time.time() - self._start, 6)}
                self._returns[i], self._lengths[i] = 0.0, 0
            else:
                item = copy_info(info, i)
            item["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            infos.append(item)
        return obs, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        """Copy 0's frame only (see :meth:`FFSRVectorEnv.render`), None for the others."""
        frame = self.venv.render() if self.venv.render_mode else None
        return [frame[0] if frame else None] + [None] * (self.num_envs - 1)

    def _copies(self, indices: Any) -> list[int]:
        """SB3's ``indices`` (None, an int or an iterable of ints) as a list of copies, each in [0, num_envs).

        Raises:
            InvalidInputError: an index that is not an integer, or one outside the copies.
        """
        chosen = list(self._get_indices(indices))
        bad = [i for i in chosen if isinstance(i, bool) or not isinstance(i, (int, np.integer))
               or not 0 <= i < self.num_envs]
        if bad:
            raise InvalidInputError(f"indices {bad[0]!r}; allowed: integers in [0, {self.num_envs - 1}] "
                                    f"(this adapter has {self.num_envs} copies)")
        return [int(i) for i in chosen]

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        """An attribute of the batched env, once per selected copy (the copies share one env)."""
        return [getattr(self.venv, attr_name)] * len(self._copies(indices))

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        raise InvalidInputError(f"set_attr({attr_name!r}): the copies share one batched env; create a new one instead")

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any) -> list[Any]:
        raise InvalidInputError(f"env_method({method_name!r}): the copies share one batched env; call "
                                f".venv.{method_name}(...) on it")

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        """No copy is wrapped (SB3's evaluation helpers then count episodes themselves)."""
        return [False] * len(self._copies(indices))
