"""The tier rule: which tier a candidate task belongs to, and its certificate.

For a candidate that passes screening (:mod:`ffsr_gym.tasks.generator`):

* ``easy``: the version's default planner (m, T_c) succeeds (certificate: that setting);
* ``medium``: it fails, and a constant (m, T_c) of the ``[tasks]`` grid succeeds (the first in
  grid order, m outer);
* ``hard``: no grid setting succeeds, and one of ``residual_trials`` constant residual actions
  drawn uniformly in [-1, 1]^12 (float32) from ``default_rng([seed, 1])`` does (the first that does);
* otherwise the candidate is rejected as ``unsolved_<failure of the default planner>``.

With an ensemble (``[tasks.ensemble]``, v2), "succeeds" means: at the task's step and in every
kernel member of :func:`~ffsr_gym.tasks.certificate.ensemble_members` (the Pinocchio member is
replayed by the build on the pool tasks only, :mod:`ffsr_gym_lab.pools.build`), with the worst
episode clearing every threshold by the ensemble's margins. A setting that succeeds at the
task's step but fails in a member, or by a hair, is no certificate, and the search goes on. The
default planner's verdict must not depend on the step or a hair: when it succeeds at the task's
step but fails in a member or inside a margin, or fails at the task's step but succeeds at the
smallest step of the ensemble, the candidate is rejected as ``fragile``.

Screened-out candidates are rejected with the screening cause. For them the grid is run as well,
so that the build can report how many a constant setting would have solved (the price of the
margins).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ffsr_gym.model.benchmark import Benchmark
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.scoring.score import FAILURES, EpisodeScore
from ffsr_gym.tasks.certificate import Certificate, Margins, ensemble_members, replay, replay_members
from ffsr_gym.tasks.generator import SCREEN_CAUSES, draw_task, screen
from ffsr_gym.tasks.perturbation import PERTURBED_TIERS, PerturbedRule, perturbed_task

TIERS = ("easy", "medium", "hard")
#: Why a candidate is not in any tier.
REJECTIONS = SCREEN_CAUSES + tuple(f"unsolved_{name}" for name in FAILURES) + ("fragile",)
#: Why a candidate is not in a perturbed tier: its base task is in no tier, no admissible debris draw,
#: unsolved, or the default planner's verdict depends on the step.
PERTURBED_REJECTIONS = ("base_rejected", "draw_failed") + tuple(f"unsolved_{name}" for name in FAILURES) + ("fragile",)
#: Every tier: the three of the rule file, then the perturbed ones (``<version>_perturbed.toml``).
ALL_TIERS = TIERS + PERTURBED_TIERS


@dataclass(frozen=True)
class Verdict:
    """The tier rule applied to one candidate seed.

    Attributes:
        seed: the candidate's seed.
        tier: one of :data:`TIERS`, or None (rejected).
        rejection: one of :data:`REJECTIONS`, or None (admitted).
        certificate: the proof of solvability (None when rejected).
        certificate_score: the score of the certificate's episode (0 when rejected).
        default_failure: failure of the default planner (None: it succeeded).
        constant_solvable: a setting of the grid (or the default) succeeds.
        nominal: screening measurements (final error [m], min σ_min(J_c²), min self clearance [m]);
            empty for a perturbed-tier candidate (its base task was screened).
        rollouts: episodes run to reach the verdict.
        margins: the certificate's worst margins over the episodes it was replayed in (None when
            rejected; without an ensemble: the certificate's episode only).
    """

    seed: int
    tier: str | None
    rejection: str | None
    certificate: Certificate | None
    certificate_score: float
    default_failure: str | None
    constant_solvable: bool
    nominal: tuple[float, ...]
    rollouts: int
    margins: Margins | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {"seed": self.seed, "tier": self.tier, "rejection": self.rejection,
                "certificate": None if self.certificate is None else self.certificate.as_dict(),
                "certificate_score": self.certificate_score, "default_failure": self.default_failure,
                "constant_solvable": self.constant_solvable, "nominal": list(self.nominal), "rollouts": self.rollouts,
                "margins": None if self.margins is None else self.margins.as_dict()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Verdict:
        """Inverse of :meth:`as_dict`."""
        cert = data["certificate"]
        return cls(seed=int(data["seed"]), tier=data["tier"], rejection=data["rejection"],
                   certificate=None if cert is None else Certificate.from_dict(cert),
                   certificate_score=float(data["certificate_score"]), default_failure=data["default_failure"],
                   constant_solvable=bool(data["constant_solvable"]), nominal=tuple(data["nominal"]),
                   rollouts=int(data["rollouts"]),
                   margins=None if data.get("margins") is None else Margins.from_dict(data["margins"]))


def residual_candidates(seed: int, trials: int) -> np.ndarray:
    """The ``trials`` residual actions tried on candidate ``seed`` ((trials, 12), float32-exact float64)."""
    rng = np.random.default_rng([int(seed), 1])
    return rng.uniform(-1.0, 1.0, (int(trials), 12)).astype(np.float32).astype(np.float64)


@dataclass(frozen=True)
class Certification:
    """The certificate search of the tier rule on one task.

    Attributes:
        certificate: the first certificate that succeeds (default, grid, residual), or None.
        result: its episode at the task's step (None without a certificate).
        default_failure: failure of the default planner at the task's step (None: it succeeded).
        constant_solvable: the default or a grid setting succeeds.
        rollouts: episodes run.
        margins: the certificate's worst margins over its episodes (None without a certificate).
        fragile: the ensemble member whose verdict on the default planner differs from the task's
            step (None: the verdict holds; always None without an ensemble).
    """

    certificate: Certificate | None
    result: EpisodeScore | None
    default_failure: str | None
    constant_solvable: bool
    rollouts: int
    margins: Margins | None = None
    fragile: str | None = None


def certify(task: Scenario, seed: int, benchmark: Benchmark, *, residuals: bool = True) -> Certification:
    """Search ``task`` for a certificate in the tier rule's order: the default planner, the grid
    (m outer), then (when ``residuals``) the residual trials of ``seed``; with the rule's ensemble,
    each must also succeed in its kernel members."""
    rule, default = benchmark.tasks, benchmark.planner
    members = [] if rule.ensemble is None else ensemble_members(task, seed, rule.ensemble, pinocchio=False)
    runs = 0

    def attempt(certificate: Certificate) -> tuple[EpisodeScore, str | None, Margins | None]:
        """The episode at the task's step; the first member that fails (None: all succeed) and the margins."""
        nonlocal runs
        first = replay(task, certificate, benchmark)
        runs += 1
        if not first.success:
            return first, None, None
        failed, results = replay_members(members, certificate, benchmark)
        runs += len(results)
        margins = Margins.worst([first, *results])
        return first, failed or margins.short(benchmark), margins

    planner = Certificate("constant", default.m, default.T_c_s)
    first, failed, margins = attempt(planner)
    if failed is None and first.success:
        return Certification(planner, first, None, True, runs, margins)
    if failed is not None:
        return Certification(None, None, None, True, runs, fragile=failed)
    if rule.ensemble is not None:
        finest = members[len(rule.ensemble.step_divisors) - 1]
        runs += 1
        if replay(finest.task, planner, benchmark).success:
            return Certification(None, None, first.failure, True, runs, fragile=finest.name)
    solved = None
    grid = ((m, T_c) for m in rule.grid_m for T_c in rule.grid_T_c_s)
    while solved is None and (setting := next(grid, None)) is not None:
        certificate = Certificate("constant", *setting)
        result, failed, margins = attempt(certificate)
        solved = (certificate, result, margins) if result.success and failed is None else None
    constant = solved is not None
    if solved is None and residuals:
        for action in residual_candidates(seed, rule.residual_trials):
            certificate = Certificate("residual", default.m, default.T_c_s, tuple(float(x) for x in action))
            result, failed, margins = attempt(certificate)
            if result.success and failed is None:
                solved = (certificate, result, margins)
                break
    certificate, result, margins = solved if solved is not None else (None, None, None)
    return Certification(certificate, result, first.failure, constant, runs, margins)


def classify(seed: int, benchmark: Benchmark) -> Verdict:
    """Apply the tier rule of ``benchmark`` to the candidate task of ``seed``."""
    task = draw_task(seed, benchmark)
    nominal = screen(task, benchmark)
    measured = (nominal.final_ee_position_error_m, nominal.min_balance_sigma, nominal.min_self_clearance_m)
    found = certify(task, seed, benchmark, residuals=nominal.cause is None)
    runs = found.rollouts + 1
    if nominal.cause is not None:
        return Verdict(int(seed), None, nominal.cause, None, 0.0, found.default_failure, found.constant_solvable,
                       measured, runs)
    if found.fragile is not None:
        return Verdict(int(seed), None, "fragile", None, 0.0, found.default_failure, True, measured, runs)
    if found.certificate is None:
        return Verdict(int(seed), None, f"unsolved_{found.default_failure}", None, 0.0, found.default_failure, False,
                       measured, runs)
    tier = "hard" if found.certificate.kind == "residual" else "easy" if found.default_failure is None else "medium"
    return Verdict(int(seed), tier, None, found.certificate, found.result.score, found.default_failure,
                   found.constant_solvable, measured, runs, found.margins)


def classify_perturbed(tier: str, seed: int, benchmark: Benchmark, *, base_admitted: bool,
                       rule: PerturbedRule | None = None) -> Verdict:
    """Apply the perturbed-tier rule (``<version>_perturbed.toml``) to the ``tier`` candidate of ``seed``.

    ``base_admitted``: the base task of ``seed`` is in a tier (from the version's pool file labels);
    otherwise the candidate is rejected as ``base_rejected`` without a rollout.
    """
    if not base_admitted:
        return Verdict(int(seed), None, "base_rejected", None, 0.0, None, False, (), 0)
    task = perturbed_task(tier, seed, benchmark, rule)
    if task is None:
        return Verdict(int(seed), None, "draw_failed", None, 0.0, None, False, (), 0)
    found = certify(task, seed, benchmark)
    if found.fragile is not None:
        return Verdict(int(seed), None, "fragile", None, 0.0, found.default_failure, True, (), found.rollouts)
    if found.certificate is None:
        return Verdict(int(seed), None, f"unsolved_{found.default_failure}", None, 0.0, found.default_failure, False,
                       (), found.rollouts)
    return Verdict(int(seed), tier, None, found.certificate, found.result.score, found.default_failure,
                   found.constant_solvable, (), found.rollouts, found.margins)
