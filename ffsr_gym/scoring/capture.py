"""When an end-effector has captured a moving grasp frame (docs/model.md §22): its pose within tolerances of the
frame and its twist within tolerances of the frame's, continuously for a hold window.

The capture rule's numbers (tolerances, hold window) are data of the capture family's rule file; this module only
applies them to the relative motion of an episode, and reports how far inside the tolerances the window kept (the
margins a certificate needs, as v2's certificates keep theirs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model import portable
from ffsr_gym.model.benchmark import CaptureRule
from ffsr_gym.model.quaternion import from_rotation
from ffsr_gym.sim.setup import ScenarioSetup
from ffsr_gym.sim.trajectory import Trajectory
from ffsr_gym.types import Array

#: The relative quantities a capture bounds, in this order: position [m], attitude [rad], linear velocity [m/s],
#: angular velocity [rad/s] (each a field of :class:`~ffsr_gym.model.benchmark.CaptureRule`, the bound).
QUANTITIES = ("position_m", "attitude_rad", "linear_velocity_m_s", "angular_velocity_rad_s")


@dataclass(frozen=True)
class Capture:
    """What an episode's relative motion says of capture.

    Attributes:
        captured: the tolerances held over a whole hold window.
        time_s: when the first such window ended (NaN when never).
        worst_ratio: (4,) over that window, the largest value / bound of each quantity (NaN when never): how far
            inside the tolerances it stayed (1 is on the bound).
        margin_ratio: over every window of the episode, the smallest of its largest value / bound: the episode
            captures with every tolerance scaled by this factor and by no smaller one (<= 1 exactly when
            captured). The first window starts as soon as the quantities enter the bounds, so its own worst ratio
            is about 1 by construction; this is the margin a certificate keeps.
        sample: the sample that ended the first window (-1: never; the native judge's).
        contact_speed_m_s: the relative linear speed [m/s] at the first sample within the rule's ``contact_m`` of
            the grasp frame (NaN: none, or a rule without it; the native judge's).
    """

    captured: bool
    time_s: float
    worst_ratio: Array
    margin_ratio: float = math.inf
    sample: int = -1
    contact_speed_m_s: float = math.nan


def relative_motion(ee_position_m: Array, ee_quaternion: Array, ee_twist: Array, grasp_position_m: Array,
                    grasp_quaternion: Array, grasp_twist: Array) -> Array:
    """(N, 4) the size of each quantity of :data:`QUANTITIES` at each sample: ‖p_e − p_h‖, the angle of
    σ_h* ⊗ σ_e [rad], ‖v_e − v_h‖ and ‖ω_e − ω_h‖ (twists (N, 6) [v; ω] in the world frame, quaternions scalar
    first)."""
    position = np.linalg.norm(np.asarray(ee_position_m) - grasp_position_m, axis=1)
    dot = np.abs(np.sum(np.asarray(ee_quaternion) * np.asarray(grasp_quaternion), axis=1))
    # the angle between the frames, in [0, π]; math's acos, as everything that feeds a score (docs/model.md §17)
    attitude = np.array([2.0 * math.acos(min(float(c), 1.0)) for c in dot])
    difference = np.asarray(ee_twist) - np.asarray(grasp_twist)
    return np.column_stack([position, attitude, np.linalg.norm(difference[:, :3], axis=1),
                            np.linalg.norm(difference[:, 3:], axis=1)])


def capture(time_s: Array, relative: Array, rule: CaptureRule) -> Capture:
    """The first hold window over which every quantity of ``relative`` ((N, 4), :func:`relative_motion`) stays
    within its bound of ``rule`` (a rule file's ``[capture]``), at samples ``time_s`` (N,) [s] equally spaced; the
    window holds ``rule.hold_s`` [s] of consecutive samples that are all inside."""
    time_s = np.asarray(time_s, dtype=float)
    ratio = np.asarray(relative, dtype=float) / np.array([getattr(rule, name) for name in QUANTITIES])
    step = float(time_s[1] - time_s[0]) if len(time_s) > 1 else 0.0
    needed = int(round(rule.hold_s / step)) + 1 if step > 0.0 else 1
    if len(ratio) < needed:
        return Capture(False, float("nan"), np.full(len(QUANTITIES), np.nan))
    # each window's largest value / bound: <= 1 exactly when all its samples are inside (NaN never is)
    windows = np.lib.stride_tricks.sliding_window_view(ratio.max(axis=1), needed).max(axis=1)
    margin = float(np.min(windows))
    hits = np.flatnonzero(windows <= 1.0)
    if not len(hits):
        return Capture(False, float("nan"), np.full(len(QUANTITIES), np.nan), margin)
    first = int(hits[0])
    return Capture(True, float(time_s[first + needed - 1]), ratio[first:first + needed].max(axis=0), margin)


def episode_relative_motion(setup: ScenarioSetup, trajectory: Trajectory) -> Array:
    """(N, 4) :func:`relative_motion` of an episode's mission end-effector to its scenario's grasp frame, at every
    sample: the end-effector's pose and world twist J(q_k) v_k from the trajectory (the twist it moved with over
    the step), the grasp frame's from :attr:`~ffsr_gym.sim.setup.ScenarioSetup.grasp`.

    Raises:
        InvalidInputError: the scenario has no ``[tumbling_target]``, or the trajectory is not on its steps.
    """
    grasp = setup.grasp
    if grasp is None:
        raise InvalidInputError(f"scenario {setup.scenario.name!r} has no [tumbling_target] to capture")
    n = len(trajectory.t)
    if n > len(grasp.position_m) or abs(trajectory.info.get("dt_s", grasp.dt_s) - grasp.dt_s) > 1e-12:
        raise InvalidInputError(f"a trajectory of {n} samples at dt = {trajectory.info.get('dt_s')} s; allowed: at most "
                                f"{len(grasp.position_m)} samples at dt = {grasp.dt_s} s (the scenario's)")
    robot, frame = setup.robot, int(setup.robot.ee_frame_ids[0])
    position, attitude, jacobian = np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 6, trajectory.v.shape[1]))
    for k in range(n):
        robot.update_kinematics(trajectory.q[k])
        placement = robot.data.oMf[frame]
        position[k], attitude[k] = placement.translation, from_rotation(placement.rotation)
        jacobian[k] = robot.ee_jacobian(0)
    twist = portable.matvec_rows(jacobian, trajectory.v[:n])  # Robot.ee_twist of every sample, in one pass
    grasp_twist = np.hstack((grasp.velocity_m_s[:n], grasp.omega_rad_s[:n]))
    return relative_motion(position, attitude, twist, grasp.position_m[:n], grasp.quaternion[:n], grasp_twist)


def native_capture(setup: ScenarioSetup, trajectory: Trajectory, rule: CaptureRule) -> Capture:
    """The native kernel's capture judge (docs/model.md §23) over a recorded trajectory of a scenario with a
    ``[commanded_approach]``: the same quantities, hold window and margin as :func:`capture`, computed by the
    kernel's kinematics from the trajectory's states and velocities, as an episode's judge computes them while it
    runs (the same bits for the same rows).

    Raises:
        InvalidInputError: the scenario has no commanded approach, or the trajectory is not on its steps.
    """
    from ffsr_gym import _native
    from ffsr_gym.kernel.planner import planner_settings

    scenario = setup.scenario
    if scenario.commanded_approach is None:
        raise InvalidInputError(f"scenario {scenario.name!r} has no [commanded_approach]: judge it with "
                                "episode_relative_motion and capture")
    n, dt = len(trajectory.t), scenario.simulation.dt_s
    if n > scenario.n_steps + 1 or abs(trajectory.info.get("dt_s", dt) - dt) > 1e-12:
        raise InvalidInputError(f"a trajectory of {n} samples at dt = {trajectory.info.get('dt_s')} s; allowed: at "
                                f"most {scenario.n_steps + 1} samples at dt = {dt} s (the scenario's)")
    model = setup.assets.kernel
    x = np.zeros((n, 19))
    x[:, :7], x[:, 7:] = trajectory.q[:, :7], trajectory.q[:, model.q_index]
    v = np.zeros((n, 18))
    v[:, :6], v[:, 6:] = trajectory.v[:, :6], trajectory.v[:, model.v_index]
    settings = planner_settings(setup, method="predefined_time", m=scenario.planner.m, T_c=scenario.planner.T_c_s)
    judged = _native.capture_of(setup.assets.native, settings, x, v, np.array([getattr(rule, q) for q in QUANTITIES]),
                                rule.hold_s, rule.contact_m)
    return capture_of_judge(judged, dt)


def capture_of_judge(judged: dict, dt_s: float) -> Capture:
    """The :class:`Capture` of a native judge's dict (``_native.capture_of``, ``Episode.capture``) at step ``dt_s``."""
    at, contact = int(judged["captured_at"]), float(judged.get("contact_speed", math.nan))
    if at < 0:
        return Capture(False, float("nan"), np.full(len(QUANTITIES), np.nan), float(judged["margin"]),
                       contact_speed_m_s=contact)
    return Capture(True, at * dt_s, np.asarray(judged["worst"], dtype=float), float(judged["margin"]), at, contact)

