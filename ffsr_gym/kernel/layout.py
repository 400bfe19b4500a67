"""The native kernel's state, log and decision layouts, as the Python side reads them.

The state ``x`` of one copy is 40 floats: the configuration (19: base position, base quaternion
x, y, z, w, the 12 joint angles in the paper's order), then the servo plant's state (base twist in
the base frame and joint rates, 18, from :data:`X_V`; then the saturation record: physics steps
taken, steps with a joint at its torque limit, the peak |τ| / τ_max). The kinematic plant leaves the
servo part at zero.
"""

from __future__ import annotations

#: Layout of the state: the servo plant's velocities from ``X_V``, then its saturation record.
X_V, X_STEPS, X_SATURATED, X_PEAK = 19, 37, 38, 39
N_STATE = 40
#: Columns of the drive array: servo gain [N m s/rad], torque limit [N m] (inf: none), armature [kg m²], viscous
#: friction [N m s/rad], all at the joint (after the gearbox).
DRIVE_GAIN, DRIVE_LIMIT, DRIVE_ARMATURE, DRIVE_FRICTION = range(4)
N_DRIVE = 4

#: The log of one run, one row per step: field → shape of a row (rows of :func:`ffsr_gym._native.run` and of
#: :class:`ffsr_gym._native.Episode`).
LOG_FIELDS = {"x": (19,), "v": (18,), "dq": (12,), "err": (4,), "clear": (), "self": (), "mu": (2,), "cdf": (2,),
              "smin": (2,), "tau": (12,)}

#: Status of a run or a decision: running, a rate above the limit, a collision, non-finite planned rates, (a
#: decision only) a NaN or infinite action, which does nothing, and a capture that ended the episode (a judge that
#: stops at capture, capture v1: the last row is the episode's final sample).
STATUS_OK, STATUS_RATE, STATUS_COLLISION, STATUS_NONFINITE, STATUS_BAD_ACTION, STATUS_CAPTURED = range(6)
#: What a decision's action is: residual rates, (m, T_c) in the action box, or ignored ((m, T_c) already set).
MODE_RESIDUAL, MODE_PARAMETERS, MODE_SET = 0, 1, 2
#: The observation's length, with the desired end-effector twist appended (a capture spec's ``[observation]``), and
#: with the grasp frame's relative pose and twist and the approach's state after that (``grasp``, capture v1).
N_OBS, N_OBS_TWIST, N_OBS_GRASP = 53, 59, 76
