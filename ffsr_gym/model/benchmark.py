"""The benchmark definition files (``envs/benchmark/<version>.toml``) as frozen, validated dataclasses.

A benchmark version fixes what the scenario files leave to it: the episode score, the action
boxes of the environments, the residual fade and the task tiers. v0 is the scenario's own
``[objective]`` and ``[env]`` sections (frozen); v2 is ``envs/benchmark/v2.toml`` (v1, retired,
is in the git history). Keys v2 added have defaults that leave v1's meaning unchanged, so a v1
rule file still loads as v1 meant it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from ffsr_gym.exceptions import ScenarioError
from ffsr_gym.model.scenario import Randomization, Scenario, load_scenario
from ffsr_gym.model.schema import (
    BOOL,
    MAX_DRAW_ATTEMPTS,
    TEXT,
    Vec,
    check_action_bounds,
    choice,
    count,
    integer,
    interval,
    load_table,
    natural,
    number,
    rows,
    section,
    vector,
)


@dataclass(frozen=True)
class ScoreSettings:
    """The smoothness cost, its references and the success test (see ``v2.toml``)."""

    alpha: float = field(metadata=number(0.0, 1e6))
    beta: float = field(metadata=number(0.0, 1e6))
    rate_energy_ref_rad2_s: float = field(metadata=number(0.0, 1e9, lo_open=True))
    rate_variation_ref_rad_s: float = field(metadata=number(0.0, 1e9, lo_open=True))
    max_rate_deg_s: float = field(metadata=number(0.0, 1e5, lo_open=True))
    ee_position_tolerance_m: float = field(metadata=number(0.0, 10.0, lo_open=True))
    ee_attitude_tolerance: float = field(metadata=number(0.0, 1.0, lo_open=True))
    keep_out_m: float = field(default=0.0, metadata=number(0.0, 1.0))


@dataclass(frozen=True)
class PlannerDefaults:
    """The reference planner's (m, T_c [s]) and avoidance blend law in this version."""

    m: float = field(metadata=number(0.0, 1.0, lo_open=True, hi_open=True))
    T_c_s: float = field(metadata=number(0.0, 1e4, lo_open=True))
    mu_law: str = field(default="cdf", metadata=choice("cdf", "distance"))


@dataclass(frozen=True)
class Ensemble:
    """The members a certificate must succeed in before its task enters a pool (``[tasks.ensemble]``).

    Besides the task itself: the same task at ``dt_s / d`` for each ``d`` of ``step_divisors``;
    ``start_draws`` starts whose joints are each ``start_offset_deg`` off, with signs drawn from
    ``default_rng([seed, 4 + draw])``; and, with ``pinocchio``, the task on the Pinocchio backend. With
    ``omega_offset_deg_s`` > 0, a task with a tumbling target has ``omega_draws`` more members: its body's initial
    angular velocity with each component that far off (signs from ``default_rng([seed, 8])``, then
    ``default_rng([seed, 8, draw])`` for the further draws), or, with ``omega_sign_patterns``, in each of the 8 sign
    patterns instead of drawn ones; with ``drift_offset_m_s`` > 0 [m/s], 6 more: its drift velocity that far off
    along each world axis, each way (capture v2: margins for estimate errors in every direction).
    The worst episode must clear every success threshold by a margin (:meth:`short_margin`).
    """

    step_divisors: tuple[float, ...] = field(metadata=vector(2, 1.0, 64.0))
    start_offset_deg: float = field(metadata=number(0.0, 1.0))
    start_draws: int = field(metadata=natural(16))
    pinocchio: bool = field(metadata=BOOL)
    rate_margin: float = field(default=1.0, metadata=number(0.0, 1.0, lo_open=True))
    clearance_margin_m: float = field(default=0.0, metadata=number(0.0, 1.0))
    error_margin: float = field(default=1.0, metadata=number(0.0, 1.0, lo_open=True))
    omega_offset_deg_s: float = field(default=0.0, metadata=number(0.0, 10.0))
    omega_draws: int = field(default=1, metadata=natural(16))
    omega_sign_patterns: bool = field(default=False, metadata=BOOL)
    drift_offset_m_s: float = field(default=0.0, metadata=number(0.0, 0.1))

    def short_margin(self, peak_rate_deg_s: float, min_clearance_m: float, min_self_clearance_m: float,
                     final_errors: tuple[float, float], score: ScoreSettings) -> str | None:
        """Which worst margin of a certificate is inside the hair's-breadth band (None: all clear it).

        A certificate's worst episode must keep its peak rate at most ``rate_margin`` x the limit, its
        obstacle clearance ``clearance_margin_m`` beyond the keep-out distance (its self clearance that
        far from contact) and its final errors at most ``error_margin`` x the tolerances.
        """
        if peak_rate_deg_s > self.rate_margin * score.max_rate_deg_s:
            return "rate margin"
        if min_clearance_m < score.keep_out_m + self.clearance_margin_m or min_self_clearance_m < self.clearance_margin_m:
            return "clearance margin"
        if (final_errors[0] > self.error_margin * score.ee_position_tolerance_m
                or final_errors[1] > self.error_margin * score.ee_attitude_tolerance):
            return "final error margin"
        return None


@dataclass(frozen=True)
class CaptureRule:
    """What capture means (``[capture]``, a capture rule file; ``ffsr_gym.scoring.capture``): the mission
    end-effector within these bounds of the grasp frame's pose and twist at every sample of a ``hold_s`` [s]
    window. Position [m], the angle between the frames [rad], relative linear [m/s] and angular [rad/s] speed."""

    position_m: float = field(metadata=number(0.0, 1.0, lo_open=True))
    attitude_rad: float = field(metadata=number(0.0, 3.2, lo_open=True))
    linear_velocity_m_s: float = field(metadata=number(0.0, 10.0, lo_open=True))
    angular_velocity_rad_s: float = field(metadata=number(0.0, 10.0, lo_open=True))
    hold_s: float = field(metadata=number(0.0, 60.0))
    contact_m: float = field(default=0.0, metadata=number(0.0, 1.0))


@dataclass(frozen=True)
class CaptureQuality:
    """What a capture is worth (``[quality]``, capture v1; docs/model.md §24): on capture, the score is
    ``time_weight`` (1 − t_capture / T) + ``contact_weight`` / (1 + v_contact / ``contact_speed_ref_m_s``)
    + ``smoothness_weight`` / (1 + C), with T the episode's duration, v_contact [m/s] the relative speed when the
    tool first comes within ``[capture] contact_m`` of the grasp frame and C v2's smoothness cost up to the
    capture; 0 without one. The weights sum to 1, so the score lies in [0, 1]."""

    time_weight: float = field(metadata=number(0.0, 1.0))
    contact_weight: float = field(metadata=number(0.0, 1.0))
    smoothness_weight: float = field(metadata=number(0.0, 1.0))
    contact_speed_ref_m_s: float = field(metadata=number(0.0, 10.0, lo_open=True))


@dataclass(frozen=True)
class SpinTier:
    """A capture v1 tier's body and spin (``[tasks.capture_draw.<tier>]``): the spin rate [deg/s] and the spin
    axis' angle from the grasp axis [deg], drawn uniformly; an ``axisymmetric`` body has its two edges across the
    grasp axis equal (the handle precesses regularly: a steady sweep); otherwise its principal moments differ
    pairwise by at least ``min_inertia_spread`` of the largest (torque-free nutation)."""

    spin_deg_s: Vec = field(metadata=interval(0.0, 90.0))
    spin_tilt_deg: Vec = field(metadata=interval(0.0, 180.0))
    axisymmetric: bool = field(metadata=BOOL)
    min_inertia_spread: float = field(default=0.0, metadata=number(0.0, 0.9))


@dataclass(frozen=True)
class CaptureDraw:
    """The capture family's tumbling body (``[tasks.capture_draw]``; ``ffsr_gym.tasks.capture_family``).

    Ranges are ``[low, high]``, drawn uniformly: the box's edges ``size_m`` [m] (each), its ``mass_kg`` [kg]
    (uniform density: the inertia follows), its spin rate per tier [deg/s] (``slow_spin_deg_s``,
    ``fast_spin_deg_s``), the spin axis' angle from the grasp axis ``spin_tilt_deg`` (azimuth uniform) and the
    drift speed ``drift_m_s`` [m/s] (direction uniform). The grasp frame stands ``handle_standoff_m`` off one face
    on that face's normal. The approach (``[tumbling_target]``'s keys of the same names) is fixed. A draw is kept
    when the body clears the start configuration by ``min_start_clearance_m`` and the target configuration by
    ``min_target_clearance_m``.
    """

    size_m: Vec = field(metadata=interval(0.05, 5.0))
    mass_kg: Vec = field(metadata=interval(1.0, 1e5))
    handle_standoff_m: float = field(metadata=number(0.0, 1.0, lo_open=True))
    slow_spin_deg_s: Vec = field(metadata=interval(0.0, 90.0))
    fast_spin_deg_s: Vec = field(metadata=interval(0.0, 90.0))
    spin_tilt_deg: Vec = field(metadata=interval(0.0, 180.0))
    drift_m_s: Vec = field(metadata=interval(0.0, 1.0))
    standoff_m: float = field(metadata=number(0.0, 1.0))
    insertion_time_s: float = field(metadata=number(0.5, 60.0))
    danger_radius_m: float = field(metadata=number(0.0, 1.0))
    min_start_clearance_m: float = field(metadata=number(0.0, 10.0))
    min_target_clearance_m: float = field(metadata=number(0.0, 10.0))
    max_attempts: float = field(default=500, metadata=count(1, MAX_DRAW_ATTEMPTS))
    reach_time_s: Vec = field(default=(0.0, 0.0), metadata=interval(0.0, 3600.0))
    sweep: SpinTier | None = field(default=None, metadata=section(SpinTier))
    nutation: SpinTier | None = field(default=None, metadata=section(SpinTier))

    def spin_tier(self, tier: str) -> SpinTier:
        """Capture v1's ``tier`` (``sweep`` or ``nutation``).

        Raises:
            ScenarioError: this draw has no such section.
        """
        found = getattr(self, tier, None) if tier in ("sweep", "nutation") else None
        if not isinstance(found, SpinTier):
            raise ScenarioError(f"[tasks.capture_draw] has no [tasks.capture_draw.{tier}]; allowed: a capture v1 "
                                "rule file's sweep and nutation")
        return found


@dataclass(frozen=True)
class ActionSettings:
    """Action boxes, the residual fade and the optional reward and cost terms of the environments."""

    m_bounds: tuple[float, ...] = field(metadata=vector(2, 0.0, 1.0))
    T_c_bounds_s: tuple[float, ...] = field(metadata=vector(2, 1e-3, 1000.0))
    residual_rate_deg_s: float = field(metadata=number(0.0, 1e4))
    residual_fade_s: float = field(metadata=number(0.0, 3600.0, lo_open=True))
    shaping_position_scale_m: float = field(metadata=number(0.0, 1e3, lo_open=True))
    cost_clearance_scale_m: float = field(metadata=number(0.0, 1e3, lo_open=True))


@dataclass(frozen=True)
class TaskRule:
    """The task generator, its screening margins and the tier rule (see ``v2.toml`` [tasks]).

    A candidate task is drawn from ``family`` with the ranges of ``draw``; it is rejected when the
    nominal motion (the default planner without avoidance) misses the target, brings the balance
    arm within ``min_balance_sigma`` of a dynamic singularity, or brings the arms closer than
    ``min_nominal_self_clearance_m``. The rest are tiered: easy (the default planner succeeds),
    medium (a constant (m, T_c) of the grid does), hard (none does, a residual of
    ``residual_trials`` seeded draws does), else rejected as unsolved. Capture v1 (family ``capture_timed``)
    certifies a timing: ``go_s`` lists the moments [s] at which screening commands the insertion, and a certificate
    may (``certificate_go_s``, when given, lists the certificate's instead); ``certify_grid`` false certifies the
    default (m, T_c) only. ``straight_in_fails_divisors`` (capture v2): the default planner going straight in
    (at 0 s) must capture at none of the steps dt / d, d in the list (1: the task's own step).
    """

    family: str = field(metadata=choice("random", "capture", "capture_timed"))
    min_balance_sigma: float = field(metadata=number(0.0, 100.0))
    min_nominal_self_clearance_m: float = field(metadata=number(-1.0, 1.0))
    grid_m: tuple[float, ...] = field(metadata=vector(6, 0.0, 1.0))
    grid_T_c_s: tuple[float, ...] = field(metadata=vector(6, 1e-3, 1000.0))
    residual_trials: float = field(metadata=number(0, 1e4))
    train_tasks: float = field(metadata=number(1, 1e5))
    test_tasks: float = field(metadata=number(1, 1e5))
    draw: Randomization = field(metadata=section(Randomization))
    validation_tasks: float = field(default=0, metadata=number(0, 1e5))
    ensemble: Ensemble | None = field(default=None, metadata=section(Ensemble))
    capture_draw: CaptureDraw | None = field(default=None, metadata=section(CaptureDraw))
    min_mission_sigma: float = field(default=0.0, metadata=number(0.0, 100.0))
    go_s: tuple[float, ...] = field(default=(), metadata=rows(0, 0.0, 3600.0, 64))
    certificate_go_s: tuple[float, ...] = field(default=(), metadata=rows(0, 0.0, 3600.0, 256))
    certify_grid: bool = field(default=True, metadata=BOOL)
    straight_in_fails_divisors: tuple[float, ...] = field(default=(), metadata=rows(0, 1.0, 64.0, 8))

    @property
    def splits(self) -> tuple[str, ...]:
        """The pools' splits: train, validation (when it has tasks) and test."""
        return ("train", "validation", "test") if self.validation_tasks else ("train", "test")

    def tasks_in(self, split: str) -> int:
        """How many tasks each tier's ``split`` pool holds."""
        return int({"train": self.train_tasks, "validation": self.validation_tasks, "test": self.test_tasks}[split])


@dataclass(frozen=True)
class Benchmark:
    """One benchmark version's definition."""

    schema_version: int = field(metadata=integer(1))
    version: str = field(metadata=TEXT)
    score: ScoreSettings = field(metadata=section(ScoreSettings))
    planner: PlannerDefaults = field(metadata=section(PlannerDefaults))
    action: ActionSettings = field(metadata=section(ActionSettings))
    tasks: TaskRule = field(metadata=section(TaskRule))
    capture: CaptureRule | None = field(default=None, metadata=section(CaptureRule))
    quality: CaptureQuality | None = field(default=None, metadata=section(CaptureQuality))

    def task(self, scenario: Scenario) -> Scenario:
        """``scenario`` with this version's planner defaults, tolerances, rate limit and action box.

        The v0 code paths (B, feasibility, the action mapping) then apply this version's numbers, and the
        task's hash differs from the v0 scenario's.
        """
        s, a = self.score, self.action
        objective = dataclasses.replace(scenario.objective, max_rate_deg_s=s.max_rate_deg_s, rate_limit_scope="both_arms",
                                        ee_position_tolerance_m=s.ee_position_tolerance_m,
                                        ee_attitude_tolerance=s.ee_attitude_tolerance, keep_out_m=s.keep_out_m)
        env = dataclasses.replace(scenario.env, m_bounds=a.m_bounds, T_c_bounds_s=a.T_c_bounds_s,
                                  residual_rate_deg_s=a.residual_rate_deg_s)
        planner = dataclasses.replace(scenario.planner, m=self.planner.m, T_c_s=self.planner.T_c_s,
                                      mu_law=self.planner.mu_law)
        return scenario.replace(planner=planner, objective=objective, env=env)

    @property
    def dt_s(self) -> float:
        """The benchmark's own physics step [s]: its task family's (entries must be scored at it)."""
        return load_scenario(self.tasks.family).simulation.dt_s

    def residual_fade(self, t: float, motion_time_s: float) -> float:
        """The residual's weight f(t) ∈ [0, 1] at time ``t`` [s]: 1, a half-cosine over ``residual_fade_s``, then 0."""
        fade = self.action.residual_fade_s
        start = motion_time_s - fade
        if t <= start:
            return 1.0
        if t >= motion_time_s:
            return 0.0
        return 0.5 * (1.0 + math.cos(math.pi * (t - start) / fade))


def residual_rates(action: Any, rate_deg_s: float) -> Any:
    """Joint rates [rad/s] of a (clipped) residual action: ± ``rate_deg_s`` per unit of action."""
    return np.radians(rate_deg_s) * np.asarray(action, dtype=np.float64)


def action_to_parameters(action: Any, task: Any) -> tuple[float, float]:
    """Physical (m, T_c [s]) of a (clipped) (m, T_c) action, mapped linearly onto ``task``'s box, in float64."""
    a = np.asarray(action, dtype=np.float64)
    (m_lo, m_hi), (t_lo, t_hi) = task.env.m_bounds, task.env.T_c_bounds_s
    return m_lo + 0.5 * (a[0] + 1.0) * (m_hi - m_lo), t_lo + 0.5 * (a[1] + 1.0) * (t_hi - t_lo)


@lru_cache(maxsize=16)
def load_rules(path: Path) -> Benchmark:
    """A benchmark rule file (score, planner defaults, action boxes, tier rule), validated.

    Raises:
        ScenarioError: unreadable file or an invalid key (named, with the file).
    """
    bench = load_table(Benchmark, path)
    check_action_bounds(bench.action.m_bounds, bench.action.T_c_bounds_s, section="action", where=f"{path}: ")
    quality = bench.quality
    if quality is not None:
        total = quality.time_weight + quality.contact_weight + quality.smoothness_weight
        if abs(total - 1.0) > 1e-9:
            raise ScenarioError(f"{path}: keys 'quality.time_weight', 'quality.contact_weight' and "
                                f"'quality.smoothness_weight' sum to {total!r}; allowed: 1")
        if bench.capture is None or bench.capture.contact_m <= 0.0:
            raise ScenarioError(f"{path}: section 'quality' needs 'capture.contact_m' > 0 (where contact is read)")
    return bench
