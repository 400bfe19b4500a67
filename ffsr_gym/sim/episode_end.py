"""How an episode ended, read from its trajectory: which violation, where and when (the rendered end marker).

The verdict is recomputed from the recorded samples with the task's own limits (the rate limit
and its scope, the keep-out distance, the tolerances), so it names the same event as the score:
the last applied rates over the limit, the last sample inside the keep-out distance or touching
the robot's own parts, or the end of the run near or away from the target.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ffsr_gym.model.robot import ARMS
from ffsr_gym.sim.rollout import Rollout
from ffsr_gym.types import Array


@dataclass(frozen=True)
class EpisodeEnd:
    """The end of an episode.

    Attributes:
        kind: ``"rate limit"``, ``"collision"``, ``"self contact"``, ``"reached"`` or ``"missed"``; under a capture
            rule (:func:`with_capture`) ``"captured"`` or ``"no capture"`` instead of the last two.
        t_s: time of the last sample [s].
        point_m: where (3,) [m]: the joint over the rate limit, the robot's point closest to what
            it hit, or the end-effector.
        text: one line for the frame, with the numbers.
    """

    kind: str
    t_s: float
    point_m: Array
    text: str

    @property
    def failed(self) -> bool:
        """Whether the episode ended in a violation, away from the target or without a capture."""
        return self.kind not in ("reached", "captured")


def _first(flags: Array) -> int | None:
    hits = np.flatnonzero(flags)
    return int(hits[0]) if len(hits) else None


def episode_end(rollout: Rollout) -> EpisodeEnd:
    """How the episode of ``rollout`` ended: its first violation (sample index, hence time), else its last sample."""
    traj, scenario, setup = rollout.trajectory(), rollout.scenario, rollout.setup
    objective, robot, collision = scenario.objective, setup.robot, setup.assets.collision
    rates = np.degrees(np.abs(traj.dq_joints[:-1] if rollout.finished else traj.dq_joints))
    if objective.rate_limit_scope == "balance_arm":
        rates[:, :6] = 0.0
    events = {"rate limit": _first(rates.max(axis=1, initial=0.0) > objective.max_rate_deg_s),
              "collision": _first(traj.clearance_m < objective.keep_out_m),
              "self contact": _first(traj.self_clearance_m < 0.0)}
    kind = min((k for k in events if events[k] is not None), key=lambda k: events[k], default=None)
    index = len(traj.t) - 1 if kind is None else events[kind]
    q, t = traj.q[index], float(traj.t[index])
    robot.update_kinematics(q)
    if kind == "rate limit":
        joint = int(np.argmax(rates[index]))
        arm, k = divmod(joint, 6)
        return EpisodeEnd(kind, t, robot.joint_points(arm)[0][k],
                          f"rate limit at t = {t:.2f} s: {ARMS[arm]} joint {k + 1} at {rates[index, joint]:.0f} deg/s "
                          f"> {objective.max_rate_deg_s:g} deg/s")
    if kind == "collision":
        near = collision.obstacle_proximity(q, setup.obstacles_at(index))
        return EpisodeEnd(kind, t, near.witness_points[0],
                          f"collision at t = {t:.2f} s: {near.pair[0]} {1000 * near.distance_m:.1f} mm from "
                          f"{near.pair[1]} (keep-out {1000 * objective.keep_out_m:g} mm)")
    if kind == "self contact":
        near = collision.self_proximity(q)
        return EpisodeEnd(kind, t, near.witness_points[0],
                          f"self contact at t = {t:.2f} s: {near.pair[0]} touches {near.pair[1]}")
    ee = robot.transform_ee_to_world(q, 0).translation
    error = float(traj.ee_position_error_m[index])
    if error <= objective.ee_position_tolerance_m and traj.ee_attitude_error[index] <= objective.ee_attitude_tolerance:
        return EpisodeEnd("reached", t, ee, f"reached the target at t = {t:.2f} s (error {1000 * error:.2f} mm)")
    return EpisodeEnd("missed", t, ee, f"ended at t = {t:.2f} s, {1000 * error:.1f} mm from the target "
                                       f"(tolerance {1000 * objective.ee_position_tolerance_m:g} mm)")


def with_capture(end: EpisodeEnd, capture_time_s: float | None, hold_s: float) -> EpisodeEnd:
    """``end`` of an episode judged by a capture rule: an end without a violation says whether and when the
    end-effector captured the grasp frame, and over which hold window [s]."""
    if end.kind not in ("reached", "missed"):
        return end
    if capture_time_s is None:
        return EpisodeEnd("no capture", end.t_s, end.point_m, f"no capture: the end-effector never held the grasp "
                                                              f"frame within the tolerances for {hold_s:g} s")
    return EpisodeEnd("captured", end.t_s, end.point_m, f"captured: held within the tolerances over t = "
                                                        f"{capture_time_s - hold_s:.2f}-{capture_time_s:.2f} s")
