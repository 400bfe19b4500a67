"""Scoring a policy on the benchmark: ``evaluate`` and the black-box ``objective_for_params``."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from concurrent.futures import Executor
from functools import lru_cache
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from tqdm.auto import tqdm

from ffsr_gym.bench.entry import EvalReport, Policy, PredictsActions, stepper
from ffsr_gym.bench.evaluation_v1 import V1_IDS, evaluate_v1
from ffsr_gym.bench.protocol import BOOTSTRAP_SAMPLES, BOOTSTRAP_SEED, eval_seeds
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.provenance import provenance
from ffsr_gym.scoring.objective import objective_terms
from ffsr_gym.sim.simulate import simulate
from ffsr_gym.tasks.random_family import sample_scenario

__all__ = ["EvalReport", "Policy", "PredictsActions", "aggregate", "evaluate", "objective_for_params"]

#: The ids :func:`evaluate` scores (with the v0 objective).
V0_IDS = ("FFSR-v0", "FFSR-Residual-v0")


def scenario_for_seed(scenario: str | Scenario, seed: int | None) -> Scenario:
    """The scenario an env with ``scenario`` plays after ``reset(seed=seed)``."""
    if isinstance(scenario, str):
        return _named_scenario_for_seed(scenario, seed)
    return _scenario_for_seed(scenario, seed)


@lru_cache(maxsize=256)
def _named_scenario_for_seed(scenario: str, seed: int | None) -> Scenario:
    """Cached per process: GA and CMA-ES evaluate one scenario thousands of times (TOML parsing, hashing)."""
    return _scenario_for_seed(scenario, seed)


def _scenario_for_seed(scenario: str | Scenario, seed: int | None) -> Scenario:
    family = load_scenario(scenario)
    if family.randomization is None:
        return family
    rng, _ = seeding.np_random(seed)
    return sample_scenario(family, rng)


def objective_for_params(m: float, T_c: float, *, scenario: str | Scenario = "paper", seed: int | None = None) -> float:
    """Benchmark score of the reference planner with constant (m, T_c [s]) on one episode.

    Picklable (a module-level function) for process pools. Returns B if the episode is feasible,
    else +inf; never NaN. ``seed`` selects the task of a randomised scenario (as ``reset(seed=...)``).
    The run stops at the first rate-limit violation or collision, whose score is +inf whatever
    follows (GA populations are mostly such settings).
    """
    for name, value in (("m", m), ("T_c", T_c)):
        if not isinstance(value, (int, float, np.floating)) or not math.isfinite(value):
            raise InvalidInputError(f"{name} must be a finite number, got {value!r}")
    played = scenario_for_seed(scenario, seed)
    trajectory = simulate(played, m=float(m), T_c=float(T_c), stop_on_violation=True)
    return objective_terms(trajectory, played.objective).score


def _iqm(values: np.ndarray) -> float:
    v = np.sort(values)
    n = len(v)
    lo, hi = int(math.floor(0.25 * n)), int(math.ceil(0.75 * n))
    middle = v[lo:hi] if hi > lo else v
    return float(np.mean(middle)) if np.all(np.isfinite(middle)) else math.inf


def aggregate(scores: Sequence[float], feasible: Sequence[bool]) -> dict[str, Any]:
    """Mean, interquartile mean, seeded-bootstrap 95% CI of the IQM, and feasible rate.

    Infinite scores (infeasible episodes) make the mean infinite; the IQM is finite while at most
    a quarter of the episodes are infeasible. JSON stores infinity as ``null``.
    """
    values = np.asarray(scores, dtype=float)
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    boots = [_iqm(values[rng.integers(0, len(values), len(values))]) for _ in range(BOOTSTRAP_SAMPLES)]
    return {
        "score_mean": float(np.mean(values)),
        "score_iqm": _iqm(values),
        "score_ci95": [float(np.percentile(boots, 2.5, method="inverted_cdf")),
                       float(np.percentile(boots, 97.5, method="inverted_cdf"))],
        "feasible_rate": float(np.mean(np.asarray(feasible, dtype=float))),
        "episodes": len(values),
    }


def evaluate(policy: Policy, env_id: str, *, seeds: Sequence[int] | None = None, env_kwargs: dict | None = None,
             name: str = "submission", progress: bool = False, task: str | None = None, split: str = "test",
             training_pool: str | None = None, executor: Executor | None = None) -> EvalReport:
    """Score ``policy`` on ``env_id``: v0 with the paper's objective B, v1 with the v1 episode score.

    The env is built here (no caller wrappers can change the score), and each episode is scored
    from its trajectory, never from the summed reward.

    Args:
        policy: a callable obs -> action, an object with SB3-style ``predict(obs, deterministic=True)``,
            or, for ``FFSR-v0`` / ``FFSR-v1``, a fixed ``(m, T_c)`` in physical units (applied
            without float32 rounding).
        env_id: ``"FFSR-v0"``, ``"FFSR-Residual-v0"``, ``"FFSR-v1"`` or ``"FFSR-Residual-v1"``.
        seeds: v0 only: episode seeds; default: the public evaluation seeds of ``env_id``.
        env_kwargs: keyword arguments of ``gymnasium.make`` (e.g. ``{"scenario": "random"}``).
        name: entry name (file name of :meth:`EvalReport.save`).
        progress: show a progress bar.
        task, split, training_pool: v1 only: the tier (default ``"easy"``) and the pool scored
            (default: its **test** pool, one episode per task), and what the policy was trained on
            (recorded in the entry); see :func:`ffsr_gym.bench.evaluation_v1.evaluate_v1`.
        executor: v1 only: score chunks of the pool on any ``concurrent.futures.Executor``
            (processes, Dask); the policy must pickle. Same entry as without.
    """
    if env_id in V1_IDS:
        if seeds is not None:
            raise InvalidInputError("seeds: v1 scores one episode per task of a pool; choose it with task= and split=")
        return evaluate_v1(policy, env_id, task=task or "easy", split=split, training_pool=training_pool,
                           env_kwargs=env_kwargs, name=name, progress=progress, executor=executor)
    if env_id not in V0_IDS:
        raise InvalidInputError(f"env_id {env_id!r}; allowed: {list(V0_IDS + V1_IDS)}")
    if task is not None or training_pool is not None or executor is not None:
        raise InvalidInputError("task=, training_pool= and executor= are v1 arguments; v0 takes env_kwargs={'scenario': ...}")
    kwargs = dict(env_kwargs or {"scenario": "paper"})
    seeds = list(eval_seeds(env_id) if seeds is None else seeds)
    start = time.perf_counter()
    env = gym.make(env_id, **kwargs)
    step = stepper(policy, env)
    rows, hashes = [], {"family": env.unwrapped.family.sha256()}
    for seed in tqdm(seeds, disable=not progress, desc=f"evaluate {env_id}", unit="episode"):
        obs, _ = env.reset(seed=seed)
        done = False
        while not done:
            obs, _, terminated, truncated, _ = step(obs)
            done = terminated or truncated
        played = env.unwrapped.scenario
        traj = env.unwrapped.trajectory
        terms = objective_terms(traj, played.objective)
        metrics = traj.metrics()
        key = played.name if played.randomization is None else f"{played.name}/seed={seed}"
        if key not in hashes:  # a fixed scenario is hashed once, not once per episode
            hashes[key] = played.sha256()
        rows.append({"seed": seed, **terms.as_dict(), "final_ee_position_error_m": metrics["final_ee_position_error_m"],
                     "max_joint_rate_deg_s": metrics["max_joint_rate_deg_s"], "min_clearance_m": metrics["min_clearance_m"],
                     "duration_s": float(traj.t[-1])})
    env.close()
    scores = [math.inf if row["score"] is None else row["score"] for row in rows]
    prov = provenance(scenarios=hashes, seeds=seeds, wall_time_s=time.perf_counter() - start)
    return EvalReport(env_id, kwargs, aggregate(scores, [row["feasible"] for row in rows]), rows, prov, name=name)
