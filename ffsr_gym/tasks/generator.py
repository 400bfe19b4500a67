"""Candidate tasks of a benchmark version: one per seed, drawn from the task family, then screened.

A candidate is a deterministic function of its seed: the family scenario (the version's settings
applied) with the target pose and the obstacle drawn by
:func:`ffsr_gym.tasks.random_family.sample_scenario` from ``numpy.random.default_rng(seed)`` and
the ranges of ``[tasks.draw]`` in ``<version>.toml``.

Screening looks at the *nominal motion*: the version's default planner with avoidance switched off
(method ``no_avoidance``), run for the whole episode. A candidate is rejected when

* ``nominal_final_error``: its final end-effector error misses the tolerance (the straight path
  crosses a mission-arm singularity, so no planner setting tracks it);
* ``balance_singularity``: σ_min of the balance arm's coupling matrix J_c² falls below
  ``min_balance_sigma`` (the balance arm's rates grow like 1/σ_min, and the rate limit breaks
  whatever (m, T_c) is);
* ``self_collision``: arm-arm or arm-base clearance falls below ``min_nominal_self_clearance_m``
  (the avoidance acts on the obstacle only).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.benchmark import Benchmark
from ffsr_gym.model.scenario import Scenario, load_scenario
from ffsr_gym.scoring.score import EpisodeScore, score_episode
from ffsr_gym.sim.simulate import make_rollout
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.tasks.random_family import sample_scenario

#: Screening causes, in the order they are checked.
SCREEN_CAUSES = ("nominal_final_error", "balance_singularity", "self_collision")
MAX_SEED = 2**63 - 1


@lru_cache(maxsize=4)
def task_family(benchmark: Benchmark) -> Scenario:
    """The family scenario of the version's tasks: its settings and the ``[tasks.draw]`` ranges (cached; frozen)."""
    rule = benchmark.tasks
    return benchmark.task(load_scenario(rule.family)).replace(randomization=rule.draw)


def draw_task(seed: int, benchmark: Benchmark) -> Scenario:
    """The candidate task of ``seed`` (named ``<version>-<seed>``, no randomization section).

    Raises:
        InvalidInputError: ``seed`` is not an integer in [0, 2**63).
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) <= MAX_SEED:
        raise InvalidInputError(f"task seed must be an integer in [0, 2**63), got {seed!r}")
    return _draw_task(int(seed), benchmark)


@lru_cache(maxsize=4096)
def _draw_task(seed: int, benchmark: Benchmark) -> Scenario:
    """:func:`draw_task` after the check (cached: the environments draw pool tasks again and again)."""
    family = task_family(benchmark)
    drawn = sample_scenario(family, np.random.default_rng(int(seed)))
    version = benchmark.version
    return drawn.replace(name=f"{version}-{int(seed)}", randomization=None,
                         description=f"Benchmark {version} candidate task of seed {int(seed)} (ffsr_gym.tasks.generator).")


@dataclass(frozen=True)
class NominalMotion:
    """What screening measured on the nominal motion of one candidate.

    Attributes:
        final_ee_position_error_m: at the end of the episode.
        min_balance_sigma: smallest σ_min(J_c²) over the episode.
        min_self_clearance_m: smallest arm-arm / arm-base clearance [m].
        cause: the first failed check of :data:`SCREEN_CAUSES`, or None (admitted).
    """

    final_ee_position_error_m: float
    min_balance_sigma: float
    min_self_clearance_m: float
    cause: str | None


def nominal_motion(task: Scenario, benchmark: Benchmark) -> tuple[Trajectory, EpisodeScore]:
    """The nominal motion of ``task``: the version's default planner with avoidance switched off, run for the whole
    episode, and its score."""
    rollout = make_rollout(task, method="no_avoidance", m=benchmark.planner.m, T_c=benchmark.planner.T_c_s)
    rollout.advance(task.n_steps)
    rollout.finish()
    traj = rollout.trajectory()
    return traj, score_episode(traj, task, benchmark)


def screen(task: Scenario, benchmark: Benchmark) -> NominalMotion:
    """Run the nominal motion of ``task`` and apply the screening margins of ``benchmark``."""
    rule = benchmark.tasks
    traj, result = nominal_motion(task, benchmark)
    sigma = float(np.min(traj.sigma_min[:, 1]))
    checks = (result.final_ee_position_error_m > benchmark.score.ee_position_tolerance_m
              or result.final_ee_attitude_error > benchmark.score.ee_attitude_tolerance,
              sigma < rule.min_balance_sigma,
              result.min_self_clearance_m < rule.min_nominal_self_clearance_m)
    cause = next((name for name, failed in zip(SCREEN_CAUSES, checks) if failed), None)
    return NominalMotion(result.final_ee_position_error_m, sigma, result.min_self_clearance_m, cause)
