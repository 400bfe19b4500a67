"""RL baselines on benchmark v1: train on a tier's training pool, score on its test pool.

``ffsr-gym train --env-id FFSR-v1 --task easy --algo ppo --seeds 0 1 2 3 4`` trains one agent per
seed on ``split="train"`` and scores every agent with :func:`ffsr_gym.bench.evaluation_v1.evaluate_v1`
on the test pool (one episode per task), as one leaderboard entry. A learning curve is recorded
during training: every ``curve_every`` environment steps the current policy is scored on a fixed
sample of ``curve_tasks`` test tasks (deterministic actions), and the scores go to
``train_record.json``. A seed whose folder holds ``model.zip``, ``train_record.json`` and
``evaluation.json`` is loaded, never retrained or rescored.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from ffsr_gym.bench.entry import EvalReport
from ffsr_gym.bench.evaluation_v1 import SCORE_RULE, V1_IDS, aggregate_v1, evaluate_v1
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.optim.rl import ALGOS, _Progress, _sb3, load_hyperparams
from ffsr_gym.provenance import provenance, write_json_atomic
from ffsr_gym.tasks.splits import pool
from ffsr_gym.tasks.tiers import ALL_TIERS


def curve_indices(tier: str, count: int) -> list[int]:
    """The test tasks of the learning curve: ``count`` evenly spaced pool indices."""
    size = len(pool(tier, "test"))
    return sorted({int(i) for i in np.linspace(0, size - 1, max(1, min(count, size))).round()})


def _curve_callback(env_id: str, tier: str, every: int, indices: list[int], points: list[dict[str, Any]]):
    from stable_baselines3.common.callbacks import BaseCallback

    class Curve(BaseCallback):
        def _score(self) -> None:
            report = evaluate_v1(self.model, env_id, task=tier, split="test", indices=indices)
            points.append({"env_steps": int(self.num_timesteps), "scores": [row["score"] for row in report.episodes]})

        def _on_training_start(self) -> None:
            self._score()  # the untrained policy, at 0 steps
            self.next = every

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next:
                self._score()
                self.next += every
            return True

        def _on_training_end(self) -> None:
            if points[-1]["env_steps"] != self.num_timesteps:
                self._score()

    return Curve()


def train_v1(algo: str, env_id: str, *, tier: str, seed: int, out: str | Path, timesteps: int | None = None,
             hyperparams: str | Path | None = None, curve_every: int = 5000, curve_tasks: int = 10,
             progress: bool = True) -> tuple[Any, dict[str, Any]]:
    """Train one agent on ``tier``'s training pool; returns ``(model, record)`` (loaded if finished)."""
    sb3, torch = _sb3()
    from stable_baselines3.common.env_util import make_vec_env

    if env_id not in V1_IDS or tier not in ALL_TIERS:
        raise InvalidInputError(f"env_id {env_id!r}, tier {tier!r}; allowed: {list(V1_IDS)}, {list(ALL_TIERS)}")
    cls, out = getattr(sb3, ALGOS[algo]), Path(out)
    if (out / "model.zip").is_file() and (out / "train_record.json").is_file():
        return cls.load(out / "model.zip", device="cpu"), json.loads((out / "train_record.json").read_text())
    torch.set_num_threads(1)
    params = load_hyperparams(algo, env_id, hyperparams)
    n_envs, steps = int(params.pop("n_envs", 1)), int(timesteps or params.pop("n_timesteps"))
    params.pop("n_timesteps", None)
    policy = params.pop("policy", "MlpPolicy")
    start, points = time.perf_counter(), []
    env = make_vec_env(env_id, n_envs=n_envs, seed=seed, env_kwargs={"task": tier, "split": "train"})
    model = cls(policy, env, seed=seed, device="cpu", verbose=0, **params)
    callbacks = [_curve_callback(env_id, tier, curve_every, curve_indices(tier, curve_tasks), points),
                 _Progress(steps, f"{algo} {env_id} {tier} seed {seed}", progress)]
    model.learn(total_timesteps=steps, callback=callbacks)
    model.save(out / "model.zip")
    env.close()
    record = {"algo": algo, "env_id": env_id, "training_pool": f"{tier}/train", "seed": seed, "timesteps": steps,
              "n_envs": n_envs, "policy": policy, "hyperparams": params, "wall_time_s": time.perf_counter() - start,
              "curve": {"test_indices": curve_indices(tier, curve_tasks), "points": points}}
    write_json_atomic(out / "train_record.json", record)
    return model, record


def train_and_evaluate_v1(algo: str, env_id: str, *, tier: str, seeds: list[int], out: str | Path,
                          timesteps: int | None = None, hyperparams: str | Path | None = None, curve_every: int = 5000,
                          curve_tasks: int = 10, progress: bool = True) -> EvalReport:
    """Train one agent per seed on ``tier``'s training pool and score all on its test pool as one entry."""
    if not seeds:
        raise InvalidInputError("at least one training seed is needed")
    start, rows, runs = time.perf_counter(), [], []
    for seed in seeds:
        folder = Path(out) / f"{algo}_{env_id}_{tier}_seed{seed}"
        model, record = train_v1(algo, env_id, tier=tier, seed=seed, out=folder, timesteps=timesteps,
                                 hyperparams=hyperparams, curve_every=curve_every, curve_tasks=curve_tasks, progress=progress)
        scored = folder / "evaluation.json"
        if scored.is_file():
            evaluation = json.loads(scored.read_text())
        else:
            evaluation = evaluate_v1(model, env_id, task=tier, training_pool=f"{tier}/train").to_json()
            write_json_atomic(scored, evaluation)
        rows += [row | {"train_seed": seed} for row in evaluation["episodes"]]
        runs.append({key: record[key] for key in ("seed", "timesteps", "n_envs", "wall_time_s", "curve")}
                    | {"metrics": evaluation["metrics"]})
    prov = provenance(seeds=seeds, wall_time_s=time.perf_counter() - start)
    compute = {"env_steps": sum(run["timesteps"] for run in runs), "wall_time_s": sum(run["wall_time_s"] for run in runs)}
    extra = {"method": f"{ALGOS[algo]} (stable-baselines3), {len(seeds)} training seeds", "training_pool": f"{tier}/train",
             "evaluation_pool": f"{tier}/test", "training_seeds": seeds, "runs": runs, "compute": compute}
    metrics = aggregate_v1([row["score"] for row in rows], [row["success"] for row in rows])
    name = f"{algo}_{'residual_' if 'Residual' in env_id else ''}{tier}"
    return EvalReport(env_id, {"task": tier, "split": "test"}, metrics, rows, prov, name=name, extra=extra,
                      score_rule=SCORE_RULE)
