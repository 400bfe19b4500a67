"""The batched Gymnasium environment of every benchmark version: an adapter over N engine copies.

``gymnasium.make_vec(id, num_envs=64, vectorization_mode="vector_entry_point", ...)`` gives the
same episodes as 64 single environments seeded ``seed, seed + 1, ...`` (tested bit for bit): each
copy draws its tasks with its own generator, every copy's decision runs the single environment's
compiled decision in one thread-parallel kernel call, and rewards and episode scores come from
the same score rule, per copy.
"""

from __future__ import annotations

import os
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from ffsr_gym.environments import info as info_contract
from ffsr_gym.environments.actions import check_action, observation_bounds, physical_command, physical_parameters
from ffsr_gym.environments.engine import EpisodeEngine
from ffsr_gym.environments.env import task_options
from ffsr_gym.environments.task_source import TaskSource
from ffsr_gym.environments.vector_inputs import check_open, check_options, copy_seeds, reset_mask, task_indices
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.versions.registry import spec_for_version

_MODES = {mode.value: mode for mode in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED)}


def copy_info(info: dict[str, Any], i: int) -> dict[str, Any]:
    """Copy ``i``'s part of a batched ``info`` (a key whose ``_key`` mask is False for it is left out)."""
    return {key: value[i] for key, value in info.items()
            if not key.startswith("_") and (f"_{key}" not in info or info[f"_{key}"][i])}



#: The variable that sets the batched environments' default thread count (a cluster piece sets it to its share).
THREADS_VARIABLE = "FFSR_GYM_THREADS"


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity where the platform tells it)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def default_threads(cores: int) -> int:
    """The batched environments' threads when none are asked for: ``FFSR_GYM_THREADS`` (bounded by ``cores``),
    else every core."""
    text = os.environ.get(THREADS_VARIABLE, "").strip()
    if not text:
        return cores
    if not text.isdigit() or int(text) < 1:
        raise InvalidInputError(f"{THREADS_VARIABLE} = {text!r}; allowed: an integer >= 1 (unset: every core)")
    return min(int(text), cores)

class FFSRVectorEnv(gym.vector.VectorEnv):
    """``num_envs`` copies of :class:`~ffsr_gym.environments.env.FFSREnv` (spaces, rewards, info keys: see there).

    Arguments as the single environment plus ``threads`` (the threads the copies are stepped on, default
    ``FFSR_GYM_THREADS`` or else every core); ``terminate_on_violation`` must stay True (the batched kernel stops a copy at its first
    violation). Autoreset is Gymnasium's next-step mode; with ``AutoresetMode.SAME_STEP`` a copy
    whose episode ended is reset in the same step (its last observation in ``info["final_obs"]``, an
    object array, and its last info in ``info["final_info"]``, a dict of masked arrays, as Gymnasium's
    ``SyncVectorEnv`` gives them;
    what stable-baselines3 expects, :mod:`ffsr_gym.environments.sb3_vec_env`); with
    ``AutoresetMode.DISABLED`` none: a copy whose episode ended holds (not stepped, reward 0, its
    end reported once) until a ``reset()``, of every copy or of those of ``options={"reset_mask": ...}``
    (a bool array, as Gymnasium's vector envs take it). ``reset(seed=s)`` seeds copy i with s + i;
    ``options={"task_index": [...]}``
    picks each copy's pool task of this reset. Every info has every key of the info contract
    (:mod:`ffsr_gym.environments.info`) as an array with its ``_key`` mask, as ``SyncVectorEnv`` gives them.
    Memory: a copy keeps its state and its episode's score totals, a few kB (docs/kernel.md); with
    ``record_trajectories=True`` (or a ``render_mode``, or a rule that scores from the trajectory: v0's, a capture
    rule's) also its whole trajectory, ~1 MB at dt = 0.01 s over 20 s, which :meth:`trajectory` reads.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, num_envs: int, version: str = "v2", residual: bool = False, *, threads: int | None = None,
                 backend: str = "kernel", render_mode: str | None = None, max_episode_steps: int | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP, record_trajectories: bool = False,
                 **options: Any) -> None:
        spec = spec_for_version(version)
        options = task_options(spec, options)
        if not isinstance(num_envs, (int, np.integer)) or isinstance(num_envs, bool) or num_envs < 1:
            raise InvalidInputError(f"num_envs must be a positive integer, got {num_envs!r}")
        if backend not in ("auto", "kernel"):
            raise InvalidInputError(f"backend {backend!r}; the batched environments run on the kernel: 'auto' or 'kernel'")
        if render_mode not in (None, "rgb_array"):
            raise InvalidInputError(f"render_mode {render_mode!r}; allowed: 'rgb_array' (draws copy 0 only) or None")
        mode = _MODES.get(autoreset_mode.value if isinstance(autoreset_mode, AutoresetMode) else autoreset_mode)
        if mode is None:
            raise InvalidInputError(f"autoreset_mode {autoreset_mode!r}; allowed: {list(_MODES)}")
        if options.get("terminate_on_violation", True) is not True:
            raise InvalidInputError("terminate_on_violation: the batched environments stop a copy at its first "
                                    "violation; use True, or the single environment for False")
        cores = available_cores()
        if threads is not None and (isinstance(threads, bool) or not isinstance(threads, (int, np.integer))
                                    or not 1 <= threads <= cores):
            raise InvalidInputError(f"threads = {threads!r}; allowed: an integer from 1 to {cores} (this machine's "
                                    "cores)")
        self.metadata = {**self.metadata, "autoreset_mode": mode}
        for name, flag in (("residual", residual), ("record_trajectories", record_trajectories)):
            if not isinstance(flag, (bool, np.bool_)):
                raise InvalidInputError(f"{name} = {flag!r}; allowed: True or False")
        self.render_mode, self._renderer, self.residual = render_mode, None, bool(residual)
        self.benchmark_spec, self.num_envs = spec, int(num_envs)
        self.source = TaskSource(spec, score_rule(spec), options.get(spec.tasks.keyword), options.get("split"),
                                 options.get("dt_s"))
        self.engine = EpisodeEngine(self.source, residual=self.residual, copies=self.num_envs, backend="kernel",
                                    dense_shaping=options.get("dense_shaping", False), batched=True,
                                    threads=default_threads(cores) if threads is None else int(threads),
                                    record=bool(record_trajectories) or render_mode is not None)
        self.family = self.source.family
        self.n_steps, self.dt = self.engine.n_steps, self.engine.dt
        self.steps_per_decision = self.engine.steps_per_decision
        decisions = self.n_steps // self.steps_per_decision
        if max_episode_steps is not None and int(max_episode_steps) != decisions:
            raise InvalidInputError(f"max_episode_steps = {max_episode_steps}; episodes have {decisions} decisions here "
                                    "(they end at the task's simulation.duration_s)")
        self.single_action_space = gym.spaces.Box(-1.0, 1.0, self.engine.action_shape, np.float32)
        spec = self.source.spec
        self.single_observation_space = gym.spaces.Box(*observation_bounds(spec.target_twist, spec.grasp_observation),
                                                       dtype=np.float32)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._rngs: list[np.random.Generator | None] = [None] * self.num_envs
        self._needs_reset = np.zeros(self.num_envs, dtype=bool)
        self._task_index = np.full(self.num_envs, -1, dtype=np.int64)
        self._task_seed = np.full(self.num_envs, -1, dtype=np.int64)
        self._started = False

    # ---------------------------------------------------------------------------- resets
    def _reset_copy(self, i: int, task_index: int | None = None) -> None:
        info = self.engine.reset_copy(i, self._rngs[i], None if task_index is None else {"task_index": task_index})
        self._task_index[i], self._task_seed[i] = info.get("task_index", -1), info.get("task_seed", -1)

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        """Reset every copy (see the class docstring for ``seed`` and ``options``)."""
        check_open(self)
        check_options(options, ("reset_mask", *self.source.reset_options()), self.source.spec)
        mask = reset_mask(options, self.num_envs, self._started)
        forced = task_indices(options, self.num_envs, self.source.pool is not None)
        seeds = copy_seeds(seed, self.num_envs)
        super().reset(seed=seeds[0] if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) else None)
        for i, s in enumerate(seeds):
            if not mask[i]:
                continue
            if s is not None or self._rngs[i] is None:
                self._rngs[i] = seeding.np_random(s)[0]
            self._reset_copy(i, None if forced is None else forced[i])
        self._needs_reset[mask], self._started = False, True
        return self.engine.obs.copy(), info_contract.with_masks(self.engine.reset_info(), mask)

    @property
    def autoreset_mode(self) -> AutoresetMode:
        """How ended copies are reset (Gymnasium's ``AutoresetMode``; also ``metadata["autoreset_mode"]``)."""
        return self.metadata["autoreset_mode"]

    # ----------------------------------------------------------------------------- steps
    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        return self._step(actions, None)

    def step_with_parameters(self, m: float, T_c: float,
                             command: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        """A step of every copy with physical (m, T_c [s]), no float32 rounding (the (m, T_c) ids only);
        ``command``: capture v1's approach command u ∈ [0, 2] from this step on (None: as it was)."""
        if self.residual:
            raise InvalidInputError("step_with_parameters is for the (m, T_c) envs (FFSR-v0, FFSR-v2), not a residual env")
        parameters = physical_parameters(m, T_c)
        u = None if command is None else physical_command(command, self.engine.grasp)
        return self._step(np.zeros((self.num_envs, self.engine.action_shape[0]), dtype=np.float32), parameters, u)

    def play_out_with_parameters(self, m: float, T_c: float) -> tuple[np.ndarray, np.ndarray, dict]:
        """Every running copy's episode to its end with physical (m, T_c [s]) in one kernel call: the
        trajectories and episode scores of :meth:`step_with_parameters` repeated until each copy ends
        (bit for bit), without a decision's observation and bookkeeping in between.

        Returns ``(terminated, truncated, info)`` as a step's (episode-end keys included); the copies
        then need a ``reset()`` (none is reset here, whatever the autoreset mode).
        """
        if self.residual:
            raise InvalidInputError("play_out_with_parameters is for the (m, T_c) envs (FFSR-v0, FFSR-v2), not a residual env")
        check_open(self)
        if not self._started:
            raise InvalidInputError("call reset() before play_out_with_parameters()")
        active = ~self._needs_reset
        _, terminated, truncated, info = self.engine.step_copies(
            np.zeros((self.num_envs, 2), dtype=np.float32), active, physical_parameters(m, T_c), to_end=True)
        self._needs_reset |= terminated | truncated
        return terminated, truncated, info

    def _step(self, actions: Any, parameters: tuple[float, float] | None, command: float | None = None):
        check_open(self)
        if not self._started:
            raise InvalidInputError("call reset() before step()")
        a, was_clipped = check_action(actions, self.action_space.shape)
        active = ~self._needs_reset
        if command is not None:  # the running copies' approach command (a copy reset by this step starts afresh)
            self.engine.set_command(np.flatnonzero(active), command)
        restarted = self._needs_reset.copy() if self.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP \
            else np.zeros(self.num_envs, dtype=bool)
        self.engine.clipped += was_clipped
        for i in np.flatnonzero(restarted):
            self._reset_copy(int(i))
        rewards, terminated, truncated, info = self.engine.step_copies(a, active, parameters)
        if restarted.any():  # a copy reset by this step gives its reset info, as a Gymnasium vector env does
            self._put_reset_info(info, restarted)
        self._needs_reset = (self._needs_reset & ~restarted) | terminated | truncated
        obs = self.engine.obs.copy()
        if self.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP and self._needs_reset.any():
            info = self._reset_ended(obs, info)
        return obs, rewards, terminated, truncated, info

    def _reset_ended(self, obs: np.ndarray, info: dict[str, Any]) -> dict[str, Any]:
        """Same-step autoreset: every ended copy's last observation and info into ``info``, then a reset (in ``obs``)."""
        ended = self._needs_reset.copy()
        final_obs = np.full(self.num_envs, None, dtype=object)
        final_info: dict[str, Any] = {}  # as SyncVectorEnv gathers it: every key's array, masked to the ended copies
        for key in [k for k in info if not k.startswith("_")]:
            final_info[key] = np.where(ended, info[key], np.zeros_like(info[key]))
            final_info[f"_{key}"] = ended.copy()
        for i in np.flatnonzero(ended):
            final_obs[i] = obs[i].copy()
            self._reset_copy(int(i))
            obs[i] = self.engine.obs[i]
        self._needs_reset[:] = False
        self._put_reset_info(info, ended)
        return {**info, "final_obs": final_obs, "_final_obs": ended, "final_info": final_info, "_final_info": ended.copy()}

    def _put_reset_info(self, info: dict[str, Any], copies: np.ndarray) -> None:
        """The reset info of ``copies`` in place of their step info (every key present: masks True)."""
        fresh = self.engine.reset_info()
        for key, values in fresh.items():
            info[key][copies], info[f"_{key}"][copies] = values[copies], True

    # ----------------------------------------------------------------------------- extras
    def trajectory(self, i: int) -> Trajectory:
        """The :class:`~ffsr_gym.sim.trajectory.Trajectory` of copy ``i``'s current episode (samples so far; an env
        made with ``record_trajectories=True``)."""
        if not 0 <= i < self.num_envs:
            raise InvalidInputError(f"copy {i}; allowed: 0 to {self.num_envs - 1}")
        return self.engine.trajectory(i)

    def render(self) -> tuple[np.ndarray, ...] | None:
        """Copy 0's current frame, as a tuple of one (H, W, 3) array; the other copies are not drawn
        (drawing is ~10 ms per frame). None, with a warning, without ``render_mode="rgb_array"``."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' to make_vec")
            return None
        if not self._started:
            raise InvalidInputError("call reset() before render()")
        from ffsr_gym.environments.render import SceneRenderer, ending

        if self._renderer is None:
            self._renderer = SceneRenderer()
        return (self._renderer.draw(self.engine.rollout(0), self.engine.scenarios[0], ending(self.engine)),)

    def close_extras(self, **kwargs: Any) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
