"""Scoring a policy on the benchmark: ``evaluate`` and the black-box ``objective_for_params``."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from tqdm.auto import tqdm

from ffsr_gym.bench.protocol import BOOTSTRAP_SAMPLES, BOOTSTRAP_SEED, eval_seeds
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.provenance import provenance, write_json_atomic
from ffsr_gym.scoring.objective import objective_terms
from ffsr_gym.sim.simulate import simulate
from ffsr_gym.tasks.random_family import sample_scenario


@runtime_checkable
class PredictsActions(Protocol):
    """Anything with a stable-baselines3-style ``predict``."""

    def predict(self, observation: Any, deterministic: bool = True) -> tuple[Any, Any]: ...


Policy = Callable[[np.ndarray], np.ndarray] | PredictsActions | tuple[float, float]
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


def _json_safe(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    return x


@dataclass
class EvalReport:
    """Result of :func:`evaluate`: aggregate metrics, per-episode rows and provenance."""

    env_id: str
    env_kwargs: dict[str, Any]
    metrics: dict[str, Any]
    episodes: list[dict[str, Any]]
    provenance: dict[str, Any]
    name: str = "submission"
    extra: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """The leaderboard entry (infinite values as ``null``)."""
        return _json_safe({
            "name": self.name, "env_id": self.env_id, "env_kwargs": self.env_kwargs,
            "protocol": {"seeds": [row["seed"] for row in self.episodes], "episodes": len(self.episodes),
                         "score": "objective B if feasible else inf (null in JSON)",
                         "bootstrap": {"seed": BOOTSTRAP_SEED, "samples": BOOTSTRAP_SAMPLES}},
            "metrics": self.metrics, "episodes": self.episodes, "extra": self.extra, "provenance": self.provenance,
        })

    def save(self, directory: str | Path) -> Path:
        """Write the entry atomically to ``directory/<name>.json`` and return its path."""
        path = Path(directory) / f"{self.name}.json"
        write_json_atomic(path, self.to_json())
        return path


def _stepper(policy: Policy, env: gym.Env) -> Callable[[np.ndarray], tuple]:
    """One env step for ``policy`` given the last observation (fixed parameters bypass float32 actions)."""
    if isinstance(policy, tuple):
        if env.unwrapped.residual:
            raise InvalidInputError("a fixed (m, T_c) policy only applies to FFSR-v0")
        return lambda _obs: env.unwrapped.step_with_parameters(*policy)
    if isinstance(policy, PredictsActions):
        return lambda obs: env.step(policy.predict(obs, deterministic=True)[0])
    if callable(policy):
        return lambda obs: env.step(policy(obs))
    raise InvalidInputError(f"policy must be callable, have .predict, or be a (m, T_c) tuple; got {type(policy).__name__}")


def evaluate(policy: Policy, env_id: str, *, seeds: Sequence[int] | None = None, env_kwargs: dict | None = None,
             name: str = "submission", progress: bool = False) -> EvalReport:
    """Score ``policy`` on ``env_id`` with the benchmark objective, one episode per seed.

    The env is built here (no caller wrappers can change the score); each episode is scored with
    :func:`ffsr_gym.scoring.objective.objective_terms` on its trajectory, never with the summed reward.

    Args:
        policy: a callable obs -> action, an object with SB3-style ``predict(obs, deterministic=True)``,
            or, for ``FFSR-v0``, a fixed ``(m, T_c)`` in physical units (applied without float32 rounding).
        env_id: ``"FFSR-v0"`` or ``"FFSR-Residual-v0"``.
        seeds: episode seeds; default: the public evaluation seeds of ``env_id``.
        env_kwargs: keyword arguments of ``gymnasium.make`` (e.g. ``{"scenario": "random"}``).
        name: entry name (file name of :meth:`EvalReport.save`).
        progress: show a progress bar.
    """
    if env_id not in V0_IDS:
        raise InvalidInputError(f"env_id {env_id!r}: evaluate() scores the v0 ids {list(V0_IDS)}; v1 episodes are "
                                "scored by ffsr_gym.scoring.score.score_episode (v1 evaluation and leaderboards come "
                                "with the v1 task pools)")
    kwargs = dict(env_kwargs or {"scenario": "paper"})
    seeds = list(eval_seeds(env_id) if seeds is None else seeds)
    start = time.perf_counter()
    env = gym.make(env_id, **kwargs)
    step = _stepper(policy, env)
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
