"""An RL study: one agent per training seed (:func:`ffsr_gym.optim.rl.train`), each scored on the test pool
through :func:`ffsr_gym.evaluate`, gathered into one leaderboard entry per checkpoint (``ffsr-gym train``).

A seed whose folder holds ``train_record.json`` and its test scores is taken from them, never retrained or
rescored, so an interrupted study resumes seed by seed and a study's small records can be kept in git while its
models stay out. The entry carries every seed's trace of applied actions, so ``verify`` replays it without the
models."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from ffsr_gym.bench.entry import EvalReport, entry_name
from ffsr_gym.bench.evaluation import evaluate
from ffsr_gym.bench.policies import SB3_CLASSES, sb3_modules
from ffsr_gym.bench.trace_file import read_entry, write_entry_files
from ffsr_gym.bench.verify import CHECKPOINTS
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym.optim.rl import BEST_MODEL, curve_split, train
from ffsr_gym.provenance import provenance, write_text_atomic
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.versions.registry import spec_of


def train_and_evaluate(algo: str, env_id: str, *, seeds: list[int], out: str | Path, task: str | None = None,
                       timesteps: int | None = None, hyperparams: str | Path | None = None,
                       eval_seeds: list[int] | None = None, curve_every: int = 5000, curve_tasks: int | None = None,
                       progress: bool = True, n_envs: int | None = None,
                       vec_env: str = "batched") -> dict[str, EvalReport]:
    """Train one agent per seed and score them with :func:`evaluate`: one leaderboard entry per checkpoint.

    Returns ``{"last": entry}``, and on a pool version also ``{"best_on_validation": entry}``
    (see :data:`CHECKPOINTS`).
    """
    if not seeds:
        raise InvalidInputError("at least one training seed is needed")
    spec = spec_of(env_id)
    task = task or spec.evaluation.default_task
    pooled = spec.evaluation.protocol == "pool"
    checkpoints = list(CHECKPOINTS) if pooled else ["last"]
    start, rows, runs, recorded = time.perf_counter(), {c: [] for c in checkpoints}, [], {}
    traces: dict[str, list] = {c: [] for c in checkpoints}  # each row's applied actions, while every seed has them
    for seed in seeds:
        folder = seed_folder(out, algo, env_id, task, seed)
        record, evaluations = _scored_seed(folder, checkpoints)
        if evaluations is None:  # not finished and scored yet (a scored seed needs no model: records suffice)
            model, record = train(algo, env_id, task=task, seed=seed, out=folder, timesteps=timesteps,
                                  hyperparams=hyperparams, curve_every=curve_every, curve_tasks=curve_tasks,
                                  progress=progress, n_envs=n_envs, vec_env=vec_env)
            evaluations = {}
            for checkpoint in checkpoints:
                if checkpoint != "last":
                    model = getattr(sb3_modules()[0], SB3_CLASSES[algo]).load(folder / BEST_MODEL, device="cpu")
                evaluations[checkpoint] = _evaluation(model, spec, env_id, task, folder, eval_seeds, checkpoint)
        run = {key: record[key] for key in ("seed", "timesteps", "trained_steps", "n_envs", "wall_time_s", "curve",
                                            "best_on_validation") if key in record}
        for checkpoint in checkpoints:
            rows[checkpoint] += [row | {"train_seed": seed} for row in evaluations[checkpoint]["episodes"]]
            trace = evaluations[checkpoint]["extra"].get("trace")
            if traces[checkpoint] is not None and trace is not None:
                traces[checkpoint].append(trace)
            else:
                traces[checkpoint] = None  # a seed scored before traces were recorded: the entry has none
            run.setdefault("metrics", {})[checkpoint] = evaluations[checkpoint]["metrics"]
            same_scoring(recorded, checkpoint, evaluations[checkpoint], folder, seeds[0])
        runs.append(run)
    # the steps trained (PPO rounds the budget up to whole rollouts), not the budget
    compute = {"env_steps": sum(run.get("trained_steps", run["timesteps"]) for run in runs),
               "wall_time_s": sum(run["wall_time_s"] for run in runs),
               "hardware": "1 CPU core per training seed"}
    reports = {}
    for checkpoint in checkpoints:
        how = {"last": "last checkpoint", "best_on_validation": "checkpoint best on the validation pool"}[checkpoint]
        steps = runs[0]["timesteps"]
        extra = {"method": f"{SB3_CLASSES[algo]} (stable-baselines3), {len(seeds)} training seed"
                           f"{'s' * (len(seeds) != 1)}, {steps:,} env steps each, {how}",
                 "training_seeds": seeds, "checkpoint": checkpoint,
                 "runs": [run | {"metrics": run["metrics"][checkpoint]} for run in runs],
                 "compute": compute, "timesteps_per_seed": steps}
        if pooled:
            extra |= {"training_pool": f"{task}/train", "evaluation_pool": f"{task}/{spec.evaluation.split}",
                      "selection_pool": f"{task}/{curve_split(spec)}",  # and what evaluate recorded: pool file, step
                      **{key: value for key, value in recorded[checkpoint].items() if value is not None}}
            env_kwargs, scenarios = {spec.tasks.keyword: task, "split": spec.evaluation.split}, None
        else:
            env_kwargs, scenarios = {spec.tasks.keyword: task}, {"family": load_scenario(task).sha256()}
        prov = provenance(**({"scenarios": scenarios} if scenarios else {}), seeds=seeds,
                          wall_time_s=time.perf_counter() - start)
        if traces[checkpoint]:  # ``verify`` replays every seed's episodes from their applied actions
            extra["trace"] = merged_traces(traces[checkpoint])
        name = entry_name(algo, spec, env_id, task) + CHECKPOINTS[checkpoint]
        reports[checkpoint] = EvalReport(env_id, env_kwargs, score_rule(spec).aggregate(rows[checkpoint]),
                                         rows[checkpoint], prov, name=name, extra=extra, score_rule=spec.score.text)
    return reports


def same_scoring(recorded: dict[str, dict], checkpoint: str, evaluation: dict, where: str | Path,
                 first_seed: int) -> None:
    """Record what ``evaluation`` (an ``EvalReport`` as JSON) was scored on (pool file, step, reference) for
    ``checkpoint``, refusing one scored on other ones than the seeds before it: the seeds of one entry share them."""
    scored = {key: evaluation["extra"].get(key) for key in ("pool_file_sha256", "dt_s", "reference_sha256")}
    if recorded.setdefault(checkpoint, scored) != scored:
        raise InvalidInputError(f"{where}: scored on another pool file or step than seed {first_seed} "
                                f"({scored} vs {recorded[checkpoint]}); delete its evaluation files to rescore")


def seed_folder(out: str | Path, algo: str, env_id: str, task: str, seed: int) -> Path:
    """The folder of one training seed of a study rooted at ``out`` (model, record, test scores)."""
    return Path(out) / f"{algo}_{env_id}_{task}_seed{seed}"


def scored_seed_files(folder: Path, checkpoints: list[str] | None = None) -> bool:
    """Whether a seed's folder holds its training record and the test scores of every checkpoint."""
    checkpoints = list(CHECKPOINTS) if checkpoints is None else checkpoints
    return all(f.is_file() for f in (folder / "train_record.json", *(_evaluation_file(folder, c) for c in checkpoints)))


def _evaluation_file(folder: Path, checkpoint: str) -> Path:
    return folder / ("evaluation.json" if checkpoint == "last" else f"evaluation_{checkpoint}.json")


def _scored_seed(folder: Path, checkpoints: list[str]) -> tuple[dict[str, Any] | None, dict[str, Any] | None]:
    """A finished seed's training record and test scores per checkpoint, or (None, None) while any is missing."""
    if not scored_seed_files(folder, checkpoints):
        return None, None
    return (json.loads((folder / "train_record.json").read_text()),
            {c: read_entry(_evaluation_file(folder, c)) for c in checkpoints})


def _evaluation(model: Any, spec: BenchmarkSpec, env_id: str, task: str, folder: Path,
                eval_seeds: list[int] | None, checkpoint: str = "last") -> dict[str, Any]:
    """A trained agent's test scores (cached in ``folder``: a resumed study never rescores)."""
    scored = _evaluation_file(folder, checkpoint)
    if scored.is_file():
        return read_entry(scored)
    if spec.evaluation.protocol == "pool":
        evaluation = evaluate(model, env_id, task=task, training_pool=f"{task}/train").to_json()
    else:
        evaluation = evaluate(model, env_id, seeds=eval_seeds, env_kwargs={spec.tasks.keyword: task}).to_json()
    write_entry_files(scored, evaluation)  # its trace in a file beside it, as an entry's
    return evaluation


def merged_traces(traces: list[dict[str, Any]]) -> dict[str, Any]:
    """One trace record of the seeds' evaluations, row after row (the clipped decisions while every seed has them)."""
    merged = traces[0] | {"episodes": [text for trace in traces for text in trace["episodes"]]}
    merged.pop("clipped", None)
    if all("clipped" in trace for trace in traces):
        merged["clipped"] = [indices for trace in traces for indices in trace["clipped"]]
    return merged


def seed_piece(algo: str, env_id: str, task: str, seed: int, timesteps: int, curve_every: int,
               command: list[str]) -> dict[str, str]:
    """One training seed of a study as a cluster piece: trained and scored in a folder of its own on the machine
    that runs it (its models stay there), its records returned (file name -> text) for the client to write into
    the study's folder (:func:`write_seed`). ``command`` is the client's command line, which the records' provenance
    names instead of the worker's."""
    import sys
    import tempfile

    asked, sys.argv = sys.argv, list(command)
    try:
        with tempfile.TemporaryDirectory(prefix="ffsr-gym-seed-") as tmp:
            train_and_evaluate(algo, env_id, task=task, seeds=[seed], out=tmp, timesteps=timesteps,
                               curve_every=curve_every, progress=False)
            folder = seed_folder(tmp, algo, env_id, task, seed)
            return {p.name: json.dumps(read_entry(p)) if p.name.startswith("evaluation") else p.read_text(encoding="utf-8")
                    for p in sorted(folder.glob("*.json"))}
    finally:
        sys.argv = asked


def write_seed(out: str | Path, algo: str, env_id: str, task: str, seed: int, files: dict[str, str]) -> Path:
    """Write a :func:`seed_piece`'s records into the seed's folder of the study at ``out``, each atomically, the
    training record last (a folder is a finished seed once all are there); an evaluation's trace goes to a trace
    file beside it (:func:`ffsr_gym.bench.trace_file.write_entry_files`)."""
    folder = seed_folder(out, algo, env_id, task, seed)
    for name in sorted(files, key=lambda n: n == "train_record.json"):
        if name.startswith("evaluation"):  # its trace to a file beside it
            write_entry_files(folder / Path(name).name, json.loads(files[name]))
        else:
            write_text_atomic(folder / Path(name).name, files[name])
    return folder
