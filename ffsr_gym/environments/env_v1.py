"""Benchmark-v1 environments ``FFSR-v1`` and ``FFSR-Residual-v1`` (v0 stays as it is, frozen)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym.environments.env import FFSREnv, check_action
from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.kernel import decision
from ffsr_gym.model.benchmark import Benchmark, load_benchmark
from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.scoring.score import (
    EpisodeScore,
    score_episode,
    score_reward,
    score_vector,
    smoothness_cost,
    smoothness_terms,
)
from ffsr_gym.sim.compiled import LOG_FIELDS, KernelRollout
from ffsr_gym.sim.rollout import STATUS
from ffsr_gym.tasks.splits import SPLITS, PoolTask, pool, task_scenario
from ffsr_gym.tasks.tiers import ALL_TIERS

_FLOAT32 = np.dtype(np.float32)
#: Tasks of benchmark v1 (``task=``); a :class:`Scenario` is accepted as a custom, unranked task.
TASKS = ("paper", *ALL_TIERS)
#: The ``info`` keys at the end of a v1 episode (:class:`EpisodeScore` fields) and their dtypes in a batch.
END_INFO_V1 = {"score": float, "success": bool, "failure": object, "smoothness_cost": float, "paper_B": float}


def v1_task(task: str | Scenario, benchmark: Benchmark) -> Scenario:
    """The scenario of ``paper`` (or of a custom scenario) with v1's settings applied."""
    if isinstance(task, Scenario):
        return benchmark.task(task)
    if task != "paper":
        raise InvalidInputError(f"task {task!r}; allowed: {list(TASKS)} or a Scenario")
    return benchmark.task(load_scenario(task))


class FFSRV1Env(FFSREnv):
    """Dual-arm free-floating space robot reaching a target past an obstacle: benchmark v1.

    ## Description
    The robot, physics and planner of ``FFSR-v0``. What v1 changes: the episode score
    (``ffsr_gym.scoring.score``: 1 / (1 + C) on success, 0 on failure, C a smoothness cost of
    both arms' rates without dead zone that also sees chatter), a 1 mm / 1e-3 success tolerance,
    the action box, and a residual that fades to zero by the end of the motion. All numbers are
    in ``envs/benchmark/v1.toml``.

    ## Action Space
    ``FFSR-v1``: ``Box(-1, 1, (2,), float32)`` → m ∈ [0.05, 0.6], T_c ∈ [1, 10] s, per decision.
    ``FFSR-Residual-v1``: ``Box(-1, 1, (12,), float32)`` → ± 20 deg/s per joint (mission arm
    first), times the fade f(t) (1 until 2 s before the end of the desired motion, a half-cosine
    to 0 at its end, 0 after; evaluated at the start of each decision), added to the reference
    planner at v1's (m, T_c) = (0.3, 4 s). A zero action is exactly the reference planner.
    Out-of-range actions are clipped and counted; NaN, inf or a wrong shape raise ``ValueError``.

    ## Observation Space
    As ``FFSR-v0``: ``Box(float32, (53,))``.

    ## Rewards
    The change of the episode's value over each decision: the value is 1 / (1 + C_t) while the
    episode runs (C_t the smoothness cost so far) and the score when it ends, so an episode's
    rewards sum to its score minus 1, and returns rank episodes exactly as scores do. A failure
    (rate limit, collision, final error) loses the remaining 1 / (1 + C_t), reported as
    ``info["penalty"]``. With ``dense_shaping=True`` the potential difference Φ(s') − Φ(s),
    Φ = −‖p_e − p_d‖ / 0.01 m, is added (off by default). The leaderboard score never comes from
    the rewards: it is computed from the trajectory (``ffsr_gym.scoring.score``).
    ``info``: ``smoothness_increment``, ``penalty``, ``shaping``, ``cost`` (0 when nothing is
    violated, else penetration depth / 0.01 m + relative excess of the peak rate over the limit),
    ``clearance_m``, ``ee_position_error_m``, ``clipped_actions``; at the end of an episode
    ``score``, ``success``, ``failure``, ``smoothness_cost``, ``paper_B``.

    ## Starting State
    ``task="paper"``: the paper's scenario (``split`` is accepted; both splits hold that one task).
    ``task`` in ``easy``, ``medium``, ``hard``, ``debris``, ``robust``: each reset draws one task of
    the tier's ``split`` pool uniformly from ``self.np_random`` (``reset(options={"task_index": i})``
    picks one); the test pool is used only with ``split="test"``. Tiers, pools and certificates:
    ``ffsr_gym.tasks`` and docs/envs.md. ``reset``'s info has ``task_index`` and ``task_seed``. On
    ``robust`` the planner sees a noisy target: the observation's end-effector error is the
    planner's; the score uses the true target.

    ## Episode End
    Terminated on a rate above 200 deg/s or a negative clearance (unless
    ``terminate_on_violation=False``: the episode then runs to the horizon, ``info["cost"]`` grades
    each violation and the episode fails); truncated after ``simulation.duration_s`` (200 decisions,
    ``max_episode_steps`` in the registration).

    ## Arguments
    ``gymnasium.make("FFSR-v1", task="paper", split="train", render_mode=None, backend="auto",
    terminate_on_violation=True, dense_shaping=False)``.

    ## Version History
    * v1: bounded score that ranks, rewards that sum to it, 1 mm tolerance, v1 action box, fading
      residual, task tiers easy / medium / hard with certified train and test pools; perturbed tiers
      debris (several drifting obstacles) and robust (model mismatch, initial momentum, noisy target).
    * v0: initial release (``FFSR-v0``, frozen).
    """

    def __init__(self, task: str | Scenario = "paper", split: str = "train", render_mode: str | None = None,
                 backend: str = "auto", terminate_on_violation: bool = True, dense_shaping: bool = False) -> None:
        if split not in SPLITS:
            raise InvalidInputError(f"split {split!r}; allowed: {list(SPLITS)}")
        for name, flag in (("terminate_on_violation", terminate_on_violation), ("dense_shaping", dense_shaping)):
            if not isinstance(flag, bool):
                raise InvalidInputError(f"{name} must be True or False, got {flag!r}")
        self.benchmark = load_benchmark("v1")
        self.task_name = task if isinstance(task, str) else task.name
        self.split = split
        self.terminate_on_violation, self.dense_shaping = terminate_on_violation, dense_shaping
        if isinstance(task, str) and task in ALL_TIERS:
            self.pool: tuple[PoolTask, ...] | None = pool(task, split)
            first = task_scenario(task, self.pool[0].seed, self.benchmark)
        else:
            self.pool, first = None, v1_task(task, self.benchmark)
        super().__init__(first, render_mode=render_mode, backend=backend)

    def _episode_scenario(self, options: dict | None) -> tuple[Scenario, dict]:
        """A tier's task: drawn uniformly from the split's pool, or ``options={"task_index": i}``."""
        if options is not None and not isinstance(options, dict):
            raise InvalidInputError(f"options must be a dict or None, got {type(options).__name__}")
        if self.pool is None:
            return self.family, {}
        index = (options or {}).get("task_index")
        if index is None:
            index = int(self.np_random.integers(len(self.pool)))
        elif isinstance(index, bool) or not isinstance(index, (int, np.integer)) or not 0 <= index < len(self.pool):
            raise InvalidInputError(f"options['task_index'] = {index!r}; allowed: an integer in [0, {len(self.pool) - 1}]")
        seed = self.pool[int(index)].seed
        return task_scenario(self.task_name, seed, self.benchmark), {"task_index": int(index), "task_seed": seed}

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        obs, info = super().reset(seed=seed, options=options)
        self._potential, self._cost_so_far = self._shaping_potential(), 0.0
        self._episode = self._compiled_episode()
        return obs, info

    def __getstate__(self) -> dict:
        """Pickled without the compiled episode (a numba structure); unpickling rebuilds it over the
        same arrays, so a clone steps on bit for bit (its first decision plans afresh: same numbers)."""
        state = self.__dict__.copy()
        state["_episode"] = None
        state["_rebuild_episode"] = self.__dict__.get("_episode") is not None
        return state

    def __setstate__(self, state: dict) -> None:
        rebuild = state.pop("_rebuild_episode", False)
        self.__dict__.update(state)
        if rebuild:
            self._episode = self._compiled_episode()

    # ------------------------------------------------------------- the compiled step (kernel)
    def _compiled_episode(self) -> decision.Episode | None:
        """The episode's arrays for :func:`ffsr_gym.kernel.decision.step_episode` (None on the reference backend)."""
        rollout = self.rollout
        if not isinstance(rollout, KernelRollout):
            return None
        self._obs, self._no_action = np.zeros(decision.N_OBS, dtype=np.float32), np.zeros(2, dtype=np.float32)
        self._action_mode = decision.MODE_RESIDUAL if self.residual else decision.MODE_PARAMETERS
        settings = decision_settings(self.scenario, self.benchmark)
        logs = tuple(rollout._log[key] for key in LOG_FIELDS)
        return decision.new_episode(rollout._mdl, rollout.plant, rollout.x, rollout.fp, rollout.ip, settings, logs,
                                    self.last_rates)

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        if self._episode is None:
            return super().step(action)
        if self.rollout.finished:
            self._check_running()  # raises
        shape, clipped = self.action_space.shape, 0
        if not (type(action) is np.ndarray and action.dtype is _FLOAT32 and action.shape == shape
                and action.flags.c_contiguous):  # else the checks in Python (the kernel takes C-ordered float32)
            action, was_clipped = check_action(action, shape)
            clipped = int(was_clipped)
        return self._decide(action, self._action_mode, clipped)

    def step_with_parameters(self, m: float, T_c: float) -> tuple[np.ndarray, float, bool, bool, dict]:
        if self._episode is None or self.residual:
            return super().step_with_parameters(m, T_c)
        self._check_running()
        self.rollout.set_parameters(float(m), float(T_c))
        return self._decide(self._no_action, decision.MODE_SET, 0)

    def _decide(self, action: np.ndarray, mode: int, clipped: int):
        """One compiled decision (:func:`ffsr_gym.kernel.decision.decide`), then what Gymnasium needs as objects."""
        rollout = self.rollout
        rows, status, was_clipped, increment, cost, clearance, ee_error = decision.step_episode(
            self._episode, action, mode, self.terminate_on_violation, rollout.k, rollout.rows, rollout.n_steps,
            self.steps_per_decision, self._obs)
        if status == decision.STATUS_BAD_ACTION:
            check_action(action, self.action_space.shape)  # raises, naming the problem
            raise InvalidInputError(f"action must be finite, got {action}; allowed range [-1, 1] per entry")
        if status == 3:
            raise FFSRError(f"planner produced non-finite joint rates at t = {(rollout.k + rows) * rollout.dt:.3f} s")
        rollout.k += rows
        rollout.rows += rows
        self.clipped_actions += clipped + int(was_clipped)
        self._clearance, self._ee_error = clearance, ee_error
        return self._finish_decision(status, increment, cost, self._obs.copy())

    def _finish_decision(self, status: int, increment: float, cost: float, obs: np.ndarray):
        """Episode end (score from the whole trajectory), reward, shaping and info of a decision."""
        rollout = self.rollout
        terminated = status != 0
        truncated = not terminated and rollout.k >= rollout.n_steps
        info: dict[str, Any] = {"smoothness_increment": increment, "cost": cost, "clipped_actions": self.clipped_actions}
        result = None
        if terminated or truncated:
            rollout.finish()
            result = score_episode(rollout.trajectory(), self.scenario, self.benchmark)
            info.update(self._final_info_v1(result))
        reward, penalty = score_reward(self._cost_so_far, self._cost_so_far + increment, result)
        self._cost_so_far += increment
        shaping = 0.0
        if self.dense_shaping:
            potential = self._shaping_potential()
            shaping, self._potential = potential - self._potential, potential
        info["penalty"], info["shaping"] = penalty, shaping
        info["clearance_m"], info["ee_position_error_m"] = self._clearance, self._ee_error
        if self.render_mode == "human":
            self.render()
        return obs, float(reward + shaping), terminated, truncated, info

    def _residual(self, action: np.ndarray) -> np.ndarray:
        """The v0 residual times the fade f(t) at the start of this decision."""
        fade = self.benchmark.residual_fade(self.rollout.t, self.scenario.trajectory.motion_time_s)
        return fade * super()._residual(action)

    def _advance(self, parameters: tuple[float, float] | None, residual: np.ndarray | None):
        """A decision through the :class:`~ffsr_gym.sim.rollout.Rollout` interface (the reference backend)."""
        rollout = self.rollout
        if parameters is not None:
            rollout.set_parameters(*parameters)
        applied, status = rollout.advance(self.steps_per_decision, residual, stop_on_violation=self.terminate_on_violation)
        increment = smoothness_cost(*smoothness_terms(applied, rollout.dt, self.last_rates), self.benchmark.score)
        self.last_rates = applied[-1]
        cost = self._violation_cost(applied, rollout.min_clearance(len(applied)))
        obs = self._observation()
        return self._finish_decision(STATUS.index(status), increment, cost, obs)

    def _violation_cost(self, applied: np.ndarray, min_clearance: float) -> float:
        """0 without violation; penetration depth / scale + relative excess of the peak rate."""
        limit = self.benchmark.score.max_rate_deg_s
        peak = float(np.degrees(np.max(np.abs(applied)))) if len(applied) else 0.0
        depth = max(0.0, -min_clearance) / self.benchmark.action.cost_clearance_scale_m
        return depth + max(0.0, peak / limit - 1.0)

    def _shaping_potential(self) -> float:
        return -self._ee_error / self.benchmark.action.shaping_position_scale_m

    @staticmethod
    def _final_info_v1(result: EpisodeScore) -> dict[str, Any]:
        return {key: getattr(result, key) for key in END_INFO_V1}


def decision_settings(task: Scenario, benchmark: Benchmark) -> np.ndarray:
    """The compiled decision's settings (:data:`ffsr_gym.kernel.decision.N_DS`) of a v1 task."""
    settings, action, score = np.zeros(decision.N_DS), benchmark.action, benchmark.score
    (m_lo, m_hi), (t_lo, t_hi) = task.env.m_bounds, task.env.T_c_bounds_s
    settings[:decision.D_SCORE] = (float(np.radians(task.env.residual_rate_deg_s)), action.residual_fade_s,
                                   task.trajectory.motion_time_s, m_lo, m_hi, t_lo, t_hi, score.max_rate_deg_s,
                                   action.cost_clearance_scale_m)
    settings[decision.D_SCORE:] = score_vector(score)
    return settings


class FFSRResidualV1Env(FFSRV1Env):
    __doc__ = FFSRV1Env.__doc__
    residual = True
