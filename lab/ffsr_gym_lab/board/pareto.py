"""Smoothness against convergence time on one task: the planner over the (m, T_c) action box and every baseline.

``ffsr-gym leaderboard pareto --root leaderboards --models runs/rl_study`` runs, on the first
task of the ranked version's easy test pool (:data:`PARETO_TIER`, index 0), the predefined-time
planner at every (m, T_c) of :data:`GRID_M` × :data:`GRID_T_C_S` and every baseline of
``<root>/<version>/<tier>/*.json``: a planner entry at its recorded parameters, an RL entry with
each training seed's model (``<models>/<algo>_<env id>_<tier>_seed<s>/model.zip``, deterministic
actions). Every episode is scored by :func:`ffsr_gym.scoring.score.score_episode`; the points go
to ``<root>/<version>/pareto.json`` (with provenance; the name is
``ffsr_gym_lab.board.plots.PARETO_FILE``), from which ``ffsr-gym leaderboard plot``
draws ``pareto.png``. An RL entry whose models are missing is listed as such, never dropped
silently. (v1 drew it on ``paper``; under v2's blend law no (m, T_c) reaches the target there.)
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.bench.evaluation import evaluate
from ffsr_gym.bench.policies import SB3_CLASSES
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.provenance import provenance, write_json_atomic
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.scoring.score import EpisodeScore
from ffsr_gym.tasks.certificate import planner_episode, planner_task
from ffsr_gym.tasks.splits import pool, task_scenario
from ffsr_gym.versions.registry import ranked_spec
from ffsr_gym_lab.board.leaderboard import load_entries, verified
from ffsr_gym_lab.board.tables import method_name

#: The task of the study: index 0 of this tier's test pool.
PARETO_TIER = "easy"
#: The planner grid: 12 values of m and 10 of T_c [s] spanning the (m, T_c) action box.
GRID_M = tuple(float(x) for x in np.round(np.linspace(0.05, 0.6, 12), 4))
GRID_T_C_S = tuple(float(x) for x in np.linspace(1.0, 10.0, 10))


def _point(result: EpisodeScore | dict[str, Any], **where: Any) -> dict[str, Any]:
    row = result.as_dict() if isinstance(result, EpisodeScore) else result
    return {**where, **{key: row[key] for key in ("score", "success", "failure", "smoothness_cost", "convergence_time_s")}}


def _rl_points(entry: dict[str, Any], tier: str, models: Path | None,
               load_model: Callable[[str, Path], Any] | None) -> tuple[list[dict], str | None]:
    """One point per training seed whose model is found; or why there are none. The model's path is made from
    the entry's algorithm, env id and seeds only when each has the form a study writes, and must stay inside
    ``models``: an entry does not choose which files are unpickled."""
    if models is None or load_model is None:
        return [], "no model folder given"
    algo = str(entry["name"]).split("_")[0]
    if algo not in SB3_CLASSES or entry.get("env_id") not in ranked_spec().env_ids:
        return [], f"not an RL study's entry (algorithm {algo[:20]!r}, env id {str(entry.get('env_id'))[:40]!r})"
    points = []
    for run in entry["extra"]["runs"]:
        seed = run.get("seed") if isinstance(run, dict) else None
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            return [], f"a run's seed {str(seed)[:20]!r} is not an integer >= 0"
        path = (models / f"{algo}_{entry['env_id']}_{tier}_seed{seed}" / "model.zip").resolve()
        if not path.is_relative_to(models.resolve()):
            return [], f"model path leaves {models}"
        if not path.is_file():
            return [], f"model missing: {path}"
        row = evaluate(load_model(algo, path), entry["env_id"], task=PARETO_TIER, indices=[0]).episodes[0]
        points.append(_point(row, train_seed=run["seed"]))
    return points, None


def task_pareto(root: str | Path, out: str | Path, models: str | Path | None = None, *,
                load_model: Callable[[str, Path], Any] | None = None, progress: bool = True,
                command: str | None = None, trust_model: bool = False) -> Path:
    """Compute the grid and the points of the verified baselines under ``<root>/<version>/`` on the study's task;
    write them to ``out``.

    ``load_model(algo, path)`` loads an RL entry's model (``ffsr_gym.optim.rl.load_model``); without
    it or ``models``, RL entries are listed as not run. Loading an SB3 model unpickles it, which runs code of its
    maker's choosing: ``models`` is refused unless ``trust_model`` (``--trust-model``) says its source is trusted.

    Raises:
        InvalidInputError: ``models`` without ``trust_model``, or not a folder.
    """
    if models is not None:
        if not trust_model:
            raise InvalidInputError(f"--models {str(models)!r}: loading its SB3 models unpickles them, which can run "
                                    "any code their maker chose; pass --trust-model if you trust their source")
        if not Path(models).is_dir():
            raise InvalidInputError(f"--models {str(models)!r}: not a folder; allowed: the RL study's model folder")
    root, start = Path(root), time.perf_counter()
    benchmark = score_rule(ranked_spec()).benchmark
    first = pool(PARETO_TIER, "test", version=benchmark.version)[0]
    task, label = task_scenario(PARETO_TIER, first.seed, benchmark), f"{PARETO_TIER}/test[0]"
    settings = [(m, T_c) for m in GRID_M for T_c in GRID_T_C_S]
    grid = [_point(planner_episode(task, benchmark, method="predefined_time", m=m, T_c=T_c), m=m, T_c_s=T_c)
            for m, T_c in tqdm(settings, desc=f"{label} grid", disable=not progress)]
    baselines: list[dict[str, Any]] = []
    fixed: dict[str, dict[str, Any]] = {}  # a planner setting that several tiers' entries share: one point
    entries = [(tier, entry) for tier, items in verified(load_entries(root, ranked_spec())).items() for entry in items]
    for tier, entry in tqdm(entries, desc=f"baselines on {label}", disable=not progress):
        planner = entry.get("extra", {}).get("planner")
        if planner is not None:
            key = entry["name"] + json.dumps(planner, sort_keys=True)
            if key in fixed:
                fixed[key]["tiers"].append(tier)
                continue
            result = planner_episode(task, benchmark, method=planner["method"], m=planner["m"], T_c=planner["T_c_s"],
                                     gain_per_s=planner["gain_per_s"])
            fixed[key] = {"name": entry["name"], "method": method_name(entry, tier), "tiers": [tier], "planner": planner,
                          "points": [_point(result)],
                          "missing": None, "task_sha256": planner_task(task, planner["method"], planner["gain_per_s"]).sha256()}
            baselines.append(fixed[key])
        else:
            points, missing = _rl_points(entry, tier, None if models is None else Path(models), load_model)
            baselines.append({"name": entry["name"], "method": method_name(entry, tier), "tiers": [tier], "planner": None,
                              "points": points,
                              "missing": missing, "task_sha256": task.sha256()})
    out = Path(out)
    prov = provenance(scenarios={task.name: task.sha256()}, command=command, wall_time_s=time.perf_counter() - start)
    write_json_atomic(out, {"task": label, "task_name": task.name,
                            "grid": {"m": list(GRID_M), "T_c_s": list(GRID_T_C_S), "points": grid},
                            "baselines": baselines, "provenance": prov})
    return out
