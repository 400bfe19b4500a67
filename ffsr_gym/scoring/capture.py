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

from ffsr_gym.types import Array

#: The relative quantities a capture bounds, in this order: position [m], attitude [rad], linear velocity [m/s],
#: angular velocity [rad/s].
QUANTITIES = ("position_m", "attitude_rad", "linear_velocity_m_s", "angular_velocity_rad_s")


@dataclass(frozen=True)
class CaptureTolerances:
    """The capture rule: each bound of :data:`QUANTITIES` (> 0) and the hold window ``hold_s`` [s] (>= 0)."""

    position_m: float
    attitude_rad: float
    linear_velocity_m_s: float
    angular_velocity_rad_s: float
    hold_s: float

    def bounds(self) -> Array:
        """(4,) the bounds in the order of :data:`QUANTITIES`."""
        return np.array([getattr(self, name) for name in QUANTITIES])


@dataclass(frozen=True)
class Capture:
    """What an episode's relative motion says of capture.

    Attributes:
        captured: the tolerances held over a whole hold window.
        time_s: when the first such window ended (NaN when never).
        worst_ratio: (4,) over that window, the largest value / bound of each quantity (NaN when never): how far
            inside the tolerances it stayed (1 is on the bound).
    """

    captured: bool
    time_s: float
    worst_ratio: Array


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


def capture(time_s: Array, relative: Array, tolerances: CaptureTolerances) -> Capture:
    """The first hold window over which every quantity of ``relative`` ((N, 4), :func:`relative_motion`) stays
    within its bound, at samples ``time_s`` (N,) [s] equally spaced; the window holds ``hold_s`` [s] of
    consecutive samples that are all inside."""
    time_s = np.asarray(time_s, dtype=float)
    ratio = np.asarray(relative, dtype=float) / tolerances.bounds()
    inside = np.all(ratio <= 1.0, axis=1)
    step = float(time_s[1] - time_s[0]) if len(time_s) > 1 else 0.0
    needed = int(round(tolerances.hold_s / step)) + 1 if step > 0.0 else 1
    run = 0
    for k, ok in enumerate(inside):
        run = run + 1 if ok else 0
        if run >= needed:
            window = ratio[k - needed + 1:k + 1]
            return Capture(True, float(time_s[k]), window.max(axis=0))
    return Capture(False, float("nan"), np.full(len(QUANTITIES), np.nan))
