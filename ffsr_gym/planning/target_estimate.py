"""The planner's estimates of the target pose under ``[target_noise]`` (docs/model.md §16).

Without the section the planner sees the true target: one estimate, the true desired path.
With it, estimate k holds for t in [k, k + 1) · interval and is drawn once per task, so both
backends and the batched environment read the same numbers:

    p̂_k = p_t + b_p + σ_p n_k,        σ̂_k = exp(b_θ + σ_θ n'_k) ⊗ σ_t,

with (n_k, n'_k) the rows of ``default_rng(seed).standard_normal((rows, 6))``. Path k is the
desired path from the start pose to estimate k (same timing). An exactly zero rotation vector
keeps σ_t itself, so zero noise reproduces the true path bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from ffsr_gym.model import portable
from ffsr_gym.model import quaternion as quat
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.planning.desired_path import DesiredPath

#: Added to t / interval before flooring, so that t = k · dt on an estimate boundary picks row k.
INDEX_SLACK = 1e-9


def estimate_rows(scenario: Scenario) -> int:
    """Number of target estimates of an episode (1 without ``[target_noise]``)."""
    noise = scenario.target_noise
    if noise is None:
        return 1
    return int(math.floor(scenario.simulation.duration_s / noise.interval_s + INDEX_SLACK)) + 1


def estimate_index(t: float, interval_s: float, rows: int) -> int:
    """The estimate the planner uses at time ``t`` [s] (the kernel's ``estimate_row`` is the same formula)."""
    if rows == 1:
        return 0
    return min(int(math.floor(t / interval_s + INDEX_SLACK)), rows - 1)


def estimated_paths(scenario: Scenario, path: DesiredPath) -> tuple[DesiredPath, ...]:
    """The planner's desired paths, one per estimate (``(path,)`` without ``[target_noise]``).

    Args:
        scenario: the task.
        path: its true desired path (:func:`ffsr_gym.planning.planner.reference_targets`).
    """
    noise = scenario.target_noise
    if noise is None:
        return (path,)
    rows = estimate_rows(scenario)
    draws = np.random.default_rng(int(noise.seed)).standard_normal((rows, 6))
    positions = path.target_position + np.asarray(noise.position_bias_m) + noise.position_sigma_m * draws[:, :3]
    rotations = np.asarray(noise.attitude_bias_rad) + noise.attitude_sigma_rad * draws[:, 3:]
    true_attitude = np.asarray(scenario.target.quaternion_wxyz, dtype=float)
    paths = []
    for position, rotation in zip(positions, rotations):
        attitude = true_attitude if portable.norm(rotation) == 0.0 else quat.multiply(
            quat.from_rotation_vector(rotation), true_attitude)
        paths.append(DesiredPath.between(path.start_position, path.start_attitude, position, attitude,
                                         motion_time=path.motion_time, accel_time=path.accel_time))
    return tuple(paths)
