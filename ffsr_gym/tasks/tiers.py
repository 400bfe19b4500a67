"""The tier rule of benchmark v1: which tier a candidate task belongs to, and its certificate.

For a candidate that passes screening (:mod:`ffsr_gym.tasks.generator`):

* ``easy``: the v1 default planner (m, T_c) succeeds (certificate: that setting);
* ``medium``: it fails, and a constant (m, T_c) of the ``[tasks]`` grid succeeds (the first in
  grid order, m outer);
* ``hard``: no grid setting succeeds, and one of ``residual_trials`` constant residual actions
  drawn uniformly in [-1, 1]^12 (float32) from ``default_rng(seed)`` does (the first that does);
* otherwise the candidate is rejected as ``unsolved_<failure of the default planner>``.

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
from ffsr_gym.tasks.certificate import Certificate, replay
from ffsr_gym.tasks.generator import SCREEN_CAUSES, draw_task, screen
from ffsr_gym.tasks.perturbation import PERTURBED_TIERS, PerturbedRule, perturbed_task

TIERS = ("easy", "medium", "hard")
#: Why a candidate is not in any tier.
REJECTIONS = SCREEN_CAUSES + tuple(f"unsolved_{name}" for name in FAILURES)
#: Why a candidate is not in a perturbed tier: its v1 task is in no tier, no admissible debris draw, or unsolved.
PERTURBED_REJECTIONS = ("base_rejected", "draw_failed") + tuple(f"unsolved_{name}" for name in FAILURES)
#: Every tier of benchmark v1: the three of v1.toml, then the perturbed ones (v1_perturbed.toml).
ALL_TIERS = TIERS + PERTURBED_TIERS


@dataclass(frozen=True)
class Verdict:
    """The tier rule applied to one candidate seed.

    Attributes:
        seed: the candidate's seed.
        tier: one of :data:`TIERS`, or None (rejected).
        rejection: one of :data:`REJECTIONS`, or None (admitted).
        certificate: the proof of solvability (None when rejected).
        certificate_score: the v1 score of the certificate's episode (0 when rejected).
        default_failure: failure of the default planner (None: it succeeded).
        constant_solvable: a setting of the grid (or the default) succeeds.
        nominal: screening measurements (final error [m], min σ_min(J_c²), min self clearance [m]);
            empty for a perturbed-tier candidate (its v1 task was screened).
        rollouts: episodes run to reach the verdict.
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

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {"seed": self.seed, "tier": self.tier, "rejection": self.rejection,
                "certificate": None if self.certificate is None else self.certificate.as_dict(),
                "certificate_score": self.certificate_score, "default_failure": self.default_failure,
                "constant_solvable": self.constant_solvable, "nominal": list(self.nominal), "rollouts": self.rollouts}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Verdict:
        """Inverse of :meth:`as_dict`."""
        cert = data["certificate"]
        return cls(seed=int(data["seed"]), tier=data["tier"], rejection=data["rejection"],
                   certificate=None if cert is None else Certificate.from_dict(cert),
                   certificate_score=float(data["certificate_score"]), default_failure=data["default_failure"],
                   constant_solvable=bool(data["constant_solvable"]), nominal=tuple(data["nominal"]),
                   rollouts=int(data["rollouts"]))


def residual_candidates(seed: int, trials: int) -> np.ndarray:
    """The ``trials`` residual actions tried on candidate ``seed`` ((trials, 12), float32-exact float64)."""
    rng = np.random.default_rng([int(seed), 1])
    return rng.uniform(-1.0, 1.0, (int(trials), 12)).astype(np.float32).astype(np.float64)


@dataclass(frozen=True)
class Certification:
    """The certificate search of the tier rule on one task.

    Attributes:
        certificate: the first certificate that succeeds (default, grid, residual), or None.
        result: its episode (None without a certificate).
        default_failure: failure of the default planner (None: it succeeded).
        constant_solvable: the default or a grid setting succeeds.
        rollouts: episodes run.
    """

    certificate: Certificate | None
    result: EpisodeScore | None
    default_failure: str | None
    constant_solvable: bool
    rollouts: int


def certify(task: Scenario, seed: int, benchmark: Benchmark, *, residuals: bool = True) -> Certification:
    """Search ``task`` for a certificate in the tier rule's order: the default planner, the grid
    (m outer), then (when ``residuals``) the residual trials of ``seed``."""
    rule, default = benchmark.tasks, benchmark.planner
    runs = 0

    def attempt(certificate: Certificate) -> tuple[Certificate, EpisodeScore]:
        nonlocal runs
        runs += 1
        return certificate, replay(task, certificate, benchmark)

    first = attempt(Certificate("constant", default.m, default.T_c_s))
    solved = first if first[1].success else None
    grid = ((m, T_c) for m in rule.grid_m for T_c in rule.grid_T_c_s)
    while solved is None and (setting := next(grid, None)) is not None:
        tried = attempt(Certificate("constant", *setting))
        solved = tried if tried[1].success else None
    constant = solved is not None
    if solved is None and residuals:
        for action in residual_candidates(seed, rule.residual_trials):
            tried = attempt(Certificate("residual", default.m, default.T_c_s, tuple(float(x) for x in action)))
            if tried[1].success:
                solved = tried
                break
    certificate, result = solved if solved is not None else (None, None)
    return Certification(certificate, result, first[1].failure, constant, runs)


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
    if found.certificate is None:
        return Verdict(int(seed), None, f"unsolved_{found.default_failure}", None, 0.0, found.default_failure, False,
                       measured, runs)
    tier = "hard" if found.certificate.kind == "residual" else "easy" if found.default_failure is None else "medium"
    return Verdict(int(seed), tier, None, found.certificate, found.result.score, found.default_failure,
                   found.constant_solvable, measured, runs)


def classify_perturbed(tier: str, seed: int, benchmark: Benchmark, *, base_admitted: bool,
                       rule: PerturbedRule | None = None) -> Verdict:
    """Apply the perturbed-tier rule (``v1_perturbed.toml``) to the ``tier`` candidate of ``seed``.

    ``base_admitted``: the v1 task of ``seed`` is in a v1 tier (from the v1 pool file's labels);
    otherwise the candidate is rejected as ``base_rejected`` without a rollout.
    """
    if not base_admitted:
        return Verdict(int(seed), None, "base_rejected", None, 0.0, None, False, (), 0)
    task = perturbed_task(tier, seed, benchmark, rule)
    if task is None:
        return Verdict(int(seed), None, "draw_failed", None, 0.0, None, False, (), 0)
    found = certify(task, seed, benchmark)
    if found.certificate is None:
        return Verdict(int(seed), None, f"unsolved_{found.default_failure}", None, 0.0, found.default_failure, False,
                       (), found.rollouts)
    return Verdict(int(seed), tier, None, found.certificate, found.result.score, found.default_failure,
                   found.constant_solvable, (), found.rollouts)
