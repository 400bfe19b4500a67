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
from ffsr_gym.scoring.score import FAILURES, EpisodeScore
from ffsr_gym.tasks.certificate import Certificate, replay
from ffsr_gym.tasks.generator import SCREEN_CAUSES, draw_task, screen

TIERS = ("easy", "medium", "hard")
#: Why a candidate is not in any tier.
REJECTIONS = SCREEN_CAUSES + tuple(f"unsolved_{name}" for name in FAILURES)


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
        nominal: screening measurements (final error [m], min σ_min(J_c²), min self clearance [m]).
        rollouts: episodes run to reach the verdict.
    """

    seed: int
    tier: str | None
    rejection: str | None
    certificate: Certificate | None
    certificate_score: float
    default_failure: str | None
    constant_solvable: bool
    nominal: tuple[float, float, float]
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


def classify(seed: int, benchmark: Benchmark) -> Verdict:
    """Apply the tier rule of ``benchmark`` to the candidate task of ``seed``."""
    task, rule, default = draw_task(seed, benchmark), benchmark.tasks, benchmark.planner
    nominal = screen(task, benchmark)
    measured = (nominal.final_ee_position_error_m, nominal.min_balance_sigma, nominal.min_self_clearance_m)
    runs = 1

    def attempt(certificate: Certificate) -> EpisodeScore:
        nonlocal runs
        runs += 1
        return replay(task, certificate, benchmark)

    def verdict(tier: str | None, rejection: str | None, certificate: Certificate | None, result: EpisodeScore | None,
                default_failure: str | None, constant: bool) -> Verdict:
        return Verdict(int(seed), tier, rejection, certificate, 0.0 if result is None else result.score,
                       default_failure, constant, measured, runs)

    base = Certificate("constant", default.m, default.T_c_s)
    first = attempt(base)
    solved = (base, first) if first.success else None
    grid = ((m, T_c) for m in rule.grid_m for T_c in rule.grid_T_c_s)
    while solved is None and (setting := next(grid, None)) is not None:
        certificate = Certificate("constant", *setting)
        result = attempt(certificate)
        solved = (certificate, result) if result.success else None
    if nominal.cause is not None:
        return verdict(None, nominal.cause, None, None, first.failure, solved is not None)
    if solved is not None:
        return verdict("easy" if first.success else "medium", None, *solved, first.failure, True)
    for action in residual_candidates(seed, rule.residual_trials):
        certificate = Certificate("residual", default.m, default.T_c_s, tuple(float(x) for x in action))
        result = attempt(certificate)
        if result.success:
            return verdict("hard", None, certificate, result, first.failure, False)
    return verdict(None, f"unsolved_{first.failure}", None, None, first.failure, False)
