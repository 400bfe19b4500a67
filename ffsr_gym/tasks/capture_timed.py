"""Capture v1's tasks (docs/model.md §24): a handle that sweeps, drawn per seed and tier, screened and certified on
timings.

A candidate of tier ``sweep`` or ``nutation`` and seed s is capture-v0's draw
(:func:`~ffsr_gym.tasks.capture_family.sample_capture`) with the tier's body and spin
(``[tasks.capture_draw.<tier>]``), from ``numpy.random.default_rng([s, 10, tier index])``, and with the grasp frame
at its well-reachable pose at a moment uniform in ``reach_time_s`` (from ``default_rng([s, 11, tier index])``):

* ``sweep``: a body symmetric about the grasp axis (its two edges across it equal), so the handle precesses
  regularly round a cone about the angular momentum;
* ``nutation``: a body whose principal moments lie at least ``min_inertia_spread`` of the largest apart, so the
  torque-free motion nutates and the handle's path does not repeat.

Screening plays the default planner at every moment of the rule's ``go_s`` (:func:`timing_outcomes`: hold the
start pose, then command the insertion): a candidate is admitted when one of them captures with both arms clear of
their singularity margins up to the capture. Certification (:func:`certify_timed`) then finds the first timed
certificate, the default (m, T_c) then the grid's, each at every moment of ``go_s``, that captures in every kernel
member of the ensemble with the ensemble's margins (the Pinocchio member is replayed by the pool build).

Capture v2's rule (the same family and draws) screens for tasks where the method must time: the default planner
going straight in must capture at none of the steps of ``straight_in_fails_divisors`` (cause
``straight_in_captures``): at the task's own step first, which is also the screening's moment 0 s, and at the finer
steps, four times costlier, only for the candidates the timings admit (:func:`straight_in_capture`). It certifies
the default (m, T_c) only (``certify_grid`` false) at the finer moments of ``certificate_go_s``, in an ensemble that
moves the body's spin in every sign pattern and its drift along every axis
(:func:`~ffsr_gym.tasks.certificate.target_members`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.model.benchmark import Benchmark, SpinTier
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.scoring.score import score_episode
from ffsr_gym.tasks.capture_family import BodyDraw, box_inertia, capture_family, sample_capture, tilted_spin
from ffsr_gym.tasks.certificate import Certificate, Margins, Member, ensemble_members, replay_with_margins, timed_run
from ffsr_gym.tasks.generator import MAX_SEED
from ffsr_gym.tasks.tiers import Verdict

#: Capture v1's tiers: the index is part of each candidate's generator seeds.
TIMED_TIERS = ("sweep", "nutation")
#: Screening causes of a capture v1 candidate, in the order they are checked.
TIMED_SCREEN_CAUSES = ("draw_failed", "straight_in_captures", "no_timing_captures", "mission_singularity",
                       "balance_singularity")
#: Why a capture v1 candidate is not in its tier.
TIMED_REJECTIONS = TIMED_SCREEN_CAUSES + ("unsolved",)
#: The measurements a verdict's ``nominal`` holds, in this order (None: no capture).
NOMINAL_KEYS = ("earliest_capture_s", "straight_in_capture_s", "timings_captured", "min_mission_sigma",
                "min_balance_sigma")
#: Edge draws an asymmetric body may take to meet its tier's inertia spread before the draw is rejected.
SPREAD_ATTEMPTS = 20


def inertia_spread(moments: tuple[float, float, float]) -> float:
    """The smallest difference between two principal moments, as a fraction of the largest."""
    a, b, c = sorted(moments)
    return min(b - a, c - b) / c


def timed_body(tier: SpinTier, size_m: tuple[float, float], mass_kg: tuple[float, float]) -> BodyDraw:
    """The body draw of a capture v1 tier (module docstring): edges, mass, then spin from the rng."""
    def draw(rng: np.random.Generator) -> tuple:
        size = None
        for _ in range(SPREAD_ATTEMPTS):
            edges = rng.uniform(*size_m, 2 if tier.axisymmetric else 3)
            size = np.array([edges[0], edges[0], edges[1]]) if tier.axisymmetric else edges
            if tier.axisymmetric or inertia_spread(box_inertia(1.0, size)) >= tier.min_inertia_spread:
                break
            size = None
        return size, rng.uniform(*mass_kg), tilted_spin(tier.spin_deg_s, tier.spin_tilt_deg, rng)
    return draw


def draw_timed_task(tier: str, seed: int, benchmark: Benchmark) -> Scenario | None:
    """The ``tier`` candidate of ``seed`` (named ``<version>-<tier>-<seed>``), or None when no draw is admissible.

    Raises:
        InvalidInputError: an unknown tier, a seed that is not an integer in [0, 2**63), or a rule file whose
            family is not ``capture_timed``.
    """
    if tier not in TIMED_TIERS:
        raise InvalidInputError(f"capture v1 tier {tier!r}; allowed: {list(TIMED_TIERS)}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) <= MAX_SEED:
        raise InvalidInputError(f"task seed must be an integer in [0, 2**63), got {seed!r}")
    if benchmark.tasks.family != "capture_timed":
        raise InvalidInputError(f"benchmark {benchmark.version!r} draws from {benchmark.tasks.family!r}; allowed: a "
                                "capture v1 rule file (envs/benchmark/capture-v1.toml)")
    return _draw_timed_task(tier, int(seed), benchmark)


@lru_cache(maxsize=4096)
def _draw_timed_task(tier: str, seed: int, benchmark: Benchmark) -> Scenario | None:
    """:func:`draw_timed_task` after the checks (cached: the environments draw pool tasks again and again)."""
    rule, index = benchmark.tasks, TIMED_TIERS.index(tier)
    draw = rule.capture_draw
    spin = draw.spin_tier(tier)
    reach = float(np.random.default_rng([seed, 11, index]).uniform(*draw.reach_time_s))
    try:
        drawn = sample_capture(capture_family(benchmark), rule.draw, draw, tier,
                               np.random.default_rng([seed, 10, index]), reach_time_s=reach,
                               body=timed_body(spin, draw.size_m, draw.mass_kg))
    except ScenarioError:  # no admissible draw
        return None
    version = benchmark.version
    return drawn.replace(name=f"{version}-{tier}-{seed}",
                         description=f"{version} {tier} capture candidate of seed {seed}, grasp frame reachable at "
                                     f"{reach:.2f} s (ffsr_gym.tasks.capture_timed).")


@dataclass(frozen=True)
class TimingOutcome:
    """The default planner going in at ``go_s`` [s]: when it captured (None: it did not), its failure, and the
    smallest σ_min of each arm's matrix up to the capture (over the whole run without one)."""

    go_s: float
    capture_time_s: float | None
    failure: str | None
    min_mission_sigma: float
    min_balance_sigma: float


def timing_outcome(task: Scenario, benchmark: Benchmark, m: float, T_c: float, go_s: float) -> TimingOutcome:
    """The planner at (m, T_c [s]) going in at ``go_s`` [s]."""
    run = timed_run(task, m, T_c, go_s)
    result = score_episode(run, task, benchmark)
    rows = len(run.t) if result.capture_time_s is None else int(round(result.capture_time_s / run.dt)) + 1
    sigma = run.sigma_min[:rows]
    return TimingOutcome(float(go_s), result.capture_time_s, result.failure, float(np.min(sigma[:, 0])),
                         float(np.min(sigma[:, 1])))


def timing_outcomes(task: Scenario, benchmark: Benchmark, m: float | None = None, T_c: float | None = None, *,
                    known: dict[float, TimingOutcome] | None = None) -> list[TimingOutcome]:
    """The planner at (m, T_c [s]) (default: the rule's) going in at every moment of the rule's ``go_s``; ``known``:
    outcomes of that planner already run, by moment (kept, not run again)."""
    m = benchmark.planner.m if m is None else m
    T_c = benchmark.planner.T_c_s if T_c is None else T_c
    known = known or {}
    return [known[go] if go in known else timing_outcome(task, benchmark, m, T_c, go) for go in benchmark.tasks.go_s]


def screen_timed(outcomes: list[TimingOutcome], benchmark: Benchmark) -> tuple[str | None, tuple]:
    """The screening cause of a candidate from its :func:`timing_outcomes` (None: admitted) and its
    measurements (:data:`NOMINAL_KEYS`)."""
    rule = benchmark.tasks
    captured = [o for o in outcomes if o.capture_time_s is not None]
    mission = [o for o in captured if o.min_mission_sigma >= rule.min_mission_sigma]
    kept = [o for o in mission if o.min_balance_sigma >= rule.min_balance_sigma]
    cause = ("no_timing_captures" if not captured else "mission_singularity" if not mission
             else "balance_singularity" if not kept else None)
    best = min(kept or captured or outcomes, key=lambda o: math.inf if o.capture_time_s is None else o.capture_time_s)
    straight = outcomes[0].capture_time_s if outcomes and outcomes[0].go_s == 0.0 else None
    return cause, (best.capture_time_s, straight, len(captured), best.min_mission_sigma, best.min_balance_sigma)


@dataclass(frozen=True)
class TimedCertification:
    """A timed certificate search: the certificate, its episode's score and margins (None: none found), runs."""

    certificate: Certificate | None
    score: float
    margins: Margins | None
    rollouts: int


def certify_timed(task: Scenario, seed: int, benchmark: Benchmark,
                  outcomes: list[TimingOutcome] | None = None) -> TimedCertification:
    """The first timed certificate (module docstring) that captures in every kernel member with the ensemble's
    margins. ``outcomes``: the default planner's :func:`timing_outcomes`, whose failed moments are not tried again."""
    rule, default = benchmark.tasks, benchmark.planner
    members = [] if rule.ensemble is None else ensemble_members(task, seed, rule.ensemble, pinocchio=False)
    members.sort(key=lambda member: not member.name.startswith(("omega", "drift")))  # likeliest to fail first
    failed = {o.go_s for o in outcomes or () if o.capture_time_s is None}
    runs = 0
    settings = [(default.m, default.T_c_s)]
    settings += [(m, T_c) for m in rule.grid_m for T_c in rule.grid_T_c_s] if rule.certify_grid else []
    for index, (m, T_c) in enumerate(settings):
        for go in rule.certificate_go_s or rule.go_s:
            if index == 0 and go in failed:
                continue
            found = try_timed(task, Certificate("timed", float(m), float(T_c), go_s=float(go)), members, benchmark)
            runs += found.rollouts
            if found.certificate is not None:
                return dataclasses.replace(found, rollouts=runs)
    return TimedCertification(None, 0.0, None, runs)


def try_timed(task: Scenario, certificate: Certificate, members: list[Member],
              benchmark: Benchmark) -> TimedCertification:
    """One timed setting tried as a certificate: it is one (``certificate`` not None) when it captures in ``task``
    and in every member with the ensemble's margins; the members are replayed in order until one fails."""
    result, margins = replay_with_margins(task, certificate, benchmark)
    runs = 1
    if not result.success:
        return TimedCertification(None, 0.0, None, runs)
    for member in members:
        other, more = replay_with_margins(member.task, certificate, benchmark, backend=member.backend)
        runs += 1
        margins = margins.merge(more)
        if not other.success:
            return TimedCertification(None, 0.0, None, runs)
    if margins.short(benchmark) is not None:
        return TimedCertification(None, 0.0, None, runs)
    return TimedCertification(certificate, result.score, margins, runs)


def straight_in_capture(task: Scenario, benchmark: Benchmark, divisors: Sequence[float] | None = None) -> int | None:
    """Whether the default planner going straight in (at 0 s) captures at one of the steps dt / d, d in ``divisors``
    (default: the rule's ``straight_in_fails_divisors``): the runs it took to find one (None: it captures at none, or
    there is no step to try). In order of the divisor: the task's own step first, the cheapest."""
    planner, dt = benchmark.planner, task.simulation.dt_s
    divisors = benchmark.tasks.straight_in_fails_divisors if divisors is None else divisors
    for runs, divisor in enumerate(sorted(divisors), start=1):
        played = task if divisor == 1 else task.at_step(dt / divisor)
        run = timed_run(played, planner.m, planner.T_c_s, 0.0)
        if score_episode(run, played, benchmark).capture_time_s is not None:
            return runs
    return None


def classify_timed(tier: str, seed: int, benchmark: Benchmark) -> Verdict:
    """Capture v1's tier rule on the ``tier`` candidate of ``seed``: rejected when no draw is admissible, screening
    fails (:data:`TIMED_SCREEN_CAUSES`) or no timed certificate is found (``unsolved``); else admitted with the
    first certificate. ``nominal``: :data:`NOMINAL_KEYS`; ``default_failure``: the default planner's failure going
    straight in (None: it captured)."""
    task = draw_timed_task(tier, seed, benchmark)
    if task is None:
        return Verdict(int(seed), None, "draw_failed", None, 0.0, None, False, (), 0)
    planner, finer = benchmark.planner, sorted(benchmark.tasks.straight_in_fails_divisors)
    known: dict[float, TimingOutcome] = {}
    if 1.0 in finer:  # going straight in at the task's own step: one run, and the screening's moment 0 s
        finer.remove(1.0)
        known[0.0] = timing_outcome(task, benchmark, planner.m, planner.T_c_s, 0.0)
        if known[0.0].capture_time_s is not None:
            return Verdict(int(seed), None, "straight_in_captures", None, 0.0, None, False, (), 1)
    outcomes = timing_outcomes(task, benchmark, known=known)
    cause, nominal = screen_timed(outcomes, benchmark)
    straight = outcomes[0].failure if outcomes else None
    checked = len(known) + sum(o.go_s not in known for o in outcomes)
    if cause is not None:
        return Verdict(int(seed), None, cause, None, 0.0, straight, False, nominal, checked)
    finer_capture = straight_in_capture(task, benchmark, finer)  # the finer steps: costlier, for the screened-in only
    if finer_capture is not None:
        return Verdict(int(seed), None, "straight_in_captures", None, 0.0, straight, False, nominal,
                       checked + finer_capture)
    found = certify_timed(task, seed, benchmark, outcomes)
    runs = checked + len(finer) + found.rollouts
    if found.certificate is None:
        return Verdict(int(seed), None, "unsolved", None, 0.0, straight, False, nominal, runs)
    constant = found.certificate.m == benchmark.planner.m and found.certificate.T_c_s == benchmark.planner.T_c_s
    return Verdict(int(seed), tier, None, found.certificate, found.score, straight, constant, nominal, runs,
                   found.margins)

