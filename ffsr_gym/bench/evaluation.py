"""Scoring a policy on any benchmark version: ``evaluate``, one code path for every spec.

The spec's evaluation protocol says which episodes make an entry: the public seeds of an id
(``seeds``, v0) or one episode per task of a tier's split (``pool``, v2, the test pool by
default). A version with tiers also scores a *custom task* (a scenario of one's own, one episode
per seed): the same rule, recorded as unranked (``extra.custom_task``) so no leaderboard folder
takes it. Every episode is scored from its trajectory by the spec's score rule
(:mod:`ffsr_gym.scoring.rules`), never from the rewards; the env is built here, so no caller's
wrapper can change a score.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.bench.entry import EvalReport, Policy, PredictsActions, check_compute, policy_origin
from ffsr_gym.bench.episodes import play_batched, play_chunk
from ffsr_gym.bench.planner_scores import check_go, check_in_box, objective_for_params
from ffsr_gym.bench.trace import trace_record
from ffsr_gym.bench.verify import training_pool_problem
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym.provenance import provenance
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.tasks.reference import reference_record
from ffsr_gym.tasks.splits import pool, pool_path
from ffsr_gym.versions.registry import spec_of

__all__ = ["EvalReport", "Policy", "PredictsActions", "evaluate", "objective_for_params"]


@dataclass
class Plan:
    """What an evaluation runs: the env's kwargs and one (seed, pool index or None) per episode."""

    spec: BenchmarkSpec
    env_id: str
    kwargs: dict[str, Any]
    episodes: list[tuple[int, int | None]]
    extra: dict[str, Any] = field(default_factory=dict)
    recorded_kwargs: dict[str, Any] | None = None  # what the entry records, when ``kwargs`` holds a Scenario
    policy_origin: dict[str, Any] | None = None  # what made the policy (entry.policy_origin), found before the run


#: Environment arguments an evaluation may pass besides the task: they change nothing the score reads.
NEUTRAL_KWARGS = ("backend", "render_mode")


def _check_protocol(spec: BenchmarkSpec, kwargs: dict[str, Any]) -> None:
    """Refuse env arguments that change the evaluation protocol (episode length, step, task set).

    Raises:
        InvalidInputError: naming the argument and the ones allowed.
    """
    allowed = spec.env_options() | set(NEUTRAL_KWARGS)
    for name in kwargs:
        if name not in allowed:
            raise InvalidInputError(f"env_kwargs[{name!r}] would change the evaluation protocol of {spec.version} "
                                    f"(an entry plays the spec's whole episodes of its tasks); allowed: {sorted(allowed)}")


def _check_constant(policy: tuple, plan: Plan) -> None:
    """A fixed policy: on a residual id, a constant action of 12 numbers in [-1, 1], exact in float32 (it is played
    as the env's action every decision); else a fixed (m, T_c [s]) (:func:`_check_parameters`).

    Raises:
        InvalidInputError: naming the value and what is allowed.
    """
    if not plan.spec.is_residual(plan.env_id):
        _check_parameters(policy, plan)
        return
    values = np.array([x if isinstance(x, (int, float, np.floating)) and not isinstance(x, bool) else np.nan
                       for x in policy], dtype=float)
    if values.shape != (12,) or not np.all(np.abs(values) <= 1.0) or np.any(values.astype(np.float32) != values):
        raise InvalidInputError(f"constant residual action {policy!r}; allowed: 12 numbers in [-1, 1], exact in float32 "
                                "(np.float32 values), one per joint")


def _check_parameters(policy: tuple, plan: Plan) -> None:
    """A fixed (m, T_c [s]) must be two real numbers inside the version's action box; on an id whose action
    commands the approach (capture v1), a timed (m, T_c [s], go_s [s]): the insertion commanded from the first
    decision at or after go_s, in [0, the episode's duration).

    Raises:
        InvalidInputError: naming the value and the box.
    """
    rule = score_rule(plan.spec)
    if plan.spec.actions.command:
        if not (isinstance(policy, tuple) and len(policy) == 3):
            raise InvalidInputError(f"fixed policy {policy!r}; allowed on {plan.env_id}: (m, T_c [s], go_s [s]), "
                                    f"go_s in [0, {rule.duration_s:g}) s, when the insertion is commanded")
        check_go(policy[2], plan.spec, rule)
        policy = policy[:2]
    if rule.benchmark is not None and plan.spec.actions.boxes == "rules":
        m_box, t_box = rule.benchmark.action.m_bounds, rule.benchmark.action.T_c_bounds_s
    else:
        from ffsr_gym.model.scenario import load_scenario

        env = load_scenario(plan.kwargs.get(plan.spec.tasks.keyword, plan.spec.tasks.default)).env
        m_box, t_box = env.m_bounds, env.T_c_bounds_s
    check_in_box(policy, m_box, t_box)


def _seed_plan(spec: BenchmarkSpec, env_id: str, seeds: Sequence[int] | None, env_kwargs: dict | None,
               pool_arguments: dict[str, Any]) -> Plan:
    given = [name for name, value in pool_arguments.items() if value is not None]
    if given:
        raise InvalidInputError(f"{', '.join(f'{n}=' for n in given)}: arguments of the pool protocol; {env_id} is "
                                f"scored on seeds and takes env_kwargs={{'{spec.tasks.keyword}': ...}}")
    kwargs = dict(env_kwargs or {spec.tasks.keyword: spec.evaluation.default_task})
    chosen = list(spec.eval_seeds(env_id) if seeds is None else seeds)
    return Plan(spec, env_id, kwargs, [(int(s), None) for s in chosen])


def _task_arguments(spec: BenchmarkSpec, env_kwargs: dict | None, task: Any, split: Any) -> tuple[dict, Any, Any]:
    """``env_kwargs`` without the task and split, which may come from either place but not from both.

    Raises:
        InvalidInputError: the same argument given twice.
    """
    kwargs = dict(env_kwargs or {})
    given = {spec.tasks.keyword: task, "split": split}
    for key in given:
        if key in kwargs:
            if given[key] is not None:
                raise InvalidInputError(f"env_kwargs[{key!r}] and {key}= both given; pass it once (as {key}=)")
            given[key] = kwargs.pop(key)
    return kwargs, given[spec.tasks.keyword], given["split"]


def _custom_plan(spec: BenchmarkSpec, env_id: str, task: Any, split: Any, seeds: Sequence[int] | None,
                 indices: Any, kwargs: dict[str, Any], training_pool: str | None) -> Plan:
    """A custom task: one episode per seed (default: seed 0) of the scenario, recorded as unranked."""
    from ffsr_gym.environments.task_source import scenario_task
    from ffsr_gym.model.scenario import to_dict

    for name, value in (("split", split), ("indices", indices)):
        if value is not None:
            raise InvalidInputError(f"{name} = {value!r}: a custom task (a scenario) has no pool; {name} applies to "
                                    f"the tiers {list(spec.tasks.tiers)}")
    scenario = scenario_task(spec, task)
    chosen = [0] if seeds is None else list(seeds)
    if not chosen or any(isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0 for s in chosen):
        raise InvalidInputError(f"seeds = {seeds!r}; allowed: a non-empty list of non-negative integers")
    extra = {"training_pool": training_pool, "evaluation_pool": None,
             "custom_task": {"name": scenario.name, "scenario_sha256": scenario.sha256(), "scenario": to_dict(scenario)}}
    if spec.tasks.step_option:
        extra["dt_s"] = float(kwargs.get("dt_s", scenario.simulation.dt_s))
    recorded = {**kwargs, spec.tasks.keyword: scenario.source or scenario.name}
    return Plan(spec, env_id, {**kwargs, spec.tasks.keyword: scenario}, [(int(s), None) for s in chosen], extra,
                recorded_kwargs=recorded)


def _pool_plan(spec: BenchmarkSpec, env_id: str, *, task: Any, split: str | None, indices: Sequence[int] | None,
               env_kwargs: dict | None, training_pool: str | None, seeds: Sequence[int] | None = None) -> Plan:
    env_kwargs, task, split = _task_arguments(spec, env_kwargs, task, split)
    task = spec.evaluation.default_task if task is None else task
    refused = training_pool_problem(training_pool, spec)
    if refused:
        raise InvalidInputError(refused)
    from ffsr_gym.environments.task_source import is_custom

    if is_custom(spec, task):
        return _custom_plan(spec, env_id, task, split, seeds, indices, env_kwargs, training_pool)
    if seeds is not None:
        raise InvalidInputError(f"seeds: {spec.version} scores one episode per task of a pool; choose it with task= "
                                "and split= (seeds= applies to a custom task)")
    split = spec.evaluation.split if split is None else split
    if task not in (*spec.tasks.scenarios, *spec.tasks.tiers) or split not in spec.tasks.splits:
        raise InvalidInputError(f"task {task!r}, split {split!r}; allowed: task in "
                                f"{[*spec.tasks.scenarios, *spec.tasks.tiers]}, split in {list(spec.tasks.splits)}")
    kwargs = {**(env_kwargs or {}), spec.tasks.keyword: task, "split": split}
    is_pool = task in spec.tasks.tiers
    version = spec.rules.version
    size = len(pool(task, split, version=version)) if is_pool else 1
    chosen = list(range(size) if indices is None else indices)
    if not chosen or any(isinstance(i, bool) or not isinstance(i, (int, np.integer)) or not 0 <= i < size for i in chosen):
        raise InvalidInputError(f"indices must be a non-empty list of integers in [0, {size - 1}], got {indices!r}")
    pools = pool_path(task if is_pool else spec.tasks.tiers[0], version).read_bytes()
    extra = {"training_pool": training_pool, "evaluation_pool": f"{task}/{split}",
             "pool_file_sha256": hashlib.sha256(pools).hexdigest()}
    extra |= reference_record(task, split, version)
    if spec.tasks.step_option:  # the step the episodes ran at; the leaderboard ranks the benchmark's own only
        extra["dt_s"] = float(kwargs.get("dt_s", spec.rules.dt_s))
    return Plan(spec, env_id, kwargs, [(int(i), int(i) if is_pool else None) for i in chosen], extra)


def evaluate(policy: Policy, env_id: str, *, seeds: Sequence[int] | None = None, env_kwargs: dict | None = None,
             name: str = "submission", progress: bool = False, task: str | None = None, split: str | None = None,
             training_pool: str | None = None, executor: Executor | None = None, indices: Sequence[int] | None = None,
             chunk: int = 10, batched: bool | None = None, compute: dict[str, Any] | None = None,
             policy_library: str | None = None) -> EvalReport:
    """Score ``policy`` on ``env_id`` by its version's protocol and score rule.

    Args:
        policy: a callable obs -> action, an object with SB3-style ``predict(obs, deterministic=True)``,
            or a tuple: on an (m, T_c) id, a fixed ``(m, T_c)`` in physical units (no float32 rounding); on a
            residual id, a constant action (12 values in [-1, 1], exact in float32).
        env_id: a registered id (``ffsr-gym list``).
        seeds: protocol ``seeds`` (v0): episode seeds; default: the id's public evaluation seeds.
        env_kwargs: other ``gymnasium.make`` arguments (v0: ``{"scenario": ...}``; never the score).
        name: entry name (file name of :meth:`EvalReport.save`).
        progress: show a progress bar.
        task: protocol ``pool`` (v2): the tier (default ``"easy"``), or a custom task (below).
        split: protocol ``pool``: the pool scored (default: the tier's **test** pool, one episode per task).
        indices: protocol ``pool``: the pool indices scored (default: all).
        training_pool: protocol ``pool``: what the policy was trained or tuned on, recorded in the entry:
            ``"<tier>/train"`` or ``"<tier>/validation"`` (optionally followed by ``" (a note)"``), never a test
            pool.
        executor: protocol ``pool``: score chunks of ``chunk`` tasks on any
            ``concurrent.futures.Executor`` (processes, Dask); the policy must pickle. Same entry.
        chunk: with ``executor``, the tasks of one piece of work sent to it (an integer >= 1).
        batched: a fixed (m, T_c) on a pool runs all tasks in one batched env in this process
            (None: whenever possible without an executor; the same entry, tested bit for bit).
        compute: what training or tuning the policy cost, for the leaderboard's compute column:
            ``{"env_steps": int, "wall_time_s": float}`` (or ``objective_evaluations`` for an
            optimiser's episodes), optionally ``"hardware": str`` (:func:`check_compute`).
            Recorded as the entry's ``extra.compute``.
        policy_library: the library that made the policy (e.g. ``"tianshou 2.0.1"``), recorded in the
            entry's ``provenance.policy`` beside the package found from the policy object's module.

    A task that is not a tier (a :class:`Scenario`, a scenario TOML path or a shipped scenario
    name, as ``task=`` or ``env_kwargs={"task": ...}``) is a custom task: one episode per seed of
    ``seeds`` (default ``[0]``), recorded as unranked (``extra.custom_task`` holds the scenario).

    A policy that is code (a callable, a model) gets its applied actions recorded in the entry
    (``extra.trace``, :mod:`ffsr_gym.bench.trace`), so that ``ffsr-gym leaderboard verify`` replays
    the entry without running it.
    """
    plan = plan_evaluation(policy, env_id, seeds=seeds, env_kwargs=env_kwargs, task=task, split=split,
                           training_pool=training_pool, executor=executor, indices=indices, batched=batched)
    if isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1:
        raise InvalidInputError(f"chunk = {chunk!r}; allowed: an integer >= 1")
    if compute is not None:
        plan.extra["compute"] = check_compute(compute)
    plan.policy_origin = policy_origin(policy, policy_library)  # checked before any episode
    return run_plan(policy, plan, name=name, progress=progress, executor=executor, chunk=chunk, batched=batched)


def plan_evaluation(policy: Policy, env_id: str, *, seeds: Sequence[int] | None = None, env_kwargs: dict | None = None,
                    task: str | None = None, split: str | None = None, training_pool: str | None = None,
                    executor: Executor | None = None, indices: Sequence[int] | None = None,
                    batched: bool | None = None) -> Plan:
    """The checked :class:`Plan` of an :func:`evaluate` call (its arguments, the same meaning).

    Raises:
        InvalidInputError: any argument outside what the version's protocol allows (named).
    """
    spec = spec_of(env_id)
    if spec.evaluation.protocol == "seeds":
        plan = _seed_plan(spec, env_id, seeds, env_kwargs, {"task": task, "split": split, "training_pool": training_pool,
                                                            "executor": executor, "indices": indices, "batched": batched})
    else:
        plan = _pool_plan(spec, env_id, task=task, split=split, indices=indices, env_kwargs=env_kwargs,
                          training_pool=training_pool, seeds=seeds)
    _check_protocol(spec, plan.kwargs)
    if isinstance(policy, tuple):
        _check_constant(policy, plan)
    return plan


def _runner(policy: Any, plan: Plan, executor: Executor | None, chunk: int, batched: bool | None):
    """How the plan's episodes run: one batched env, or chunks of single envs (serially or on ``executor``)."""
    pooled = plan.spec.evaluation.protocol == "pool" and "custom_task" not in plan.extra
    residual = plan.spec.is_residual(plan.env_id)
    fixed = (isinstance(policy, tuple) and pooled and not residual and not plan.spec.actions.command
             and plan.kwargs.get("terminate_on_violation", True)
             is True and set(plan.kwargs) <= {plan.spec.tasks.keyword, "split", "dense_shaping", "terminate_on_violation",
                                              "dt_s"})
    if batched and not fixed:
        raise InvalidInputError(f"batched=True needs a fixed (m, T_c) policy on {plan.spec.ids.parameters} with a pool, "
                                "terminate_on_violation=True and no env_kwargs other than dense_shaping")
    if batched and executor is not None:
        raise InvalidInputError("batched=True runs in this process (the batched kernel's threads do not survive a fork); "
                                "with an executor each worker runs single environments")
    if fixed and executor is None and batched is not False:
        return partial(play_batched, policy, plan.spec.version, plan.kwargs), len(plan.episodes)
    return partial(play_chunk, policy, plan.env_id, plan.kwargs, pooled), chunk


def run_plan(policy: Any, plan: Plan, *, name: str = "submission", progress: bool = False,
             executor: Executor | None = None, chunk: int = 10, batched: bool | None = None) -> EvalReport:
    """The entry of ``policy`` played on a :func:`plan_evaluation` plan (what :func:`evaluate` returns)."""
    start = time.perf_counter()
    if executor is not None:
        _check_pickles(policy)
    run, size = _runner(policy, plan, executor, chunk, batched)
    pieces = [plan.episodes[k:k + size] for k in range(0, len(plan.episodes), size)]
    results = (map if executor is None else executor.map)(run, pieces)
    rows, hashes, traces = [], {}, []
    if plan.spec.evaluation.protocol == "seeds":
        hashes["family"] = _family_hash(plan)
    label = f"evaluate {plan.env_id}" + (f" {plan.extra['evaluation_pool']}" if plan.extra else "")
    with tqdm(total=len(plan.episodes), disable=not progress, desc=label, unit="episode") as bar:
        for episodes in results:
            for row, key, sha, trace in episodes:
                rows.append(row)
                traces.append(trace)
                hashes.setdefault(key, sha)
            bar.update(len(episodes))
    rule = score_rule(plan.spec)
    prov = provenance(scenarios=hashes, seeds=[seed for seed, _ in plan.episodes],
                      wall_time_s=time.perf_counter() - start)
    extra = dict(plan.extra)
    if isinstance(policy, tuple):  # what `ffsr-gym leaderboard verify` re-runs
        extra["policy"] = {"fixed": [float(x) for x in policy]}
    else:  # what `ffsr-gym leaderboard verify` replays without running the policy, and what made the policy
        width = (12 if plan.spec.is_residual(plan.env_id) else 2) + int(plan.spec.actions.command)
        extra["trace"] = trace_record([text for text, _ in traces], (width,),
                                      [clipped for _, clipped in traces])
        prov["policy"] = plan.policy_origin if plan.policy_origin is not None else policy_origin(policy)
    return EvalReport(plan.env_id, plan.kwargs if plan.recorded_kwargs is None else plan.recorded_kwargs,
                      rule.aggregate(rows), rows, prov, name=name, extra=extra,
                      score_rule=plan.spec.score.text)


def _check_pickles(policy: Any) -> None:
    """An executor's workers get the policy by pickle: refuse, by name, one that does not pickle before any work.

    Raises:
        InvalidInputError: naming the policy and what pickles.
    """
    import pickle

    try:
        pickle.dumps(policy)
    except Exception as exc:  # noqa: BLE001 - pickle raises many kinds for what it cannot do
        raise InvalidInputError(f"policy {policy!r} does not pickle ({type(exc).__name__}: {exc}), so executor workers "
                                "cannot receive it; allowed with an executor (--workers > 1): fixed parameters, an SB3 "
                                "model, or a function of an importable module (module:callable)") from None


def _family_hash(plan: Plan) -> str:
    """The hash of the scenario (family) a seeds-protocol env plays."""
    from ffsr_gym.model.scenario import load_scenario

    return load_scenario(plan.kwargs.get(plan.spec.tasks.keyword, plan.spec.tasks.default)).sha256()
