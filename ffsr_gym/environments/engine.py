"""The episode engine: N copies of one benchmark version's episodes, stepped decision by decision.

The engine owns everything an environment step computes: the action's mapping, the decision's physics, its reward,
the episode's end, the final score and the info keys. It draws its tasks from a
:class:`~ffsr_gym.environments.task_source.TaskSource` and scores with the spec's rule (:mod:`ffsr_gym.scoring.rules`).
It knows nothing of Gymnasium: the single environment is an adapter over one copy, the batched one over N.

Two pipelines compute a decision, written once for every version:

* compiled (the kernel backend): each copy's episode is a native :class:`ffsr_gym._native.Episode` (its logs in the
  engine's arrays, or none: its score totals); one call of its ``decide`` for one copy, one call of an
  :class:`ffsr_gym._native.EpisodeBatch` for N (on threads, the GIL released); same numbers;
* reference (any backend, one copy): the :class:`~ffsr_gym.sim.rollout.Rollout` interface, the increment from the
  score rule in numpy, the observation assembled in Python: the compiled pipeline's numbers bit for bit on the
  kernel backend (tested), and the Pinocchio reference.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym import _native
from ffsr_gym.environments import actions as act
from ffsr_gym.environments import info as info_contract
from ffsr_gym.environments.engine_pickle import PicklableEngine
from ffsr_gym.environments.engine_settings import EngineSettings
from ffsr_gym.environments.task_source import TaskSource
from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.kernel import layout
from ffsr_gym.model import portable
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.sim.budget import check_run
from ffsr_gym.sim.compiled import KernelRollout, new_log
from ffsr_gym.sim.rollout import BACKENDS, STATUS, Rollout
from ffsr_gym.sim.simulate import make_rollout
from ffsr_gym.sim.trajectory import Trajectory

_FLOAT32 = np.dtype(np.float32)
_FLOAT64 = np.dtype(np.float64)


def _scalars(n: int, kind: type, single: bool) -> Any:
    """``n`` zeros of ``kind``: a list for the single env's copy, an array for a batch (see :class:`EpisodeEngine`)."""
    return [0 if kind is np.int64 else 0.0] if single else np.zeros(n, dtype=kind)


class EpisodeEngine(EngineSettings, PicklableEngine):
    """``copies`` episodes of ``source``'s tasks under one spec's rule (see the module docstring).

    Per-copy state lives in stacked arrays (row i = copy i); ``obs`` (N, 53) float32 holds each
    copy's current observation, ``clearance`` and ``ee_error`` its last clearance and end-effector
    position error [m]; ``logs`` (compiled, ``record``) each copy's trajectory so far, written by its native
    episode. ``record=False``: a copy keeps no trajectory, only its native episode's score totals (its episode's
    result is the same; a rule that needs the trajectory, v0's and a capture rule, records anyway).
    ``threads``: the threads a batched decision runs its copies on.
    """

    def __init__(self, source: TaskSource, *, residual: bool, copies: int = 1, backend: str = "auto",
                 terminate_on_violation: bool = True, dense_shaping: bool = False, batched: bool = False,
                 threads: int = 1, record: bool = True) -> None:
        self.source, self.rule, self.spec = source, source.rule, source.spec
        self.residual, self.backend, self.n = residual, backend, int(copies)
        self.terminate, self.shaping = terminate_on_violation, dense_shaping and self.rule.shaping
        family = source.family
        self.dt, self.n_steps = family.simulation.dt_s, family.n_steps
        self.steps_per_decision = max(1, int(round(family.env.decision_interval_s / self.dt)))
        self.grasp = self.spec.grasp_observation  # capture v1: the command in the action, the grasp frame shown
        self.action_shape = ((12 if residual else 2) + int(self.spec.actions.command),)
        if backend not in BACKENDS or (self.grasp and backend == "pinocchio"):
            raise InvalidInputError(f"backend {backend!r}; allowed: {list(BACKENDS[:2] if self.grasp else BACKENDS)}"
                                    + (f" ({self.spec.version} is stepped by the native kernel)" if self.grasp else ""))
        self.compiled = backend in ("kernel", "auto")
        N = self.n
        copies = f"{N} environment cop{'ies' if N != 1 else 'y'} of {family.name}"
        rule = self.rule
        self.record = bool(record) or not rule.compiled_terms or (rule.benchmark.capture is not None and not self.grasp)
        check_run(steps=self.n_steps, copies=N, steps_per_decision=self.steps_per_decision,
                  substeps=max(1, family.physics_substeps), what=copies, trajectories=self.record)
        self.single = N == 1 and not batched  # stepped by step_one (else by step_copies)
        self.scenarios: list[Scenario | None] = [None] * N
        self.rollouts: list[Rollout | None] = [None] * N
        self.results: list[Any] = [None] * N  # each copy's last finished episode's result (the rule's)
        self.twist = self.spec.target_twist  # the observation ends with the desired twist (a capture spec)
        width = layout.N_OBS_GRASP if self.grasp else layout.N_OBS_TWIST if self.twist else layout.N_OBS
        self.obs = np.zeros((N, width), dtype=np.float32)
        self._obs0 = self.obs[0]  # copy 0's row (the single env's compiled step writes it)
        self._mode = layout.MODE_RESIDUAL if residual else layout.MODE_PARAMETERS
        self._no_action = np.zeros(2)  # the action of a decision with (m, T_c) already set
        self.last_rates = np.zeros((N, 12))  # the reference pipeline's
        # Per-copy scalars: step k, clipped actions, smoothness cost so far, shaping potential, clearance [m] and
        # EE position error [m]. One copy keeps them in lists (a Python element access costs a third of numpy's,
        # which the single env's microsecond budget notices); N copies in arrays for the vectorised bookkeeping.
        self.K, self.clipped = _scalars(N, np.int64, self.single), _scalars(N, np.int64, self.single)
        self.cost_so_far, self.potential = _scalars(N, float, self.single), _scalars(N, float, self.single)
        self.clearance, self.ee_error = _scalars(N, float, self.single), _scalars(N, float, self.single)
        self.logs = new_log(self.n_steps + 1, N) if self.compiled and self.record else None
        self.episodes: list[_native.Episode | None] = [None] * N
        self.threads, self.batch = int(threads), None
        self.out = np.zeros((N, 7))
        self.task_index, self.task_seed = np.full(N, -1, dtype=np.int64), np.full(N, -1, dtype=np.int64)
        self._blank = info_contract.scalars(info_contract.blank(self.rule, 1), 0)  # the single env's info, before

    # ------------------------------------------------------------------------------ resets
    def reset_copy(self, i: int, rng: np.random.Generator, options: dict | None = None) -> dict[str, int]:
        """Copy ``i``'s next episode, drawn from ``rng``; returns the task source's info."""
        scenario, info = self.source.draw(rng, options)
        self.scenarios[i], self.results[i] = scenario, None
        for key, values in (("task_index", self.task_index), ("task_seed", self.task_seed)):
            values[i] = -1 if info.get(key) is None else info[key]
        self.last_rates[i], self.clipped[i], self.cost_so_far[i], self.K[i] = 0.0, 0, 0.0, 0
        if self.compiled:
            self._load_copy(i, scenario)
            self.clearance[i], self.ee_error[i] = self.episodes[i].observe(0, self.obs[i])
        else:
            rollout = self.rollouts[i] = make_rollout(scenario, backend=self.backend)
            angles, e1, e0, rel, clear = rollout.observation()
            self.obs[i] = act.assemble_observation(angles, self.last_rates[i], e1, e0, rel, clear, 0.0,
                                                   self._desired_twist(rollout))
            self.clearance[i], self.ee_error[i] = clear, portable.norm(e1[:3])
        self.out[i, 5], self.out[i, 6] = self.clearance[i], self.ee_error[i]
        self.potential[i] = self._potential(self.ee_error[i])
        return info

    def reset_info(self) -> dict[str, np.ndarray]:
        """Every copy's info as it stands after a reset (the contract's keys, :mod:`~ffsr_gym.environments.info`)."""
        arrays = info_contract.blank(self.rule, self.n)
        arrays["task_index"][:], arrays["task_seed"][:] = self.task_index, self.task_seed
        arrays["clearance_m"][:], arrays["ee_position_error_m"][:] = self.clearance, self.ee_error
        arrays["clipped_actions"][:] = self.clipped
        return arrays

    def _load_copy(self, i: int, scenario: Scenario, state: tuple | None = None) -> None:
        """Copy ``i``'s new episode: its rollout and its native episode, both on copy ``i``'s rows of the logs.
        ``state``: (x (40), m, T_c [s], last rates (12), score totals, approach state (5), capture judge) to continue
        from."""
        if scenario.n_steps != self.n_steps or scenario.simulation.dt_s != self.dt:
            raise FFSRError("a task changed dt_s or duration_s; the copies need them fixed")
        views = {key: rows[i] for key, rows in self.logs.items()} if self.record else None
        rollout = KernelRollout(scenario, log=new_log(1) if views is None else views)  # no trajectory: one row
        x = rollout.x
        if state is not None:
            x, (rollout.settings.m, rollout.settings.T_c) = state[0], state[1:3]
        episode = _native.Episode(rollout.setup.assets.native, rollout.settings,
                                  act.decision_settings(scenario, self.rule, self.spec.actions.residual_fades,
                                                        self.grasp), x,
                                  self.n_steps, plant=rollout.setup.native_plant, logs=views)
        if rollout.timing is not None:  # a custom task's commanded approach (docs/model.md §23): its own command
            episode.timing = rollout.timing if state is None else state[5]
        if self.grasp:  # capture v1: judged as it runs, and ended at the capture
            act.judge_capture(episode, self.rule.benchmark.capture)
        if state is not None:
            episode.last_rates, episode.totals = state[3], state[4]
            if self.grasp:
                episode.capture_state = state[6]
        self.rollouts[i], self.episodes[i] = rollout, episode
        if self.batch is not None:
            self.batch.set(i, episode)

    def use_reference_pipeline(self) -> None:
        """Step copy 0 through the :class:`Rollout` interface from now on (right after a reset; one copy only).

        The compiled and the reference pipelines give the same numbers bit for bit on the kernel backend:
        this switch is how the tests show it.
        """
        if not self.single or any(self.K) or self.grasp:
            raise InvalidInputError("the reference pipeline steps one copy, from the start of an episode, of a version "
                                    "whose action does not command an approach")
        self.compiled, self.episodes[0] = False, None

    def _potential(self, ee_error: Any) -> Any:
        return -ee_error / self.rule.benchmark.action.shaping_position_scale_m if self.shaping else 0.0

    # --------------------------------------------------------------------- one copy (N = 1)
    def step_one(self, action: Any, parameters: tuple[float, float] | None = None) -> tuple:
        """One decision of copy 0: ``(obs, reward, terminated, truncated, info)``.

        ``action``: a float32 C-ordered array of the action's shape is passed to the compiled step
        as it is (clipped and counted there); anything else is checked here. ``parameters``: a
        physical (m, T_c [s]) instead (the (m, T_c) ids; validated, no float32 rounding).
        """
        clipped = 0
        if parameters is None and not (self.compiled and type(action) is np.ndarray and action.dtype is _FLOAT32
                                       and action.shape == self.action_shape and action.flags.c_contiguous):
            action, was_clipped = act.check_action(action, self.action_shape)
            clipped = int(was_clipped)
        started = self.K[0] * self.dt
        if self.compiled:
            status, increment, cost = self._decide_one(action, parameters)
            obs = self._obs0.copy()
        else:
            status, increment, cost, obs = self._advance_one(action, parameters)
        self.clipped[0] += clipped
        return self._finish_one(status, increment, cost, obs, started)

    def _decide_one(self, action: np.ndarray, parameters: tuple[float, float] | None) -> tuple[int, float, float]:
        """The compiled decision of copy 0."""
        mode = self._mode
        if parameters is not None:
            self._set_parameters(0, parameters)
            action, mode = self._no_action, layout.MODE_SET
        k = self.K[0]
        rows, status, was_clipped, increment, cost, clearance, ee_error = self.episodes[0].decide(
            action if action.dtype is _FLOAT64 else action.astype(_FLOAT64), mode, self.terminate, k,
            self.steps_per_decision, self._obs0)
        if status == layout.STATUS_BAD_ACTION:
            act.check_action(action, self.action_shape)  # raises, naming the problem
            raise InvalidInputError(f"action must be finite, got {action}; allowed range [-1, 1] per entry")
        if status == layout.STATUS_NONFINITE:
            raise FFSRError(f"planner produced non-finite joint rates at t = {(k + rows) * self.dt:.3f} s")
        self.K[0] = k + rows
        self.clipped[0] += int(was_clipped)
        self.clearance[0], self.ee_error[0] = clearance, ee_error
        if not self.rule.compiled_terms:
            applied = self.logs["dq"][0][k:k + rows]
            increment = self.rule.increment(applied, self.dt, None, self.scenarios[0])
            cost = self.rule.cost(applied, 0.0, status != 0, self.scenarios[0])
        return status, increment, cost

    def _advance_one(self, action: np.ndarray, parameters: tuple[float, float] | None) -> tuple:
        """The reference decision of copy 0, through the :class:`Rollout` interface."""
        rollout, scenario = self.rollout(0), self.scenarios[0]
        residual = None
        if parameters is not None:
            rollout.set_parameters(*parameters)
        elif self.residual:
            residual = act.residual_rates(action, scenario, self.rule, self.spec.actions.residual_fades, rollout.t)
        else:
            rollout.set_parameters(*act.action_to_parameters(action, scenario))
        applied, status = rollout.advance(self.steps_per_decision, residual, stop_on_violation=self.terminate)
        code = STATUS.index(status)
        increment = self.rule.increment(applied, self.dt, self.last_rates[0], scenario)
        cost = self.rule.cost(applied, rollout.min_margin(len(applied)), code != 0, scenario)
        self.last_rates[0] = applied[-1]
        self.K[0] = rollout.k
        angles, e1, e0, rel, clear = rollout.observation()
        self.clearance[0], self.ee_error[0] = float(clear), portable.norm(e1[:3])
        obs = act.assemble_observation(angles, self.last_rates[0], e1, e0, rel, clear, rollout.k / rollout.n_steps,
                                       self._desired_twist(rollout))
        return code, increment, cost, obs

    def _desired_twist(self, rollout: Rollout) -> np.ndarray | None:
        """The desired end-effector twist V_ed at the rollout's time (a capture spec's observation; else None)."""
        return rollout.setup.path.at(rollout.t)[2] if self.twist else None

    def _finish_one(self, status: int, increment: float, cost: float, obs: np.ndarray, started: float) -> tuple:
        """Episode end (the rule's result of the whole trajectory), reward, shaping and info (``started``: the
        decision's start [s])."""
        terminated = bool(status != 0)
        truncated = bool(not terminated and self.K[0] >= self.n_steps)
        info: dict[str, Any] = dict(self._blank)
        info.update({"task_index": int(self.task_index[0]), "task_seed": int(self.task_seed[0]),
                     self.rule.increment_key: float(increment), "cost": float(cost),
                     "clipped_actions": int(self.clipped[0])})
        result = None
        if terminated or truncated:
            result = self.end_copy(0, captured=status == layout.STATUS_CAPTURED)
            info.update(info_contract.end_values(self.rule, result), episode_end=True)
        before = float(self.cost_so_far[0])
        reward, penalty = self.rule.reward(before, increment, result, terminated=terminated, truncated=truncated,
                                           scenario=self.scenarios[0], started_s=started)
        self.cost_so_far[0] = before + increment
        info["penalty"] = float(penalty)
        if self.rule.shaping:
            shaping = 0.0
            if self.shaping:
                potential = self._potential(float(self.ee_error[0]))
                shaping, self.potential[0] = potential - float(self.potential[0]), potential
            info["shaping"] = shaping
            reward += shaping
        info["clearance_m"], info["ee_position_error_m"] = float(self.clearance[0]), float(self.ee_error[0])
        return obs, float(reward), terminated, truncated, info

    # ------------------------------------------------------------------------ N copies
    def step_copies(self, actions: np.ndarray, active: np.ndarray, parameters: tuple[float, float] | None = None,
                    *, to_end: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
        """One decision of every ``active`` copy (checked, clipped float32 ``actions`` (N, size)).

        ``to_end``: the decision lasts until the episode ends (its horizon or a violation): one kernel
        call plays whole episodes, with the trajectories of decision after decision (the planner keeps
        no state between steps), for a fixed policy's evaluation.

        Returns ``(rewards, terminated, truncated, info)``, arrays over the copies (inactive: 0);
        ``info`` has the rule's end keys with their ``_key`` masks and the per-decision keys.
        """
        mode = layout.MODE_RESIDUAL if self.residual else layout.MODE_PARAMETERS
        if parameters is not None:
            self._set_parameters_of(active, parameters)
            mode = layout.MODE_SET
        out, start = self.out, self.K.copy()
        out[~active, :5] = 0.0  # no steps, no cost; clearance and EE error of the reset (or held) state stay
        if self.batch is None:
            self.batch = _native.EpisodeBatch(self.n, self.threads)
            for i, episode in enumerate(self.episodes):
                if episode is not None:
                    self.batch.set(i, episode)
        self.batch.decide(np.ascontiguousarray(actions, dtype=_FLOAT64), np.ascontiguousarray(active, dtype=bool),
                          self.K, mode, self.n_steps if to_end else self.steps_per_decision, self.obs, out)
        rows, status = out[:, 0].astype(np.int64), out[:, 1].astype(np.int64)
        if np.any(status == layout.STATUS_NONFINITE):
            bad = np.flatnonzero(status == layout.STATUS_NONFINITE).tolist()
            raise FFSRError(f"planner produced non-finite joint rates in copies {bad}")
        terminated = active & (status != 0)
        truncated = active & ~terminated & (self.K >= self.n_steps)
        increments, costs = self._batch_terms(active, start, rows, terminated)
        self.clearance[:], self.ee_error[:] = out[:, 5], out[:, 6]
        return self._batch_rewards(active, terminated, truncated, increments, costs, start,
                                   status == layout.STATUS_CAPTURED)

    def _batch_terms(self, active: np.ndarray, start: np.ndarray, rows: np.ndarray,
                     terminated: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each copy's increment and cost: the kernel's, or the rule's from the applied rates (zero-padded)."""
        if self.rule.compiled_terms:
            return self.out[:, 3].copy(), self.out[:, 4].copy()
        applied = np.zeros((self.n, self.steps_per_decision, 12))
        for i in np.flatnonzero(active):
            applied[i, :rows[i]] = self.logs["dq"][i, start[i]:start[i] + rows[i]]
        increments = np.where(active, self.rule.increment(applied, self.dt, None, self.source.family), 0.0)
        return increments, terminated.astype(float)

    def _batch_rewards(self, active: np.ndarray, terminated: np.ndarray, truncated: np.ndarray, increments: np.ndarray,
                       costs: np.ndarray, start: np.ndarray, captured: np.ndarray) -> tuple:
        """Rewards, shaping and info of a batched decision (from steps ``start``); ends score their whole episode."""
        N, ended = self.n, terminated | truncated
        results = {int(i): self.end_copy(int(i), captured=bool(captured[i])) for i in np.flatnonzero(ended)}
        info = info_contract.blank(self.rule, N)
        info["task_index"][:], info["task_seed"][:], info["episode_end"][:] = self.task_index, self.task_seed, ended
        for i, result in results.items():
            for key, value in info_contract.end_values(self.rule, result).items():
                info[key][i] = value
        before = self.cost_so_far
        rewards, penalties = np.where(active, self.rule.running_rewards(before, increments), 0.0), np.zeros(N)
        for i, result in results.items():
            rewards[i], penalties[i] = self.rule.reward(before[i], increments[i], result, terminated=bool(terminated[i]),
                                                        truncated=bool(truncated[i]), scenario=self.scenarios[i],
                                                        started_s=start[i] * self.dt)
        self.cost_so_far = np.where(active, before + increments, before)
        info[self.rule.increment_key][:], info["penalty"][:] = increments, penalties
        if self.rule.shaping:
            potential = self._potential(self.ee_error)
            shaping = np.where(active, potential - self.potential, 0.0) if self.shaping else np.zeros(N)
            self.potential = np.where(active, potential, self.potential)
            info["shaping"][:] = shaping
            rewards = np.where(active, rewards + shaping, 0.0)
        info["cost"][:], info["clearance_m"][:], info["ee_position_error_m"][:] = costs, self.clearance, self.ee_error
        info["clipped_actions"][:] = self.clipped
        return rewards, terminated, truncated, info_contract.with_masks(info, active)

    # ------------------------------------------------------------------------ per copy
    def end_copy(self, i: int, captured: bool = False) -> Any:
        """Record copy ``i``'s final sample (``captured``: its last row already is) and score its episode with the
        rule: from its trajectory, or from its native episode's totals when it keeps none (the same numbers)."""
        rollout, episode = self.rollout(i), self.episodes[i] if self.compiled else None
        if episode is not None and not rollout.finished:
            if not captured:
                episode.finish(int(self.K[i]))
            rollout.rows, rollout.finished = rollout.rows + (not captured), True
        rollout.finish()  # the reference pipeline's
        scenario = self.scenarios[i]
        if self.record:
            self.results[i] = self.rule.result(rollout.trajectory(), scenario)
        elif self.grasp:  # capture v1: its native judge says when and how it captured
            self.results[i] = self.rule.result_of_totals(episode.totals, scenario, episode.capture)
        else:
            self.results[i] = self.rule.result_of_totals(episode.totals, scenario)
        return self.results[i]

    def rollout(self, i: int) -> Rollout:
        """Copy ``i``'s rollout with the engine's state (an unfinished compiled episode: one logged row per step)."""
        if (rollout := self.rollouts[i]) is None:
            raise InvalidInputError("no episode yet: call reset()")
        episode = self.episodes[i] if self.compiled else None
        if episode is not None and not rollout.finished:
            rollout.x, rollout.k, rollout.rows = episode.state(), int(self.K[i]), int(self.K[i])
            rollout.settings.m, rollout.settings.T_c = episode.m, episode.T_c  # (m, T_c) the decisions set
        return rollout

    def trajectory(self, i: int) -> Trajectory:
        """Copy ``i``'s :class:`Trajectory` so far (an engine made with ``record=True``)."""
        if not self.record:
            raise InvalidInputError("these copies keep no trajectory (record_trajectories=False); make the "
                                    "environment with record_trajectories=True to read one")
        return self.rollout(i).trajectory()

    def finished(self, i: int) -> bool:
        """Whether copy ``i``'s episode has ended."""
        return self.rollouts[i] is not None and self.rollouts[i].finished
