"""Reinforcement-learning baselines with stable-baselines3 (``ffsr-gym train``), for every benchmark version.

Agents train where the version's spec says tasks come from (a scenario, or a tier's **training**
pool) and are scored only through :func:`ffsr_gym.evaluate` (the version's protocol and score
rule, never the RL return). One leaderboard entry aggregates several training seeds.

On a pool version, checkpoints are **selected on the validation pool**: every ``curve_every``
environment steps the policy (deterministic actions) is scored on ``curve_tasks`` evenly spaced
tasks of the validation pool (default: all of them); these points are the learning curve, and the
checkpoint with the best mean is kept as ``best_on_validation.zip``. The last and the selected
checkpoint are each scored once on the test pool, as two entries (``<name>`` and
``<name>_valbest``), so readers see how far training drifts from its best. The test pool never
enters training or selection.

A seed whose folder holds ``train_record.json`` and its test scores is taken from them, never retrained
or rescored (the models are not needed then, so a study's small records can be kept in git while
its models stay out), and an interrupted study resumes seed by seed. stable-baselines3 and torch
are optional (``pip install "ffsr-gym[rl]"``); the hyperparameters ship in
``ffsr_gym/hyperparams``.
"""

from __future__ import annotations

import ast
import contextlib
import json
import os
import time
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.bench.evaluation import evaluate
from ffsr_gym.bench.policies import SB3_CLASSES, sb3_modules
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym.provenance import write_json_atomic
from ffsr_gym.tasks.splits import pool
from ffsr_gym.versions.registry import spec_of

DEFAULT_HYPERPARAMS = Path(__file__).resolve().parents[1] / "hyperparams"


def algorithms(folder: str | Path | None = None) -> dict[str, str]:
    """The algorithms ``train`` offers: those with a ``<algo>.yml`` in ``folder`` (default: the shipped ones)."""
    folder = Path(folder or DEFAULT_HYPERPARAMS)
    return {algo: cls for algo, cls in SB3_CLASSES.items() if (folder / f"{algo}.yml").is_file()}


ALGOS = algorithms()


def _literal_call(text: str) -> dict[str, Any]:
    """Parse ``"dict(net_arch=[64, 64])"`` (rl-zoo style) without ``eval``."""
    node = ast.parse(text, mode="eval").body
    if not (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "dict" and not node.args):
        raise InvalidInputError(f"policy_kwargs must look like dict(key=literal, ...), got {text!r}")
    return {kw.arg: ast.literal_eval(kw.value) for kw in node.keywords}


def load_hyperparams(algo: str, env_id: str, folder: str | Path | None = None) -> dict[str, Any]:
    """Hyperparameters of ``algo`` for ``env_id`` from ``<folder>/<algo>.yml`` (rl-zoo format)."""
    import yaml

    offered = algorithms(folder)
    if algo not in offered:
        raise InvalidInputError(f"algo {algo!r}; allowed: {sorted(offered)} (a <algo>.yml in "
                                f"{Path(folder or DEFAULT_HYPERPARAMS)})")
    path = Path(folder or DEFAULT_HYPERPARAMS) / f"{algo}.yml"
    try:
        table = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise InvalidInputError(f"{path}: not a readable hyperparameter file ({type(exc).__name__}: {exc})") from None
    if not isinstance(table, dict) or not isinstance(table.get(env_id, {}), dict):
        raise InvalidInputError(f"{path}: allowed: a mapping from env ids to mappings of hyperparameters")
    if env_id not in table:
        raise InvalidInputError(f"{path} has no entry for {env_id!r}; it has {sorted(table)}")
    params = dict(table[env_id])
    if "policy_kwargs" in params and isinstance(params["policy_kwargs"], str):
        params["policy_kwargs"] = _literal_call(params["policy_kwargs"])
    return params


def progress_bar(total: int, desc: str, enabled: bool):
    """A tqdm progress bar as an SB3 callback."""
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


def curve_split(spec: BenchmarkSpec) -> str:
    """The pool learning curves score: validation when the version has one (never test), else the spec's split."""
    return "validation" if "validation" in spec.tasks.splits else spec.evaluation.split


def curve_indices(tier: str, count: int | None, split: str, version: str | None = None) -> list[int]:
    """The tasks of the learning curve: ``count`` evenly spaced indices of ``tier``'s ``split`` pool (None: all)."""
    size = len(pool(tier, split, version=version))
    if count is None:
        return list(range(size))
    return sorted({int(i) for i in np.linspace(0, size - 1, max(1, min(count, size))).round()})


#: The file of the checkpoint selected on the validation pool, in a seed's folder.
BEST_MODEL = "best_on_validation.zip"


def _curve_callback(env_id: str, tier: str, split: str, every: int, indices: list[int], points: list[dict[str, Any]],
                    best_path: Path, on_point: Any = None):
    """Scores the policy on ``indices`` of the ``split`` pool every ``every`` env steps (and at 0 and at the end),
    appends the points and saves the best-mean checkpoint (the earliest among equals) to ``best_path``.
    ``on_point(steps, mean)`` may stop training by returning False (a tuner's pruning)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class Curve(BaseCallback):
        def _score(self) -> bool:
            report = evaluate(self.model, env_id, task=tier, split=split, indices=indices)
            scores = [row["score"] for row in report.episodes]
            steps, mean = int(self.num_timesteps), float(np.mean(scores))
            points.append({"env_steps": steps, "scores": scores})
            if self.best is None or mean > self.best:
                self.best = mean
                self.model.save(best_path)
            return True if on_point is None else bool(on_point(steps, mean))

        def _on_training_start(self) -> None:
            self.best = None
            self._score()  # the untrained policy, at 0 steps
            self.next = every

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next:
                self.next += every
                return self._score()
            return True

        def _on_training_end(self) -> None:
            if points[-1]["env_steps"] != self.num_timesteps:
                self._score()

    return Curve()


def best_point(points: list[dict[str, Any]]) -> dict[str, Any]:
    """The curve point with the best mean score (the earliest among equals): the selected checkpoint."""
    means = [float(np.mean(p["scores"])) for p in points]
    k = int(np.argmax(means))
    return {"env_steps": points[k]["env_steps"], "validation_mean": means[k]}


def training_kwargs(spec: BenchmarkSpec, task: str) -> dict[str, Any]:
    """The env kwargs agents train on: the scenario, or the tier's training pool."""
    if spec.evaluation.protocol == "pool":
        if task not in spec.tasks.tiers:
            raise InvalidInputError(f"task {task!r}; allowed: {list(spec.tasks.tiers)} (agents train on a tier's "
                                    "training pool)")
        return {spec.tasks.keyword: task, "split": "train"}
    return {spec.tasks.keyword: task}


#: How the training envs are stepped: the batched kernel (:class:`~ffsr_gym.environments.sb3_vec_env.BatchedVecEnv`),
#: or SB3's ``make_vec_env`` over single environments (the same episodes, bit for bit; slower).
VEC_ENVS = ("batched", "single")


def training_env(env_id: str, n_envs: int, seed: int, env_kwargs: dict[str, Any], vec_env: str = "batched") -> Any:
    """The SB3 ``VecEnv`` an agent trains on (see :data:`VEC_ENVS`); copy i is seeded ``seed + i`` at its first reset.

    Raises:
        InvalidInputError: ``vec_env`` or ``n_envs`` out of range.
    """
    if vec_env not in VEC_ENVS:
        raise InvalidInputError(f"vec_env {vec_env!r}; allowed: {list(VEC_ENVS)}")
    if isinstance(n_envs, bool) or not isinstance(n_envs, int) or n_envs < 1:
        raise InvalidInputError(f"n_envs = {n_envs!r}; allowed: an integer >= 1")
    if vec_env == "single":
        import gymnasium as gym
        from stable_baselines3.common.env_util import make_vec_env

        from ffsr_gym.sim.budget import check_run

        with gym.make(env_id, **env_kwargs) as probe:  # n_envs environments of one copy each: their buffers together
            engine = probe.unwrapped.engine
            check_run(steps=engine.n_steps, copies=n_envs, steps_per_decision=engine.steps_per_decision,
                      what=f"{n_envs} training environments")
        return make_vec_env(env_id, n_envs=n_envs, seed=seed, env_kwargs=env_kwargs)
    from ffsr_gym.environments.sb3_vec_env import BatchedVecEnv

    env = BatchedVecEnv(env_id, n_envs, threads=1, **env_kwargs)  # one core per training run
    env.seed(seed)
    return env


def _finished(out: Path, pooled: bool) -> bool:
    return (out / "model.zip").is_file() and (out / "train_record.json").is_file() and (
        not pooled or (out / BEST_MODEL).is_file())


def train(algo: str, env_id: str, *, seed: int, out: str | Path, task: str | None = None, timesteps: int | None = None,
          hyperparams: str | Path | None = None, curve_every: int = 5000, curve_tasks: int | None = None,
          progress: bool = True, n_envs: int | None = None, vec_env: str = "batched", params: dict | None = None,
          on_point: Any = None) -> tuple[Any, dict[str, Any]]:
    """Train one agent; returns ``(model, record)`` (the last model; loaded if ``out`` holds a finished run).

    TensorBoard logs, checkpoints and ``model.zip`` go to ``out``; on a pool version the record
    holds the validation curve and ``out`` the selected checkpoint (:data:`BEST_MODEL`). ``n_envs``
    overrides the hyperparameter file's; ``vec_env`` is one of :data:`VEC_ENVS` (the same episodes
    either way); ``params`` replaces the file's hyperparameters (a tuner's trial). The batched env
    and torch use one thread each, so a run costs one core.
    """
    spec = spec_of(env_id)
    task = task or spec.evaluation.default_task
    env_kwargs = training_kwargs(spec, task)
    sb3, torch = sb3_modules()
    params = dict(params) if params is not None else load_hyperparams(algo, env_id, hyperparams)
    cls, out = getattr(sb3, SB3_CLASSES[algo]), Path(out)
    pooled = spec.evaluation.protocol == "pool"
    if _finished(out, pooled):
        record = json.loads((out / "train_record.json").read_text())
        wanted = int(timesteps or params["n_timesteps"])
        if record.get("timesteps") != wanted:
            warnings.warn(f"{out}: resumed a finished seed trained for {record.get('timesteps')} steps, not the "
                          f"{wanted} asked for; use another --out to train anew", stacklevel=2)
        return cls.load(out / "model.zip", device="cpu"), record
    with _training_lock(out):
        return _train_new(cls, algo, env_id, spec, out=out, task=task, env_kwargs=env_kwargs, params=params,
                          seed=seed, timesteps=timesteps, curve_every=curve_every, curve_tasks=curve_tasks,
                          progress=progress, n_envs=n_envs, vec_env=vec_env, on_point=on_point, torch=torch,
                          pooled=pooled)


def _lock_holder(lock: Path) -> int | None:
    """The live process holding ``lock``, or None (no lock, unreadable, or its process is gone)."""
    try:
        holder = int(lock.read_text())
        os.kill(holder, 0)
    except (OSError, ValueError) as exc:
        return holder if isinstance(exc, PermissionError) else None  # PermissionError: alive, another user's
    return holder


@contextlib.contextmanager
def _training_lock(out: Path) -> Iterator[None]:
    """Hold ``out/.training`` (this process's id) while a seed trains: a second study on the same folder is refused
    by name instead of writing models and records over the first one's. A lock left by a dead process is taken."""
    out.mkdir(parents=True, exist_ok=True)
    lock = out / ".training"
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
            break
        except FileExistsError:
            holder = _lock_holder(lock)
            if holder is not None:
                raise InvalidInputError(f"{out} is being trained by process {holder}; wait for it, or train into "
                                        "another --out / --work") from None
            lock.unlink(missing_ok=True)  # left by a process that is gone
    else:
        raise InvalidInputError(f"{lock}: could not be taken (another process keeps creating it)")
    try:
        os.write(fd, str(os.getpid()).encode())
        os.close(fd)
        yield
    finally:
        lock.unlink(missing_ok=True)


def _train_new(cls: Any, algo: str, env_id: str, spec: BenchmarkSpec, *, out: Path, task: str,
               env_kwargs: dict[str, Any], params: dict[str, Any], seed: int, timesteps: int | None, curve_every: int,
               curve_tasks: int | None, progress: bool, n_envs: int | None, vec_env: str, on_point: Any, torch: Any,
               pooled: bool) -> tuple[Any, dict[str, Any]]:
    """A new training of one seed into ``out`` (see :func:`train`)."""
    from stable_baselines3.common.callbacks import CheckpointCallback

    torch.set_num_threads(1)
    file_envs, steps = int(params.pop("n_envs", 1)), int(timesteps or params.pop("n_timesteps"))
    n_envs = file_envs if n_envs is None else n_envs
    params.pop("n_timesteps", None)
    policy = params.pop("policy", "MlpPolicy")
    start, points = time.perf_counter(), []
    env = training_env(env_id, n_envs, seed, env_kwargs, vec_env)
    model = cls(policy, env, seed=seed, device="cpu", verbose=0, tensorboard_log=str(out / "tensorboard"), **params)
    callbacks = [CheckpointCallback(save_freq=max(1, steps // (4 * n_envs)), save_path=str(out / "checkpoints")),
                 progress_bar(steps, f"{algo} {env_id} {task} seed {seed}", progress)]
    if pooled:
        split = curve_split(spec)
        indices = curve_indices(task, curve_tasks, split, spec.rules.version)
        callbacks.insert(0, _curve_callback(env_id, task, split, curve_every, indices, points, out / BEST_MODEL,
                                            on_point))
    model.learn(total_timesteps=steps, callback=callbacks)
    model.save(out / "model.zip")
    env.close()
    record = {"algo": algo, "env_id": env_id, "task": task, "training_pool": f"{task}/train" if pooled else task,
              "seed": seed, "timesteps": steps, "trained_steps": int(model.num_timesteps), "n_envs": n_envs,
              "vec_env": vec_env, "policy": policy, "hyperparams": params, "wall_time_s": time.perf_counter() - start,
              "cores": 1}
    if pooled:
        record["curve"] = {"split": split, "indices": indices, "every": curve_every, "points": points}
        record["best_on_validation"] = best_point(points)
    write_json_atomic(out / "train_record.json", record)
    return model, record


