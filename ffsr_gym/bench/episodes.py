"""Playing an evaluation's episodes: one env per chunk of tasks (any policy, with the trace of what a policy that
is code applied), or one batched env for a fixed (m, T_c). Module level, so that executors can run chunks."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from ffsr_gym.bench.entry import actor, stepper
from ffsr_gym.bench.trace import encode


def _row(seed: int, info: dict[str, Any], rule_row: dict[str, Any], pooled: bool) -> dict[str, Any]:
    """An entry's row: the seed (a pool's: also the task's index and seed), then the rule's row."""
    if not pooled:
        return {"seed": seed, **rule_row}
    return {"seed": seed, "task_index": seed, "task_seed": info.get("task_seed"), **rule_row}


def play_chunk(policy: Any, env_id: str, kwargs: dict[str, Any], pooled: bool,
              jobs: Sequence[tuple[int, int | None]]) -> list[tuple[dict, str, str]]:
    """The scored episodes of ``jobs``: each row, the played scenario's key and hash, and (a policy that is code) the
    trace of the actions it applied (:mod:`ffsr_gym.bench.trace`) with the decisions whose action was clipped.
    Module level: executors run chunks."""
    env = gym.make(env_id, **kwargs)
    engine = env.unwrapped.engine
    out = []
    for seed, index in jobs:
        obs, info = env.reset(seed=seed, options=None if index is None else {"task_index": index})
        applied: list[np.ndarray] | None = None if isinstance(policy, tuple) else []
        clipped: list[int] = []
        step = stepper(policy, env) if applied is None else _recording_stepper(policy, env, applied, clipped)
        done = False
        while not done:
            obs, _, terminated, truncated, last = step(obs)
            done = terminated or truncated
        played, traj = env.unwrapped.scenario, env.unwrapped.trajectory
        result = engine.results[0] or engine.rule.result(traj, played)  # scored at the episode's end already
        row = _row(seed, info, engine.rule.row(result, traj), pooled)
        row["clipped_actions"] = int(last["clipped_actions"])
        key = played.name if played.randomization is None or pooled else f"{played.name}/seed={seed}"
        trace = None if applied is None else (encode(np.reshape(applied, (len(applied), *env.action_space.shape))),
                                              clipped)
        out.append((row, key, played.sha256(), trace))
    env.close()
    return out


def _recording_stepper(policy: Any, env: gym.Env, applied: list[np.ndarray], clipped: list[int]):
    """:func:`stepper` of a policy that is code, appending to ``applied`` each action as the env applies it, and to
    ``clipped`` the index of each decision whose action the env clipped."""
    from ffsr_gym.environments.actions import check_action

    act, shape = actor(policy), env.action_space.shape

    def step(obs: np.ndarray) -> tuple:
        raw = act(obs)
        action, was_clipped = check_action(raw, shape)  # what the env applies (it clips and counts the same way)
        if was_clipped:
            clipped.append(len(applied))
        applied.append(action)
        return env.step(raw)
    return step


def play_batched(parameters: tuple[float, float], version: str, kwargs: dict[str, Any],
                      jobs: Sequence[tuple[int, int | None]]) -> list[tuple[dict, str, str]]:
    """:func:`play_chunk` for a fixed (m, T_c): all tasks in one batched env (bit-identical rows)."""
    from ffsr_gym.environments.vector_env import FFSRVectorEnv

    venv = FFSRVectorEnv(len(jobs), version, autoreset_mode="Disabled", **kwargs)
    indices = [index for _, index in jobs]
    _, info = venv.reset(seed=[seed for seed, _ in jobs],
                         options=None if indices[0] is None else {"task_index": indices})
    engine = venv.engine
    venv.play_out_with_parameters(*parameters)  # whole episodes in one call (the rows of decision after decision)
    results = []
    for i, (seed, _) in enumerate(jobs):
        task_seed = int(info["task_seed"][i])
        traj = engine.trajectory(i) if engine.rule.row_needs_trajectory else None
        rule_row = engine.rule.row(engine.results[i], traj)
        row = _row(seed, {"task_seed": None if task_seed < 0 else task_seed}, rule_row, True)
        row["clipped_actions"] = int(engine.clipped[i])
        results.append((row, engine.scenarios[i].name, engine.scenarios[i].sha256(), None))
    venv.close()
    return results
