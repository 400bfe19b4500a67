"""Reinforcement-learning baselines with stable-baselines3 (``ffsr-gym train``).

Agents are trained on the registered envs and scored only through :func:`ffsr_gym.evaluate`
(same objective and public seeds as the GA and the planner). One leaderboard entry aggregates
several training seeds. stable-baselines3 and torch are optional (``pip install "ffsr-gym[rl]"``).
"""

from __future__ import annotations

import ast
import json
import time
from pathlib import Path
from typing import Any

from tqdm.auto import tqdm

from ffsr_gym.bench.evaluation import EvalReport, aggregate, evaluate
from ffsr_gym.exceptions import InvalidInputError, MissingDependencyError
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.provenance import provenance, write_json_atomic

ALGOS = {"ppo": "PPO", "sac": "SAC", "td3": "TD3"}
DEFAULT_HYPERPARAMS = Path(__file__).resolve().parents[2] / "baselines" / "hyperparams"


def _sb3():
    try:
        import stable_baselines3
        import torch
    except ImportError as exc:
        raise MissingDependencyError('RL baselines need: pip install "ffsr-gym[rl]" (stable-baselines3, torch==2.13.0)') from exc
    return stable_baselines3, torch


def load_model(algo: str, path: str | Path) -> Any:
    """A saved stable-baselines3 model of ``algo`` (a key of :data:`ALGOS`), on the CPU."""
    if algo not in ALGOS:
        raise InvalidInputError(f"algo {algo!r}; allowed: {sorted(ALGOS)}")
    return getattr(_sb3()[0], ALGOS[algo]).load(path, device="cpu")


def _literal_call(text: str) -> dict[str, Any]:
    """Parse ``"dict(net_arch=[64, 64])"`` (rl-zoo style) without ``eval``."""
    node = ast.parse(text, mode="eval").body
    if not (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "dict" and not node.args):
        raise InvalidInputError(f"policy_kwargs must look like dict(key=literal, ...), got {text!r}")
    return {kw.arg: ast.literal_eval(kw.value) for kw in node.keywords}


def load_hyperparams(algo: str, env_id: str, folder: str | Path | None = None) -> dict[str, Any]:
    """Hyperparameters of ``algo`` for ``env_id`` from ``<folder>/<algo>.yml`` (rl-zoo format)."""
    import yaml

    if algo not in ALGOS:
        raise InvalidInputError(f"algo {algo!r}; allowed: {sorted(ALGOS)}")
    path = Path(folder or DEFAULT_HYPERPARAMS) / f"{algo}.yml"
    if not path.is_file():
        raise InvalidInputError(f"hyperparameter file {str(path)!r} does not exist (pass --hyperparams DIR)")
    table = yaml.safe_load(path.read_text())
    if env_id not in table:
        raise InvalidInputError(f"{path} has no entry for {env_id!r}; it has {sorted(table)}")
    params = dict(table[env_id])
    if "policy_kwargs" in params and isinstance(params["policy_kwargs"], str):
        params["policy_kwargs"] = _literal_call(params["policy_kwargs"])
    return params


class _Progress:
    """A tqdm progress bar as an SB3 callback."""

    def __new__(cls, total: int, desc: str, enabled: bool):
        from stable_baselines3.common.callbacks import BaseCallback

        class Bar(BaseCallback):
            def _on_training_start(self) -> None:
                self.bar = tqdm(total=total, desc=desc, unit="step", disable=not enabled)

            def _on_step(self) -> bool:
                self.bar.update(self.training_env.num_envs)
                return True

            def _on_training_end(self) -> None:
                self.bar.close()

        return Bar()


def train(algo: str, env_id: str, *, seed: int, out: str | Path, scenario: str = "paper", timesteps: int | None = None,
          hyperparams: str | Path | None = None, progress: bool = True) -> tuple[Any, dict[str, Any]]:
    """Train one agent; TensorBoard logs, checkpoints and ``model.zip`` go to ``out``.

    A finished run (``model.zip`` and ``train_record.json`` present) is loaded instead of retrained,
    so an interrupted multi-seed study resumes at the seed it stopped in.

    Returns:
        ``(model, record)`` with the hyperparameters, steps and wall time.
    """
    sb3, torch = _sb3()
    from stable_baselines3.common.callbacks import CheckpointCallback
    from stable_baselines3.common.env_util import make_vec_env

    torch.set_num_threads(1)
    params = load_hyperparams(algo, env_id, hyperparams)
    n_envs, steps = int(params.pop("n_envs", 1)), int(timesteps or params.pop("n_timesteps"))
    params.pop("n_timesteps", None)
    policy = params.pop("policy", "MlpPolicy")
    out = Path(out)
    record = {"algo": algo, "env_id": env_id, "scenario": scenario, "seed": seed, "timesteps": steps, "n_envs": n_envs,
              "policy": policy, "hyperparams": params}
    cls = getattr(sb3, ALGOS[algo])
    if (out / "model.zip").is_file() and (out / "train_record.json").is_file():
        return cls.load(out / "model.zip", device="cpu"), json.loads((out / "train_record.json").read_text())
    start = time.perf_counter()
    env = make_vec_env(env_id, n_envs=n_envs, seed=seed, env_kwargs={"scenario": scenario})
    model = cls(policy, env, seed=seed, device="cpu", verbose=0, tensorboard_log=str(out / "tensorboard"), **params)
    checkpoints = CheckpointCallback(save_freq=max(1, steps // (4 * n_envs)), save_path=str(out / "checkpoints"))
    model.learn(total_timesteps=steps, callback=[checkpoints, _Progress(steps, f"{algo} {env_id} seed {seed}", progress)])
    model.save(out / "model.zip")
    env.close()
    record["wall_time_s"] = time.perf_counter() - start
    write_json_atomic(out / "train_record.json", record)
    return model, record


def train_and_evaluate(algo: str, env_id: str, *, seeds: list[int], out: str | Path, scenario: str = "paper",
                       timesteps: int | None = None, hyperparams: str | Path | None = None,
                       eval_seeds: list[int] | None = None, progress: bool = True) -> EvalReport:
    """Train one agent per seed and score all of them with :func:`evaluate` as one leaderboard entry."""
    if not seeds:
        raise InvalidInputError("at least one training seed is needed")
    start = time.perf_counter()
    rows, runs = [], []
    for seed in seeds:
        model, record = train(algo, env_id, seed=seed, scenario=scenario, timesteps=timesteps, hyperparams=hyperparams,
                              out=Path(out) / f"{algo}_{env_id}_{scenario}_seed{seed}", progress=progress)
        report = evaluate(model, env_id, seeds=eval_seeds, env_kwargs={"scenario": scenario})
        rows += [row | {"train_seed": seed} for row in report.episodes]
        runs.append(record | {"metrics": report.metrics})
    scores = [float("inf") if row["score"] is None else row["score"] for row in rows]
    name = f"{algo}_{scenario}" if env_id == "FFSR-v0" else f"{algo}_residual_{scenario}"
    prov = provenance(scenarios={"family": load_scenario(scenario).sha256()}, seeds=seeds,
                      wall_time_s=time.perf_counter() - start)
    extra = {"method": f"{ALGOS[algo]} (stable-baselines3), {len(seeds)} training seeds", "training_seeds": seeds,
             "runs": runs, "timesteps_per_seed": runs[0]["timesteps"]}
    return EvalReport(env_id, {"scenario": scenario}, aggregate(scores, [row["feasible"] for row in rows]), rows, prov,
                      name=name, extra=extra)
