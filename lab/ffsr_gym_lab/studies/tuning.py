"""Hyperparameter search for the RL baselines with Optuna, on a tier's training and validation pools only.

A trial trains one agent (seed 0) on the tier's **training** pool with hyperparameters drawn by
Optuna's TPE sampler from :func:`search_space`, scores it on the **validation** pool at every
curve point, and is worth its best validation mean (the same checkpoint selection as the
study, :mod:`ffsr_gym.optim.rl`). Optuna's median pruner stops a trial whose validation mean
lies below the median of earlier trials at the same point. The test pool is never touched.

The study lives in an SQLite file (``studies/tune/`` keeps it in git), so a killed search resumes
with the trials it finished; :mod:`ffsr_gym_lab.studies.tune_loop` runs the trials, here or on a cluster;
:func:`summary` turns it into the JSON record shipped next to the hyperparameter files (search space, every
trial, the best, and what the search cost). Needs ``pip install "ffsr-gym[tune]"``.
"""

from __future__ import annotations

from typing import Any

from ffsr_gym.exceptions import InvalidInputError, require

#: Environment copies every trial trains on (batched env; PPO and SAC).
N_ENVS = {"ppo": 16, "sac": 8}


def optuna_module():
    """optuna, or a named error with the install hint."""
    return require("optuna", "tune", "optuna", "the hyperparameter search needs")


def search_space(algo: str, residual: bool) -> dict[str, list[Any] | tuple[str, float, float]]:
    """The searched hyperparameters: a list of choices, or ``("log", low, high)`` for a log-uniform number.

    SAC takes 1 or 2 gradient steps per step of its 8 copies (a replay ratio of 1/8 or 1/4): SAC's
    usual ratio, one gradient step per environment step, costs 4 to 8 times as many updates, whose
    time dominates SAC's, and the study's 50 seeds of 300k steps would not fit on 2 cores.
    """
    log_std = [-3.0, -2.0, -1.0] if residual else [-1.0, -0.5, 0.0]
    if algo == "ppo":
        return {"learning_rate": ("log", 1e-5, 1e-3), "n_steps": [64, 128, 256, 512],
                "batch_size": [64, 128, 256, 512], "n_epochs": [3, 5, 10], "gamma": [0.95, 0.98, 0.99, 0.995],
                "gae_lambda": [0.9, 0.95, 0.98], "clip_range": [0.1, 0.2, 0.3], "ent_coef": [0.0, 1e-4, 1e-3],
                "log_std_init": log_std, "net_arch": ["64-64", "256-256"]}
    if algo == "sac":
        return {"learning_rate": ("log", 1e-4, 1e-3), "batch_size": [128, 256, 512], "gamma": [0.98, 0.99, 0.995],
                "tau": [0.005, 0.02], "gradient_steps": [1, 2], "learning_starts": [1000, 5000],
                "log_std_init": log_std, "net_arch": ["64-64", "256-256"]}
    raise InvalidInputError(f"algo {algo!r}; allowed: {sorted(N_ENVS)}")


def draw(trial: Any, space: dict[str, Any]) -> dict[str, Any]:
    """One trial's values of ``space``."""
    values = {}
    for name, choices in space.items():
        if isinstance(choices, tuple):
            values[name] = trial.suggest_float(name, choices[1], choices[2], log=True)
        else:
            values[name] = trial.suggest_categorical(name, choices)
    return values


def to_hyperparams(algo: str, values: dict[str, Any]) -> dict[str, Any]:
    """Drawn values as stable-baselines3 constructor arguments (rl-zoo keys; ``policy_kwargs`` as a dict)."""
    params = {key: value for key, value in values.items() if key not in ("log_std_init", "net_arch")}
    width = [int(w) for w in values["net_arch"].split("-")]
    params["policy_kwargs"] = {"net_arch": width, "log_std_init": float(values["log_std_init"])}
    params |= {"policy": "MlpPolicy", "n_envs": N_ENVS[algo]}
    if algo == "sac":
        params |= {"buffer_size": 300_000, "train_freq": 1}
    return params


def make_sampler() -> Any:
    """The search's sampler: Optuna's TPE, seed 0."""
    return optuna_module().samplers.TPESampler(seed=0)


def make_pruner() -> Any:
    """The search's pruner: Optuna's median pruner after 5 complete trials, from the second curve point on."""
    return optuna_module().pruners.MedianPruner(n_startup_trials=5, n_warmup_steps=1)


def summary(study: Any, *, algo: str, env_id: str, tier: str, timesteps: int, points: int, command: str,
            batch: int = 1) -> dict[str, Any]:
    """The search as its shipped record: space, trials, the best trial's hyperparameters, cost, provenance."""
    from ffsr_gym.provenance import provenance
    from ffsr_gym.versions.registry import spec_of

    optuna = optuna_module()
    done = [t for t in study.trials if t.state in (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)]
    trials = [{"number": t.number, "state": t.state.name, "value": t.value, "params": t.params,
               "env_steps": t.user_attrs.get("env_steps"), "wall_time_s": t.user_attrs.get("wall_time_s")}
              for t in done]
    complete = [t for t in done if t.state == optuna.trial.TrialState.COMPLETE]
    if not complete:
        raise InvalidInputError(f"study {study.study_name!r} has no complete trial yet")
    best = max(complete, key=lambda t: t.value)
    space = search_space(algo, spec_of(env_id).is_residual(env_id))
    return {"algo": algo, "env_id": env_id, "tier": tier, "training_pool": f"{tier}/train",
            "selection_pool": f"{tier}/validation",
            "objective": "best mean score on the whole validation pool over the trial's curve points "
                         "(deterministic actions)",
            "trial": {"env_steps": timesteps, "curve_points": points, "seed": 0, "n_envs": N_ENVS[algo]},
            "sampler": "optuna TPESampler(seed=0)",
            "pruner": "optuna MedianPruner(n_startup_trials=5, n_warmup_steps=1)",
            **({} if batch == 1 else {"batch": batch}),
            "space": {k: (list(v) if isinstance(v, tuple) else v) for k, v in space.items()},
            "trials": trials, "best": {"number": best.number, "value": best.value, "params": best.params,
                                       "hyperparams": to_hyperparams(algo, best.params)},
            "cost": {"trials": len(trials), "pruned": len(done) - len(complete),
                     "env_steps": int(sum(t["env_steps"] or 0 for t in trials)),
                     "wall_time_s": float(sum(t["wall_time_s"] or 0.0 for t in trials)), "cores": 1},
            "provenance": provenance(seeds=[0], command=command)}
