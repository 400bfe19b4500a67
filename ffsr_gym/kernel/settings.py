"""The layout of the kernel's settings vectors: ``fp`` (floats, indices ``F_*``) and ``ip`` (integers, ``I_*``),
built by :mod:`ffsr_gym.sim.compiled`, and the compiled readers of their records (obstacles, target estimates, a
tumbling target's frames)."""

from __future__ import annotations

import math

from numba import njit

from ffsr_gym.kernel.physics import MAX_OBSTACLES

F_M, F_TC, F_K, F_LAM1, F_LAM2, F_EPS1, F_EPS2, F_XI, F_DELTA, F_K1, F_DANGER = range(11)
F_TF, F_TA, F_EST_DT, F_DT, F_RATE_MAX = 11, 12, 13, 14, 15
#: Path start (position, attitude), then a target record at ``F_TRUE``: target position (3) [m],
#: rotation axis from the start attitude (3) and its angle [rad] (``TARGET_FIELDS`` floats).
F_P0, F_Q0, F_TRUE, TARGET_FIELDS = 16, 19, 23, 7
F_R0D, F_SBD, F_H = 30, 33, 37
#: Obstacle records from ``F_OBSTACLES`` on, ``OBSTACLE_FIELDS`` floats each: start position (3) [m],
#: drift velocity (3) [m/s], radius [m]; ``ip[I_N_OBS]`` of the ``MAX_OBSTACLES`` slots are used.
F_OBSTACLES, OBSTACLE_FIELDS = 43, 7
#: Keep-out distance [m]: a robot–obstacle clearance below it is a collision (0: contact).
F_KEEP_OUT = F_OBSTACLES + OBSTACLE_FIELDS * MAX_OBSTACLES
#: A tumbling target (docs/model.md §22): the body's half extents (3) [m], its bounding radius [m] and its danger
#: radius beyond that [m] (0: the body is not in the danger field).
F_BODY_HALF, F_BODY_RB, F_BODY_DANGER = F_KEEP_OUT + 1, F_KEEP_OUT + 4, F_KEEP_OUT + 5
#: Length of the fixed part of ``fp``. The planner's target estimates follow it: ``ip[I_N_EST]``
#: records like ``F_TRUE``'s, record k used for t in [k, k + 1) · ``fp[F_EST_DT]``
#: (``ffsr_gym.planning.target_estimate``; one record, the true target, without noise). With a tumbling target,
#: ``ip[I_FRAMES]`` records of ``FRAME_FIELDS`` floats follow them, one per step from t = 0: the desired end-effector
#: position (3) [m], attitude (4, scalar first) and world twist (6) [m/s, rad/s] of the approach
#: (``ffsr_gym.planning.moving_target.MovingTargetPath``), then the body's centre (3) [m] and rotation (9, row by row).
N_FP = F_KEEP_OUT + 6
FRAME_FIELDS = 25
#: ``ip[I_SUBSTEPS]``: 0 for the kinematic plant, else the servo plant's physics steps per planner step
#: (``ffsr_gym.kernel.servo``). ``ip[I_FRAMES]``: the frame records (0: a still target); ``ip[I_BODY]``: 1 when the
#: body is checked for collision.
I_METHOD, I_PHI, I_SPLIT, I_ATT, I_MU, I_BAL_AVOID, I_N_OBS, I_SCOPE, I_PLANT, I_N_EST, I_SUBSTEPS = range(11)
I_FRAMES, I_BODY = 11, 12
N_IP = 13
#: ``ffsr_gym.planning.target_estimate.INDEX_SLACK``.
INDEX_SLACK = 1e-9
METHOD_CODES = {"no_avoidance": 0, "no_feedback": 1, "proportional": 2, "predefined_time": 3}


@njit(cache=True, error_model="numpy", inline="always")
def obstacle_at(fp, o, t):
    """Position (3 scalars) [m] of obstacle ``o`` at time ``t`` [s]: p + v t (``ffsr_gym.model.obstacles``)."""
    b = F_OBSTACLES + OBSTACLE_FIELDS * o
    return fp[b] + fp[b + 3] * t, fp[b + 1] + fp[b + 4] * t, fp[b + 2] + fp[b + 5] * t


@njit(cache=True, error_model="numpy", inline="always")
def estimate_record(t, fp, ip):
    """Index in ``fp`` of the target estimate the planner uses at t [s] (``target_estimate.estimate_index``)."""
    rows = ip[I_N_EST]
    k = 0 if rows == 1 else min(int(math.floor(t / fp[F_EST_DT] + INDEX_SLACK)), rows - 1)
    return N_FP + TARGET_FIELDS * k


@njit(cache=True, error_model="numpy", inline="always")
def frame_record(t, fp, ip):
    """Index in ``fp`` of the frame record of the step t [s] falls on (a tumbling target's; see ``N_FP``)."""
    k = min(int(math.floor(t / fp[F_DT] + 0.5)), ip[I_FRAMES] - 1)
    return N_FP + TARGET_FIELDS * ip[I_N_EST] + FRAME_FIELDS * k
