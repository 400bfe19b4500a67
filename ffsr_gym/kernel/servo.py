"""Compiled (numba) servo plant: velocity servos with torque limits driving the free-floating dynamics.

Each joint's drive applies ``τ = clip(k_v (q̇_cmd − q̇), ±τ_max) − b q̇`` [N m] (servo gain k_v, torque
limit τ_max, viscous friction b) through a rotor whose reflected inertia (the armature) adds to the
joint's inertia; the base is free (no external load). A physics step of ``h`` [s] is semi-implicit
Euler on all 18 velocities with the drives' damping implicit, as MuJoCo's ``implicitfast``: the
articulated-body algorithm solves (M + h D) a = τ(v) − b(q, v) (D the damping of each joint: k_v + b,
or b while its torque is at the limit), v ← v + h a, then q ← q ⊕ h v (the base by the SE(3)
exponential). Which joints saturate is found by an active-set iteration: a joint whose implicit
torque leaves its limit is held there, one that comes back inside is freed, until neither happens.
The implicit damping keeps the step stable at any gain. Euler lets the momentum drift by O(h); at
the end of every planner step the base twist is set back to the one that carries the system's
momentum at the new joint rates (the kinematic plant's rule), so every logged state conserves it to
rounding. The convergence study that chose ``h`` is in docs/model.md §21.

The servo state rides after the kernel's 19 configuration floats in the state vector ``x``
(:data:`N_STATE` floats): base twist in the base frame and joint rates (18), then the episode's
saturation record (physics steps taken, steps with a joint at its limit, the peak |τ| / τ_max).
The drive arrays are ``drive`` (12, :data:`N_DRIVE`): gain, limit, armature, friction per joint.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ffsr_gym.kernel.dynamics import aba_into, dynamics_workspace
from ffsr_gym.kernel.physics import integrate_into, kinematics_into, momentum_into, velocity_into, workspace

#: Columns of the drive array: servo gain [N m s/rad], torque limit [N m] (inf: none), armature
#: [kg m²], viscous friction [N m s/rad], all at the joint (after the gearbox).
DRIVE_GAIN, DRIVE_LIMIT, DRIVE_ARMATURE, DRIVE_FRICTION = range(4)
N_DRIVE = 4
#: Layout of the servo state: velocity (18) from ``X_V``, then the saturation record.
X_V, X_STEPS, X_SATURATED, X_PEAK = 19, 37, 38, 39
N_STATE = 40
_MAX_ACTIVE_SET = 24


@njit(cache=True, error_model="numpy")
def servo_scratch():
    """Scratch of :func:`servo_step_into`: torques, armatures, accelerations, sides (-1, 0, 1) of each joint."""
    return np.zeros(12), np.zeros(12), np.zeros(18), np.zeros(12)


@njit(cache=True, error_model="numpy")
def servo_step_into(x, mdl, cmd, drive, h, dyn, scratch, tau_out):
    """Advance the servo state ``x`` (:data:`N_STATE`) by one physics step ``h`` [s] under rate commands ``cmd`` (12) [rad/s].

    ``mdl``: the model arrays of the robot the physics integrates; ``dyn``: its
    :data:`~ffsr_gym.kernel.dynamics.Dynamics` workspace; ``scratch``: :func:`servo_scratch`'s
    arrays. ``tau_out`` (12) receives the drive torques of the step [N m] (the servo term, within
    the limit; friction not included). Updates the saturation record; returns whether a joint was
    at its limit.
    """
    tau, arm, acc, side = scratch
    v = x[X_V:X_V + 18]
    for j in range(12):
        demand = drive[j, DRIVE_GAIN] * (cmd[j] - v[6 + j])
        limit = drive[j, DRIVE_LIMIT]
        side[j] = 1.0 if demand > limit else (-1.0 if demand < -limit else 0.0)
    for _ in range(_MAX_ACTIVE_SET):
        for j in range(12):
            gain, limit, friction = drive[j, DRIVE_GAIN], drive[j, DRIVE_LIMIT], drive[j, DRIVE_FRICTION]
            rate = v[6 + j]
            if side[j] == 0.0:
                tau[j] = gain * (cmd[j] - rate) - friction * rate
                arm[j] = drive[j, DRIVE_ARMATURE] + h * (gain + friction)
            else:
                tau[j] = side[j] * limit - friction * rate
                arm[j] = drive[j, DRIVE_ARMATURE] + h * friction
        aba_into(acc, mdl, x[7:19], v, tau, arm, dyn)
        changed = False
        for j in range(12):
            demand = drive[j, DRIVE_GAIN] * (cmd[j] - (v[6 + j] + h * acc[6 + j]))
            if side[j] == 0.0 and abs(demand) > drive[j, DRIVE_LIMIT]:
                side[j], changed = (1.0 if demand > 0.0 else -1.0), True
            elif side[j] != 0.0 and demand * side[j] < drive[j, DRIVE_LIMIT]:
                side[j], changed = 0.0, True
        if not changed:
            break
    saturated, peak = False, x[X_PEAK]
    for j in range(12):
        limit = drive[j, DRIVE_LIMIT]
        if side[j] != 0.0:
            tau_out[j] = side[j] * limit
            saturated = True
        else:
            tau_out[j] = drive[j, DRIVE_GAIN] * (cmd[j] - (v[6 + j] + h * acc[6 + j]))
        if limit < np.inf:
            peak = max(peak, abs(tau_out[j]) / limit)
    for a in range(18):
        v[a] += h * acc[a]
    integrate_into(x, x, v[:6], v[6:], h)
    x[X_STEPS] += 1.0
    x[X_SATURATED] += 1.0 if saturated else 0.0
    x[X_PEAK] = peak
    return saturated


@njit(cache=True, error_model="numpy")
def keep_momentum_into(x, mdl, momentum, ws):
    """Set the base twist of the servo state ``x`` to the one that carries ``momentum`` ([P; L_G], 6) at its joint rates.

    ``ws``: a kernel workspace (its kinematics and momentum matrices are left at ``x``).
    """
    kinematics_into(mdl, x, ws)
    momentum_into(mdl, x, ws)
    velocity_into(x[X_V:X_V + 6], x, x[X_V + 6:X_V + 18], momentum, ws)


@njit(cache=True, error_model="numpy")
def servo_period_into(x, mdl, cmd, drive, dt, substeps, momentum, ws, tau_log):
    """Hold the rate commands ``cmd`` (12) [rad/s] for one planner step ``dt`` [s]: ``substeps`` physics steps,
    then the base twist set to the one that carries ``momentum`` (:func:`keep_momentum_into`).

    ``tau_log`` (12) receives, per joint, the drive torque of largest magnitude in the period [N m].
    """
    dyn, scratch, tau = dynamics_workspace(mdl), servo_scratch(), np.zeros(12)
    tau_log[:] = 0.0
    h = dt / substeps
    for _ in range(substeps):
        servo_step_into(x, mdl, cmd, drive, h, dyn, scratch, tau)
        for j in range(12):
            if abs(tau[j]) > abs(tau_log[j]):
                tau_log[j] = tau[j]
    keep_momentum_into(x, mdl, momentum, ws)


@njit(cache=True, error_model="numpy")
def drive_open_loop(x, mdl, cmds, drive, h, momentum, every, x_out, tau_out):
    """The servo plant under a given command sequence: row k of ``cmds`` (n, 12) [rad/s] held for physics step k.

    No planner: this is how the dynamics are studied on their own (tests, the step-size study).
    ``every`` > 0: the base twist is set back to the one carrying ``momentum`` after every ``every``
    steps, as the closed loop does after each planner step (0: never; the momentum then drifts
    as Euler lets it). ``x`` (:data:`N_STATE`) advances in place; ``x_out`` (n + 1,
    :data:`N_STATE`) receives the state before each step and after the last, ``tau_out`` (n, 12)
    each step's drive torques [N m].
    """
    dyn, scratch = dynamics_workspace(mdl), servo_scratch()
    ws = workspace(len(mdl.cap_radius))
    x_out[0] = x
    for k in range(cmds.shape[0]):
        servo_step_into(x, mdl, cmds[k], drive, h, dyn, scratch, tau_out[k])
        if every > 0 and (k + 1) % every == 0:
            keep_momentum_into(x, mdl, momentum, ws)
        x_out[k + 1] = x
