"""The best known score of every pool task: a per-task CMA-ES over action schedules.

For one task, CMA-ES (the ``cma`` package) searches each :class:`~ffsr_gym.tasks.schedule.Schedule`
family of the version (:func:`~ffsr_gym.tasks.schedule.version_families`): the residual of
``FFSR-Residual-v2`` at :data:`KNOTS` knots per joint, and the (m, T_c) action of ``FFSR-v2`` at
:data:`KNOTS` knots; on capture v1 the one-knot ``timed`` schedule (m, T_c and the decision the
insertion is commanded at). A family starts from the task's certificate when the certificate is of its
kind (a constant residual, a constant (m, T_c), a timed one), else from the default planner (a zero
residual; (m, T_c) = the default). Each generation is one batched env of the
population playing the task (one core). A family's result is its best schedule that also passes
the certificate test: success in every kernel member of the ensemble (dt/2, dt/4, starts a hair
off) with the margins outside the hair's-breadth band, trying the search's best candidates in
order and the start last. The task's best known score is the better family's, confirmed on the
Pinocchio backend (the ensemble's last member); when it fails there, the other family's; when no
schedule passes, the certificate's (family ``certificate``, replayed as the pool's certificates are).

Every result is an action sequence of a registered env, replayable with ``env.step`` (tests),
stored with the pools (``envs/benchmark/<version>_best_known.json``).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from ffsr_gym.exceptions import InvalidInputError, require
from ffsr_gym.model.benchmark import Benchmark
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.scoring.score import EpisodeScore, score_episode
from ffsr_gym.tasks.capture_family import capture_family
from ffsr_gym.tasks.certificate import Margins, ensemble_members, go_decision_of, whole_run_ratio
from ffsr_gym.tasks.perturbation import confirmation_member
from ffsr_gym.tasks.schedule import FAMILIES, Schedule, go_value, replay_schedule, schedule_run, version_families
from ffsr_gym.tasks.splits import PoolTask, pool, task_scenario

#: Knots per schedule.
KNOTS = 4
#: CMA-ES settings: initial step (in action units), generations, seed; the population is cma's default.
SIGMA0 = 0.3
GENERATIONS = 30
CMA_SEED = 1
#: Candidates of a search tried against the ensemble, best first, before the start.
TRIED = 5


def knots(family: str) -> int:
    """Knots of a family's search (a timed schedule has one)."""
    return 1 if family == "timed" else KNOTS


def start(task: PoolTask, family: str, benchmark: Benchmark) -> tuple[Schedule, str]:
    """The family's starting schedule and where it comes from (``certificate`` or ``default``)."""
    cert = task.certificate
    if family == "residual":
        if cert.residual is not None:
            return Schedule.constant(family, cert.residual, KNOTS), "certificate"
        return Schedule.constant(family, np.zeros(12), KNOTS), "default"
    box = benchmark.action
    (m_lo, m_hi), (t_lo, t_hi) = box.m_bounds, box.T_c_bounds_s
    m, T_c, origin = (cert.m, cert.T_c_s, "certificate") if cert.residual is None else (
        benchmark.planner.m, benchmark.planner.T_c_s, "default")
    action = [2.0 * (m - m_lo) / (m_hi - m_lo) - 1.0, 2.0 * (T_c - t_lo) / (t_hi - t_lo) - 1.0]
    if family == "timed":  # the certificate's moment
        action.append(timed_go(cert.go_s, benchmark))
    return Schedule.constant(family, action, knots(family)), origin


def timed_go(go_s: float, benchmark: Benchmark) -> float:
    """A timed schedule's g for a go time ``go_s`` [s]: the first decision at or after it, in the family scenario's
    decisions (every task's episode)."""
    played = capture_family(benchmark)
    interval = played.env.decision_interval_s
    decisions = round(played.simulation.duration_s / interval)
    return go_value(go_decision_of(go_s, interval), decisions)


class Population:
    """Scores many schedules of one family on one pool task at once (a batched env; bit-identical with
    :func:`~ffsr_gym.tasks.schedule.replay_schedule`, tested)."""

    def __init__(self, family: str, tier: str, split: str, size: int, version: str = "v2") -> None:
        from ffsr_gym.environments.vector_env import FFSRVectorEnv

        self.family, self.size = family, size
        self.venv = FFSRVectorEnv(size, version, family == "residual", threads=1, autoreset_mode="Disabled",
                                  task=tier, split=split)

    def scores(self, index: int, schedules: list[Schedule]) -> np.ndarray:
        """The v2 score of each schedule on pool task ``index`` (at most ``size`` schedules)."""
        return np.array([result.score for result in self.episodes(index, schedules)])

    def episodes(self, index: int, schedules: list[Schedule]) -> list:
        """The scored episode (:class:`~ffsr_gym.scoring.score.EpisodeScore`) of each schedule on task ``index``."""
        if not 0 < len(schedules) <= self.size:
            raise InvalidInputError(f"{len(schedules)} schedules; allowed: 1 to {self.size}")
        padded = schedules + [schedules[0]] * (self.size - len(schedules))
        self.venv.reset(seed=list(range(self.size)), options={"task_index": [index] * self.size})
        scenario = self.venv.engine.scenarios[0]
        actions = np.stack([s.actions(scenario) for s in padded], axis=1)  # (decisions, copies, width)
        engine = self.venv.engine
        for k in range(actions.shape[0]):
            if all(engine.finished(i) for i in range(self.size)):
                break
            self.venv.step(np.ascontiguousarray(actions[k]))
        return [engine.results[i] for i in range(len(schedules))]

    def close(self) -> None:
        self.venv.close()


@dataclass
class FamilyResult:
    """A family's best schedule that passes the kernel ensemble (or None), and what the search cost."""

    family: str
    schedule: Schedule | None
    score: float
    margins: Margins | None
    origin: str
    evaluations: int
    searched_best: float

    def as_dict(self) -> dict[str, Any]:
        return {"family": self.family, "schedule": None if self.schedule is None else self.schedule.as_dict(),
                "score": self.score, "margins": None if self.margins is None else self.margins.as_dict(),
                "origin": self.origin, "evaluations": self.evaluations, "searched_best": self.searched_best}


def replayed(task: Scenario, schedule: Schedule, benchmark: Benchmark, *, backend: str = "auto") -> EpisodeScore:
    """:func:`~ffsr_gym.tasks.schedule.replay_schedule`, a timed schedule's capture ratio that of its whole run (the
    margin its certificate test judges, as a timed certificate's: ``certificate.whole_run_ratio``)."""
    if schedule.family != "timed":
        return replay_schedule(task, schedule, benchmark, backend=backend)
    run = schedule_run(task, schedule, benchmark, backend=backend)
    return dataclasses.replace(score_episode(run, task, benchmark), capture_ratio=whole_run_ratio(run, task, benchmark))


def passes(task: PoolTask, tier: str, schedule: Schedule, benchmark: Benchmark, *, pinocchio: bool) -> Margins | None:
    """The worst margins of ``schedule`` over the task and its ensemble members, or None when an episode fails
    or a margin lies in the hair's-breadth band (the certificate test)."""
    scenario = task_scenario(tier, task.seed, benchmark)
    results = [replayed(scenario, schedule, benchmark)]
    members = ensemble_members(scenario, task.seed, benchmark.tasks.ensemble, pinocchio=False)
    if pinocchio:  # the Pinocchio backend, or a servo task's finer physics step
        members.append(confirmation_member(scenario, benchmark.version))
    for member in members if results[0].success else []:
        results.append(replayed(member.task, schedule, benchmark, backend=member.backend))
        if not results[-1].success:
            break
    if not all(r.success for r in results):
        return None
    margins = Margins.worst(results)
    return margins if margins.short(benchmark) is None else None


def screened_scores(population: Population, index: int, schedules: list[Schedule], benchmark: Benchmark) -> np.ndarray:
    """The screened objective: a schedule's score when its own episode succeeds with every margin outside the
    hair's-breadth band (what the certificate test asks of each ensemble member), else its score - 1, so that every
    such candidate ranks above every other and none counts as found (scores <= 0 are never tried)."""
    played = population.episodes(index, schedules)
    if population.family == "timed":  # an episode ends at its capture: the whole run's ratio is the test's to judge
        played = [dataclasses.replace(r, capture_ratio=0.0) for r in played]
    return np.array([r.score if r.success and Margins.worst([r]).short(benchmark) is None else r.score - 1.0
                     for r in played])


def search_family(population: Population, task: PoolTask, tier: str, index: int, benchmark: Benchmark,
                  generations: int = GENERATIONS, *, screened: bool = False) -> FamilyResult:
    """CMA-ES over one family's knots on one task, then the ensemble check of its best candidates. ``screened``
    searches on :func:`screened_scores`: the default search ranks on the score alone and, where its best candidates
    then fail the certificate test, falls back to a lesser one (often the certificate)."""
    objective = (lambda i, batch: screened_scores(population, i, batch, benchmark)) if screened else population.scores
    cma = require("cma", "baselines", "cma", "the best-known search needs")
    family = population.family
    first, origin = start(task, family, benchmark)
    options = {"bounds": [-1.0, 1.0], "seed": CMA_SEED, "popsize": population.size, "verbose": -9,
               "maxiter": generations, "tolfun": 0.0, "tolx": 0.0, "tolflatfitness": generations}
    strategy = cma.CMAEvolutionStrategy(first.vector(), SIGMA0, options)
    seen: dict[bytes, tuple[float, Schedule]] = {}
    start_score = float(objective(index, [first])[0])
    seen[first.vector().tobytes()] = (start_score, first)
    evaluations = 1
    for _ in range(generations):
        asked = strategy.ask()
        schedules = [Schedule.from_vector(family, x) for x in asked]
        scores = objective(index, schedules)
        evaluations += len(schedules)
        for schedule, score in zip(schedules, scores):
            seen.setdefault(schedule.vector().tobytes(), (float(score), schedule))
        strategy.tell(asked, list(1.0 - scores))
    ranked = sorted((v for k, v in seen.items() if k != first.vector().tobytes() and v[0] > 0.0),
                    key=lambda v: -v[0])[:TRIED]
    searched_best = ranked[0][0] if ranked else start_score
    for score, schedule in [*ranked, (start_score, first)]:
        if score <= 0.0:
            continue
        margins = passes(task, tier, schedule, benchmark, pinocchio=False)
        if margins is not None:
            return FamilyResult(family, schedule, score, margins, origin, evaluations, searched_best)
    return FamilyResult(family, None, 0.0, None, origin, evaluations, searched_best)


def best_known(populations: dict[str, Population], task: PoolTask, tier: str, split: str, index: int,
               benchmark: Benchmark, generations: int = GENERATIONS) -> dict[str, Any]:
    """One task's record: both families' results and the best known score (confirmed on Pinocchio)."""
    started = time.perf_counter()
    results = {family: search_family(populations[family], task, tier, index, benchmark, generations)
               for family in version_families(benchmark.version)}
    best = None
    for result in sorted(results.values(), key=lambda r: -r.score):
        if result.schedule is None:
            continue
        if passes(task, tier, result.schedule, benchmark, pinocchio=True) is not None:
            best = result
            break
    # No schedule passed (a constant (m, T_c) certificate is physical, its float32 action only close to it): the
    # certificate itself, replayed by ``step_with_parameters``, is the best known.
    chosen = {"family": best.family, "score": best.score} if best is not None else {
        "family": "certificate", "score": task.certificate_score}
    return {"tier": tier, "split": split, "index": index, "task_seed": task.seed,
            "certificate_score": task.certificate_score, "best": chosen,
            "families": {family: result.as_dict() for family, result in results.items()},
            "generations": generations, "wall_time_s": time.perf_counter() - started}


def popsize(family: str) -> int:
    """cma's default population for the family's search dimension, 4 + floor(3 ln n)."""
    return 4 + int(3 * np.log(knots(family) * FAMILIES[family]))


#: One pool's populations per process, made by the first :func:`search_task` on that pool and kept for the next.
_POPULATIONS: dict[tuple[str, str, str], dict[str, Population]] = {}


def search_task(tier: str, split: str, index: int, version: str, generations: int = GENERATIONS) -> dict[str, Any]:
    """:func:`best_known` of pool task ``index`` as a piece of its own (a cluster worker runs it; picklable), with
    the populations of its pool made once per process."""
    from ffsr_gym.versions.registry import spec_for_version

    key = (tier, split, version)
    if key not in _POPULATIONS:
        for populations in _POPULATIONS.values():
            for population in populations.values():
                population.close()
        _POPULATIONS.clear()
        _POPULATIONS[key] = {family: Population(family, tier, split, popsize(family), version)
                             for family in version_families(version)}
    benchmark = spec_for_version(version).rules
    return best_known(_POPULATIONS[key], pool(tier, split, version=version)[index], tier, split, index, benchmark,
                      generations)
