"""The hyperparameter search's loop, here or on a cluster: this process owns the Optuna study, and each trial is a
piece that trains an agent wherever it runs.

The client asks the study for ``batch`` trials at once (their values drawn here, by the study's sampler, in trial
order), sends each to a worker with a snapshot of the study's complete trials, and tells the study what came back.
A worker prunes its own trial with Optuna's pruner judging it against that snapshot, in a study of its own held in
memory: the median pruner looks only at complete trials, so with ``batch`` 1 this is the search ``study.optimize``
runs, decision for decision. With a larger batch, a trial cannot learn from the trials asked with it (nor be pruned
by them), so the search is another one, but the same one on any cluster and in this process: it depends on the
batch, never on which worker ran what or when a piece finished. Workers never reach the study's storage, so a
cluster needs no database server, and the client's SQLite file keeps every told trial: a killed client resumes
with them (trials asked but not told are marked failed and asked again as new trials).
"""

from __future__ import annotations

import json
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import Executor, as_completed
from pathlib import Path
from typing import Any

from tqdm.auto import tqdm

from ffsr_gym.provenance import write_json_atomic
from ffsr_gym_lab.studies.tuning import draw, make_pruner, optuna_module, search_space, to_hyperparams

#: What a trial piece returns: the points it reported, whether it was pruned, its value and its cost.
PIECE_KEYS = ("reports", "pruned_at", "value", "env_steps", "wall_time_s", "record")


def snapshot(study: Any) -> list[dict[str, Any]]:
    """The study's complete trials as the pruner needs them (plain data, so that it pickles to any worker)."""
    optuna = optuna_module()
    return [{"params": t.params, "value": t.value,
             "distributions": {k: optuna.distributions.distribution_to_json(d) for k, d in t.distributions.items()},
             "intermediate_values": {int(s): v for s, v in t.intermediate_values.items()}}
            for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))]


def pruning_judge(complete: list[dict[str, Any]]) -> Callable[[int, float], bool]:
    """``keep_going(step, value)``: report a point of a new trial and say whether it may go on, as the study's
    pruner (:func:`ffsr_gym_lab.studies.tuning.make_pruner`) judges it against ``complete`` (:func:`snapshot`)."""
    optuna = optuna_module()
    verbosity = optuna.logging.get_verbosity()
    optuna.logging.set_verbosity(optuna.logging.WARNING)  # a scratch study's creation is not news to the user
    study = optuna.create_study(direction="maximize", pruner=make_pruner())
    optuna.logging.set_verbosity(verbosity)
    for t in complete:
        study.add_trial(optuna.trial.create_trial(
            params=t["params"], value=t["value"], intermediate_values={int(s): v for s, v in
                                                                       t["intermediate_values"].items()},
            distributions={k: optuna.distributions.json_to_distribution(d) for k, d in t["distributions"].items()}))
    trial = study.ask()

    def keep_going(step: int, value: float) -> bool:
        trial.report(value, step)
        return not trial.should_prune()

    return keep_going


def train_trial(algo: str, env_id: str, tier: str, timesteps: int, points: int, values: dict[str, Any],
                complete: list[dict[str, Any]]) -> dict[str, Any]:
    """One trial, as a piece (:data:`PIECE_KEYS`): train an agent (seed 0) with ``values`` in a folder of its own
    that is removed after, scoring the validation pool at ``points`` curve points, pruned against ``complete``."""
    from ffsr_gym.optim.rl import train

    keep_going, reports, pruned = pruning_judge(complete), [], []

    def on_point(steps: int, mean: float) -> bool:
        reports.append([int(steps), float(mean)])
        if keep_going(steps, mean):
            return True
        pruned.append(int(steps))
        return False

    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="ffsr-trial-") as folder:
        _, record = train(algo, env_id, seed=0, out=folder, task=tier, timesteps=timesteps,
                          curve_every=max(1, timesteps // points), progress=False,
                          params=to_hyperparams(algo, values), on_point=on_point)
        record = json.loads((Path(folder) / "train_record.json").read_text())
    return {"reports": reports, "pruned_at": pruned[0] if pruned else None,
            "value": None if pruned else record["best_on_validation"]["validation_mean"],
            "env_steps": record["trained_steps"],
            "wall_time_s": time.perf_counter() - start, "record": record}


def finished(study: Any) -> int:
    """How many of the study's trials are complete or pruned."""
    states = optuna_module().trial.TrialState
    return sum(t.state in (states.COMPLETE, states.PRUNED) for t in study.get_trials(deepcopy=False))


def search(study: Any, piece: Callable[..., dict[str, Any]], space: dict[str, Any], *, trials: int, batch: int = 1,
           executor: Executor | None = None, work: Path | None = None, progress: bool = True) -> None:
    """Run ``study`` until it holds ``trials`` complete or pruned trials, ``batch`` trials at a time, each as
    ``piece(values, complete)`` (:func:`train_trial` with its first arguments bound) in this process or on
    ``executor``. Each told trial's training record goes to ``<work>/trial<number>/train_record.json``."""
    optuna = optuna_module()
    for stale in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        study.tell(stale.number, state=optuna.trial.TrialState.FAIL)  # asked by a client that was killed
    done = finished(study)
    with tqdm(total=trials, initial=min(done, trials), desc=f"tune {study.study_name}", unit="trial",
              disable=not progress) as bar:
        while done < trials:
            asked, values = [], []
            for _ in range(min(batch, trials - done)):  # ask and draw in trial order, as study.optimize does
                asked.append(study.ask())
                values.append(draw(asked[-1], space))
            complete = snapshot(study)
            if executor is None:
                arrivals = ((trial, piece(v, complete)) for trial, v in zip(asked, values))
            else:
                futures = {executor.submit(piece, v, complete): trial for trial, v in zip(asked, values)}
                arrivals = ((futures[f], f.result()) for f in as_completed(futures))
            for trial, result in arrivals:
                _tell(study, trial, result, work)
                done += 1
                bar.update(1)
                bar.set_postfix(best=f"{study.best_value:.4f}" if _any_complete(study) else "-")


def _tell(study: Any, trial: Any, result: dict[str, Any], work: Path | None) -> None:
    optuna = optuna_module()
    for step, value in result["reports"]:
        trial.report(value, step)
    trial.set_user_attr("env_steps", result["env_steps"])
    trial.set_user_attr("wall_time_s", result["wall_time_s"])
    if work is not None:
        write_json_atomic(Path(work) / f"trial{trial.number}" / "train_record.json", result["record"])
    if result["pruned_at"] is not None:
        study.tell(trial, state=optuna.trial.TrialState.PRUNED)
    else:
        study.tell(trial, result["value"])


def _any_complete(study: Any) -> bool:
    return bool(study.get_trials(deepcopy=False, states=(optuna_module().trial.TrialState.COMPLETE,)))


def default_space(algo: str, env_id: str) -> dict[str, Any]:
    """The searched space of ``algo`` on ``env_id`` (residual or not)."""
    from ffsr_gym.versions.registry import spec_of

    return search_space(algo, spec_of(env_id).is_residual(env_id))
