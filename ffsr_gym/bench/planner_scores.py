"""The reference planner with constant parameters as a black box: the v0 objective of one episode,
a version's score of a planner variant over a pool, and the training loss optimisers minimise."""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Sequence
from functools import lru_cache
from typing import Any

import numpy as np
from gymnasium.utils import seeding
from tqdm.auto import tqdm

from ffsr_gym.bench.entry import EvalReport, check_compute
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.provenance import provenance
from ffsr_gym.scoring.objective import objective_terms
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.sim.simulate import simulate
from ffsr_gym.tasks.certificate import Certificate, planner_episode, planner_task, replay
from ffsr_gym.tasks.random_family import sample_scenario
from ffsr_gym.tasks.reference import reference_record
from ffsr_gym.tasks.splits import pool, pool_path, task_scenario
from ffsr_gym.versions.registry import spec_for_version


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
    """Benchmark-v0 score of the reference planner with constant (m, T_c [s]) on one episode.

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


def evaluate_planner(method: str, *, task: str, split: str = "test", m: float | None = None, T_c: float | None = None,
                     gain_per_s: float | None = None, go_s: float | Sequence[float] | None = None,
                     training_pool: str | None = None, name: str = "planner", compute: dict | None = None,
                     progress: bool = False, version: str = "v2") -> EvalReport:
    """Score a reference-planner variant with constant parameters on a tier's pool (one episode per task).

    The planner variants that are not an env action (``proportional``) are scored here, from the
    trajectory with the version's score rule, exactly as :func:`ffsr_gym.evaluate` scores env episodes.
    ``go_s`` [s]: on a version whose action commands the approach (capture v1), when the insertion is commanded
    (:func:`check_go`): one moment for every task, or a list of one per pool task (a method that times each task,
    :mod:`ffsr_gym.bench.lookahead`; each row then records its own).
    ``compute``: what tuning the parameters cost (:func:`~ffsr_gym.bench.entry.check_compute`).
    """
    spec = spec_for_version(version)
    if task not in spec.tasks.tiers or split not in spec.tasks.splits:
        raise InvalidInputError(f"task {task!r}, split {split!r}; allowed: task in {list(spec.tasks.tiers)}, "
                                f"split in {list(spec.tasks.splits)}")
    compute = check_compute(compute) if compute else {}
    rule = score_rule(spec)
    benchmark, start, rows, hashes = rule.benchmark, time.perf_counter(), [], {}
    tasks = pool(task, split, version=benchmark.version)
    per_task = go_s is not None and not isinstance(go_s, (int, float, np.floating))
    if not per_task:
        check_go(go_s, spec, rule)
    moments = per_task_go(go_s, len(tasks), spec, rule) if per_task else [go_s] * len(tasks)
    for index, entry in enumerate(tqdm(tasks, disable=not progress, desc=f"{name} {task}/{split}")):
        played = task_scenario(task, entry.seed, benchmark)
        result = planner_episode(played, benchmark, method=method, m=m, T_c=T_c, gain_per_s=gain_per_s,
                                 go_s=moments[index])
        hashes[played.name] = planner_task(played, method, gain_per_s).sha256()
        rows.append({"seed": index, "task_index": index, "task_seed": entry.seed, **result.as_dict(),
                     **({"go_s": moments[index]} if per_task else {})})
    extra = {"training_pool": training_pool, "evaluation_pool": f"{task}/{split}",
             "pool_file_sha256": hashlib.sha256(pool_path(task, benchmark.version).read_bytes()).hexdigest(),
             "planner": {"method": method, "m": m, "T_c_s": T_c, "gain_per_s": gain_per_s,
                         **({} if go_s is None else {"go_s": list(moments) if per_task else go_s})},
             "compute": compute,
             **reference_record(task, split, benchmark.version)}
    if spec.tasks.step_option:
        extra["dt_s"] = benchmark.dt_s
    prov = provenance(scenarios=hashes, seeds=list(range(len(rows))), wall_time_s=time.perf_counter() - start)
    return EvalReport("planner", {"task": task, "split": split}, rule.aggregate(rows), rows, prov, name=name, extra=extra,
                      score_rule=spec.score.text)


def check_in_box(parameters: Any, m_box: tuple[float, float], t_box: tuple[float, float]) -> None:
    """The one check of a fixed (m, T_c [s]) against an action box, for ``evaluate`` and the black-box losses alike.

    Raises:
        InvalidInputError: not two finite real numbers inside the box (the value and the box named).
    """
    numbers = isinstance(parameters, (tuple, list)) and len(parameters) == 2 and all(
        isinstance(x, (int, float, np.floating)) and not isinstance(x, bool) and np.isfinite(x) for x in parameters)
    if not numbers or not (m_box[0] <= parameters[0] <= m_box[1] and t_box[0] <= parameters[1] <= t_box[1]):
        shown = tuple(float(x) for x in parameters) if numbers else parameters
        raise InvalidInputError(f"fixed parameters (m, T_c) = {shown!r}; allowed: "
                                f"two numbers with m in [{m_box[0]}, {m_box[1]}] and T_c in [{t_box[0]}, {t_box[1]}] s "
                                "(the action box)")


def per_task_go(go_s: Any, tasks: int, spec: Any, rule: Any) -> list[float]:
    """A list of one insertion moment [s] per pool task (each as :func:`check_go` requires), as floats.

    Raises:
        InvalidInputError: not a list of ``tasks`` moments, or a moment outside the range (its index named).
    """
    if isinstance(go_s, (str, bytes, dict)) or not hasattr(go_s, "__len__") or len(go_s) != tasks:
        raise InvalidInputError(f"go_s = {str(go_s)[:60]!r}; allowed: one number, or a list of {tasks} (one per task "
                                "of the pool)")
    for index, moment in enumerate(go_s):
        try:
            check_go(moment, spec, rule)
        except InvalidInputError as exc:
            raise InvalidInputError(f"go_s[{index}]: {exc}") from None
    return [float(moment) for moment in go_s]


def check_go(go_s: Any, spec: Any, rule: Any) -> None:
    """``go_s`` [s] must be given exactly on a version whose action commands the approach, and lie in [0, the
    episode's duration), as :func:`ffsr_gym.evaluate` requires of a timed policy.

    Raises:
        InvalidInputError: naming the value and the range.
    """
    if not spec.actions.command:
        if go_s is not None:
            raise InvalidInputError(f"go_s = {go_s!r}; allowed: None on version {spec.version!r} (its action does not "
                                    "command the approach)")
        return
    duration_s = rule.duration_s
    if isinstance(go_s, bool) or not isinstance(go_s, (int, float, np.floating)) or not 0.0 <= go_s < duration_s:
        raise InvalidInputError(f"go_s = {go_s!r}; allowed on version {spec.version!r}: a number in "
                                f"[0, {duration_s:g}) s, when the insertion is commanded")


def training_loss(m: float, T_c: float, go_s: float | None = None, *, tier: str, tasks: int = 20,
                  version: str = "v2") -> float:
    """1 − the mean score of the predefined-time planner at constant (m, T_c [s]) (going in at ``go_s`` [s] on a
    version whose action commands the approach) on the first ``tasks`` tasks of ``tier``'s **training** pool: the
    black-box loss optimisers minimise (in [0, 1]). A point outside the action box is refused, as
    :func:`ffsr_gym.evaluate` refuses it (:func:`check_in_box`, :func:`check_go`).

    A module-level function: ``functools.partial(training_loss, tier=..., tasks=...)`` pickles
    for process pools and Dask.
    """
    spec = spec_for_version(version)
    rule = score_rule(spec)
    benchmark = rule.benchmark
    check_in_box((m, T_c), benchmark.action.m_bounds, benchmark.action.T_c_bounds_s)  # what evaluate would refuse
    check_go(go_s, spec, rule)
    episodes = [planner_episode(task_scenario(tier, t.seed, benchmark), benchmark, method="predefined_time", m=m,
                                T_c=T_c, go_s=go_s) for t in pool(tier, "train", version=benchmark.version)[:tasks]]
    return 1.0 - float(np.mean([e.score for e in episodes]))


def residual_training_loss(action: Any, *, tier: str, tasks: int = 20, version: str = "v2") -> float:
    """1 − the mean score of a constant residual action (12 values in [-1, 1], rounded to float32 as the env
    rounds its actions) on top of the reference planner, faded as the residual env fades it, over the first
    ``tasks`` tasks of ``tier``'s **training** pool: the black box of a residual search (in [0, 1]; picklable
    with ``functools.partial``).
    """
    try:
        values = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):  # not numbers
        values = None
    if values is None or values.shape != (12,) or not np.all(np.abs(values) <= 1.0):  # the box evaluate refuses a constant outside of
        raise InvalidInputError(f"residual action {action!r}; allowed: 12 numbers in [-1, 1] (the action box)")
    exact = tuple(float(x) for x in values.astype(np.float32))
    benchmark = score_rule(spec_for_version(version)).benchmark
    certificate = Certificate("residual", benchmark.planner.m, benchmark.planner.T_c_s, exact)
    episodes = [replay(task_scenario(tier, t.seed, benchmark), certificate, benchmark)
                for t in pool(tier, "train", version=benchmark.version)[:tasks]]
    return 1.0 - float(np.mean([e.score for e in episodes]))
