"""Scoring a policy on benchmark v1: one episode per task of a tier's pool (the test pool by default).

Every episode is scored from its trajectory by :func:`ffsr_gym.scoring.score.score_episode`, the
one v1 score, never from the rewards. The entry records the pool it was evaluated on and the
pool the policy was trained on (as the caller states it).
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Sequence
from concurrent.futures import Executor
from functools import partial
from typing import Any

import gymnasium as gym
import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.bench.entry import EvalReport, stepper
from ffsr_gym.bench.protocol import BOOTSTRAP_SAMPLES, BOOTSTRAP_SEED
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.benchmark import load_benchmark
from ffsr_gym.provenance import provenance
from ffsr_gym.scoring.aggregate import iqm
from ffsr_gym.scoring.score import score_episode
from ffsr_gym.tasks.certificate import planner_episode, planner_task
from ffsr_gym.tasks.splits import SPLITS, pool, pool_path, task_scenario
from ffsr_gym.tasks.tiers import ALL_TIERS

V1_IDS = ("FFSR-v1", "FFSR-Residual-v1")
SCORE_RULE = "v1 episode score: 1 / (1 + C) on success, 0 on failure (ffsr_gym.scoring.score)"


def aggregate_v1(scores: Sequence[float], successes: Sequence[bool]) -> dict[str, Any]:
    """Mean, IQM and its seeded-bootstrap 95 % CI of the episode scores, and the success rate."""
    values = np.asarray(scores, dtype=float)
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    boots = [iqm(values[rng.integers(0, len(values), len(values))]) for _ in range(BOOTSTRAP_SAMPLES)]
    return {"score_mean": float(np.mean(values)), "score_iqm": iqm(values),
            "score_iqm_ci95": [float(np.percentile(boots, 2.5, method="inverted_cdf")),
                               float(np.percentile(boots, 97.5, method="inverted_cdf"))],
            "success_rate": float(np.mean(np.asarray(successes, dtype=float))), "episodes": len(values)}


def _episodes(policy: Any, env_id: str, kwargs: dict[str, Any], indices: Sequence[int]) -> list[tuple[dict, str, str]]:
    """The scored episodes of pool ``indices`` (one per task, ``reset(seed=i, task_index=i)``), with
    each played scenario's name and hash. Module level, so executors can run chunks of a pool."""
    env = gym.make(env_id, **kwargs)
    step = stepper(policy, env)
    out = []
    for index in indices:
        options = None if kwargs["task"] == "paper" else {"task_index": int(index)}
        obs, info = env.reset(seed=int(index), options=options)
        done = False
        while not done:
            obs, _, terminated, truncated, _ = step(obs)
            done = terminated or truncated
        played = env.unwrapped.scenario
        result = score_episode(env.unwrapped.trajectory, played, env.unwrapped.benchmark)
        row = {"seed": int(index), "task_index": int(index), "task_seed": info.get("task_seed"), **result.as_dict()}
        out.append((row, played.name, played.sha256()))
    env.close()
    return out


def _batched_episodes(parameters: tuple[float, float], kwargs: dict[str, Any],
                      indices: Sequence[int]) -> list[tuple[dict, str, str]]:
    """:func:`_episodes` for a fixed (m, T_c) on ``FFSR-v1``: all tasks in one batched env (bit-identical)."""
    from ffsr_gym.environments.vector_env_v1 import FFSRV1VectorEnv

    venv = FFSRV1VectorEnv(len(indices), kwargs["task"], kwargs["split"],
                           dense_shaping=bool(kwargs.get("dense_shaping", False)), autoreset_mode="Disabled")
    _, info = venv.reset(seed=[int(i) for i in indices],
                         options=None if kwargs["task"] == "paper" else {"task_index": [int(i) for i in indices]})
    results: dict[int, tuple[dict, str, str]] = {}
    while len(results) < len(indices):
        _, _, terminated, truncated, _ = venv.step_with_parameters(*parameters)
        for i in np.flatnonzero(terminated | truncated):
            if i not in results:
                played = venv._rollouts[i].scenario
                seed = int(info["task_seed"][i])
                row = {"seed": int(indices[i]), "task_index": int(indices[i]), "task_seed": None if seed < 0 else seed,
                       **venv._ended[i].as_dict()}
                results[int(i)] = (row, played.name, played.sha256())
    venv.close()
    return [results[i] for i in range(len(indices))]


def evaluate_v1(policy: Any, env_id: str, *, task: str = "easy", split: str = "test", indices: Sequence[int] | None = None,
                training_pool: str | None = None, env_kwargs: dict | None = None, name: str = "submission",
                progress: bool = False, executor: Executor | None = None, chunk: int = 10,
                batched: bool | None = None) -> EvalReport:
    """Score ``policy`` on ``env_id`` over a tier's pool, one episode per task (``reset(seed=i, task_index=i)``).

    Args:
        policy: as :func:`ffsr_gym.evaluate` (a ``(m, T_c)`` tuple only on ``FFSR-v1``).
        env_id: ``"FFSR-v1"`` or ``"FFSR-Residual-v1"``.
        task: a tier (``easy``, ``medium``, ``hard``) or ``"paper"`` (one episode).
        split: the pool scored; ``"test"`` unless you report a training score.
        indices: pool indices to score (default: the whole pool).
        training_pool: what the policy was trained or tuned on (recorded), e.g. ``"easy/train"``.
        env_kwargs: other ``gymnasium.make`` arguments (``dense_shaping``, ...; never the score).
        name: entry name.
        progress: show a progress bar.
        executor: run chunks of ``chunk`` tasks on any ``concurrent.futures.Executor`` (processes,
            a Dask cluster's ``get_executor()``); the policy must then pickle (a ``(m, T_c)`` tuple,
            a module-level function, an SB3 model). The entry is the same as without one.
        chunk: tasks per submitted job.
        batched: run a fixed ``(m, T_c)`` on ``FFSR-v1`` through the batched env, all tasks at once, in
            this process (None: whenever the policy allows it and there is no executor; the same
            entry, tested bit for bit).
    """
    if env_id not in V1_IDS:
        raise InvalidInputError(f"env_id {env_id!r}; allowed: {list(V1_IDS)}")
    if task not in ("paper", *ALL_TIERS) or split not in SPLITS:
        raise InvalidInputError(f"task {task!r}, split {split!r}; allowed: task in {['paper', *ALL_TIERS]}, "
                                f"split in {list(SPLITS)}")
    if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
        raise InvalidInputError(f"chunk = {chunk!r}; allowed: an integer >= 1")
    kwargs = {**(env_kwargs or {}), "task": task, "split": split}
    size = 1 if task == "paper" else len(pool(task, split))
    chosen = list(range(size) if indices is None else indices)
    if not chosen or any(isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= i < size for i in chosen):
        raise InvalidInputError(f"indices must be a non-empty list of integers in [0, {size - 1}], got {indices!r}")
    start = time.perf_counter()
    fixed = (isinstance(policy, tuple) and env_id == "FFSR-v1" and kwargs.get("terminate_on_violation", True) is True
             and set(kwargs) <= {"task", "split", "dense_shaping", "terminate_on_violation"})
    if batched and not fixed:
        raise InvalidInputError("batched=True needs a fixed (m, T_c) policy on FFSR-v1, terminate_on_violation=True "
                                "and no env_kwargs other than dense_shaping")
    if batched and executor is not None:
        raise InvalidInputError("batched=True runs in this process (the batched kernel's threads do not survive a fork); "
                                "with an executor each worker runs single environments")
    if fixed and executor is None and batched is not False:
        run, size = partial(_batched_episodes, policy, kwargs), len(chosen)
    else:
        run, size = partial(_episodes, policy, env_id, kwargs), chunk
    pieces = [chosen[k:k + size] for k in range(0, len(chosen), size)]
    results = (map if executor is None else executor.map)(run, pieces)
    rows, hashes = [], {}
    with tqdm(total=len(chosen), disable=not progress, desc=f"evaluate {env_id} {task}/{split}", unit="episode") as bar:
        for episodes in results:
            for row, scenario, sha in episodes:
                rows.append(row)
                hashes[scenario] = sha
            bar.update(len(episodes))
    metrics = aggregate_v1([row["score"] for row in rows], [row["success"] for row in rows])
    pools = pool_path("easy" if task == "paper" else task).read_bytes()
    extra = {"training_pool": training_pool, "evaluation_pool": f"{task}/{split}",
             "pool_file_sha256": hashlib.sha256(pools).hexdigest()}
    prov = provenance(scenarios=hashes, seeds=[int(i) for i in chosen], wall_time_s=time.perf_counter() - start)
    return EvalReport(env_id, kwargs, metrics, rows, prov, name=name, extra=extra, score_rule=SCORE_RULE)


def evaluate_planner(method: str, *, task: str, split: str = "test", m: float | None = None, T_c: float | None = None,
                     gain_per_s: float | None = None, training_pool: str | None = None, name: str = "planner",
                     compute: dict | None = None, progress: bool = False) -> EvalReport:
    """Score a reference-planner variant with constant parameters on a tier's pool (one episode per task).

    The planner variants that are not an env action (``proportional``) are scored here, from the
    trajectory with :func:`ffsr_gym.scoring.score.score_episode`, exactly as :func:`evaluate_v1`
    scores env episodes.
    """
    if task not in ALL_TIERS or split not in SPLITS:
        raise InvalidInputError(f"task {task!r}, split {split!r}; allowed: task in {list(ALL_TIERS)}, "
                                f"split in {list(SPLITS)}")
    benchmark, start, rows, hashes = load_benchmark("v1"), time.perf_counter(), [], {}
    for index, entry in enumerate(tqdm(pool(task, split), disable=not progress, desc=f"{name} {task}/{split}")):
        played = task_scenario(task, entry.seed, benchmark)
        result = planner_episode(played, benchmark, method=method, m=m, T_c=T_c, gain_per_s=gain_per_s)
        hashes[played.name] = planner_task(played, method, gain_per_s).sha256()
        rows.append({"seed": index, "task_index": index, "task_seed": entry.seed, **result.as_dict()})
    metrics = aggregate_v1([row["score"] for row in rows], [row["success"] for row in rows])
    extra = {"training_pool": training_pool, "evaluation_pool": f"{task}/{split}",
             "pool_file_sha256": hashlib.sha256(pool_path(task).read_bytes()).hexdigest(),
             "planner": {"method": method, "m": m, "T_c_s": T_c, "gain_per_s": gain_per_s}, "compute": compute or {}}
    prov = provenance(scenarios=hashes, seeds=list(range(len(rows))), wall_time_s=time.perf_counter() - start)
    return EvalReport("planner", {"task": task, "split": split}, metrics, rows, prov, name=name, extra=extra,
                      score_rule=SCORE_RULE)


def training_loss(m: float, T_c: float, *, tier: str, tasks: int = 20) -> float:
    """1 − the mean v1 score of the predefined-time planner at constant (m, T_c [s]) on the first
    ``tasks`` tasks of ``tier``'s **training** pool: the black-box loss optimisers minimise (in [0, 1]).

    A module-level function: ``functools.partial(training_loss, tier=..., tasks=...)`` pickles
    for process pools and Dask.
    """
    benchmark = load_benchmark("v1")
    episodes = [planner_episode(task_scenario(tier, t.seed, benchmark), benchmark, method="predefined_time", m=m,
                                T_c=T_c) for t in pool(tier, "train")[:tasks]]
    return 1.0 - float(np.mean([e.score for e in episodes]))
