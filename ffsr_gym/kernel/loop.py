"""Compiled (numba) closed loop: plan, check, log and integrate, step after step (``Rollout.step``)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ffsr_gym.kernel.arrays import ModelArrays
from ffsr_gym.kernel.borrow import borrowed
from ffsr_gym.kernel.collision import body_clearance, capsule_ends_into, obstacle_clearance, self_clearance
from ffsr_gym.kernel.flags import runtime_flag
from ffsr_gym.kernel.physics import midpoint_into, momentum_into, velocity_into, workspace
from ffsr_gym.kernel.planner import plan, true_error_into
from ffsr_gym.kernel.servo import X_V, servo_period_into
from ffsr_gym.kernel.settings import (
    F_BODY_HALF,
    F_DT,
    F_H,
    F_KEEP_OUT,
    F_OBSTACLES,
    F_RATE_MAX,
    I_BODY,
    I_N_EST,
    I_N_OBS,
    I_PLANT,
    I_SCOPE,
    I_SUBSTEPS,
    OBSTACLE_FIELDS,
    frame_record,
    obstacle_at,
)

STATUS_OK, STATUS_RATE, STATUS_COLLISION, STATUS_NONFINITE = 0, 1, 2, 3


@njit(cache=True, error_model="numpy", inline="always")
def _nearest_obstacle(mdl, ws, x, t, fp, ip):
    """Clearance [m] to the nearest obstacle at time ``t`` (inf without one); ``ws.rel`` points to it.

    Needs :func:`capsule_ends_into` done at ``x``. Ties keep the first obstacle (as the reference).
    """
    clear, r0, r1, r2 = np.inf, 0.0, 0.0, 0.0
    p_o = ws.p_obs
    for o in range(ip[I_N_OBS]):
        p_o[0], p_o[1], p_o[2] = obstacle_at(fp, o, t)
        value = obstacle_clearance(mdl, ws, x, p_o, fp[F_OBSTACLES + OBSTACLE_FIELDS * o + 6])
        if value < clear or o == 0:
            clear, r0, r1, r2 = value, ws.rel[0], ws.rel[1], ws.rel[2]
    ws.rel[0], ws.rel[1], ws.rel[2] = r0, r1, r2
    return clear


@njit(cache=True, error_model="numpy", inline="always")
def _clearances(mdl, x, t, fp, ip, ws):
    """Robot–obstacle clearance (inf without obstacle; a tumbling target's body is one) and self clearance [m] at
    the workspace's state."""
    capsule_ends_into(mdl, ws, x)
    clear = np.inf
    if ip[I_N_OBS] > 0:
        clear = _nearest_obstacle(mdl, ws, x, t, fp, ip)
    if ip[I_BODY] == 1:
        clear = min(clear, _body_clearance(mdl, ws, x, t, fp, ip))
    return clear, self_clearance(mdl, ws, x)


@njit(cache=True, error_model="numpy", inline="always")
def _body_clearance(mdl, ws, x, t, fp, ip):
    """Clearance [m] to a tumbling target's body at time ``t`` (needs :func:`capsule_ends_into` done at ``x``)."""
    r = frame_record(t, fp, ip) + 13
    return body_clearance(mdl, ws, x, fp[r + 3:r + 12].reshape((3, 3)), fp[r:r + 3], fp[F_BODY_HALF:F_BODY_HALF + 3])


@njit(cache=True, error_model="numpy")
def _violation(dq, clear, self_c, fp, ip):
    """Status of a step: a joint rate above the limit (in the scored scope) or a collision (an obstacle
    clearance below the keep-out distance, or arm-arm / arm-base contact)."""
    to_deg = 180.0 / math.pi
    for j in range(6 if ip[I_SCOPE] == 1 else 0, 12):
        if abs(dq[j]) * to_deg > fp[F_RATE_MAX]:
            return STATUS_RATE
    if clear < fp[F_KEEP_OUT] or self_c < 0.0:
        return STATUS_COLLISION
    return STATUS_OK


@njit(cache=True, error_model="numpy")
def run(mdl, plant, x_start, k0, n_total, n_max, fp, ip, residual, stop_on_violation, record_only, out_x, out_v,
        out_dq, out_err, out_clear, out_self, out_mu, out_cdf, out_smin, out_tau):
    """Advance up to ``n_max`` steps from step ``k0`` (or only record when ``record_only``).

    ``plant``: the (mass, lever, inertia, drive) arrays of the robot the physics integrates (the
    inertials are ``mdl``'s own unless ``ip[I_PLANT]``: then the planner's model ``mdl`` and the
    plant differ; ``drive``: the servo plant's drives, ``ffsr_gym.kernel.servo``).

    The state ``x`` holds the 19 configuration floats, and for the servo plant
    (``ip[I_SUBSTEPS]`` > 0) the servo state after them (``ffsr_gym.kernel.servo.N_STATE``). The
    kinematic plant applies the planned rates exactly; the servo plant takes them as its drives'
    commands, and the logged rates ``out_dq`` are the ones it produced (the joints' mean rates over
    the step), which the violation test and the score use. ``out_tau``: the drive torques of each
    step (``servo_period_into``; zero for the kinematic plant).

    Writes one sample per step into the ``out_*`` arrays (from row 0) and returns
    ``(x_next, rows, status)``: status 0 ok, 1 rate-limit violation, 2 collision, 3 non-finite rates.
    """
    return run_into(mdl, plant, workspace(len(mdl.cap_radius)), x_start.copy(), k0, n_total, n_max, fp, ip, residual,
                    runtime_flag(stop_on_violation), runtime_flag(record_only), runtime_flag(False), out_x, out_v,
                    out_dq, out_err, out_clear, out_self, out_mu, out_cdf, out_smin, out_tau)


@njit(cache=True, error_model="numpy")
def run_into(mdl_owner, plant_owner, ws_owner, x_owner, k0, n_total, n_max, fp_owner, ip_owner, residual,
             stop_on_violation, record_only, planned, out_x, out_v, out_dq, out_err, out_clear, out_self, out_mu, out_cdf,
             out_smin, out_tau):
    """:func:`run` in the caller's workspace, advancing the state ``x_owner`` in place (and returning it).

    Works on borrowed arrays (``ffsr_gym.kernel.borrow``): the caller owns every argument for the call.
    ``planned``: the workspace already holds :func:`plan` at (``k0`` dt, ``x_owner``) with these
    settings (an observation just computed it), so the first step reuses it.
    """
    mdl, ws, x, fp, ip = borrowed(mdl_owner), borrowed(ws_owner), borrowed(x_owner), borrowed(fp_owner), borrowed(ip_owner)
    mass, lever, inertia, drive = borrowed(plant_owner)  # the plant: the planner's kinematics, its own inertias
    body = ModelArrays(mdl.parent, mdl.placement_R, mdl.placement_p, mdl.axis, mass, lever, inertia, mdl.ee_parent,
                       mdl.ee_R, mdl.ee_p, mdl.cap_parent, mdl.cap_a, mdl.cap_b, mdl.cap_radius, mdl.cap_arm,
                       mdl.cap_vs_base, mdl.box_half, mdl.q_index, mdl.v_index, mdl.axis_code)
    mismatch, substeps = ip[I_PLANT] == 1, ip[I_SUBSTEPS]
    dt, h = fp[F_DT], fp[F_H:F_H + 6]
    rows = 0
    steps = 1 if record_only else min(n_max, n_total - k0)
    dq, v0, e0, mu, cdf, smin = ws.dq, ws.v0, ws.e0, ws.mu, ws.cdf, ws.smin
    for i in range(steps):
        if i > 0 or not planned:
            plan(mdl, x, (k0 + i) * dt, fp, ip, ws)
        logged = ws.e1
        if ip[I_N_EST] > 1:  # the planner followed a target estimate; log the error to the true target
            true_error_into(ws, (k0 + i) * dt, fp, ip)
            logged = ws.e1t
        for j in range(12):
            dq[j] += residual[j]
            if not math.isfinite(dq[j]):
                return x_owner, rows, STATUS_NONFINITE
        clear, self_c = _clearances(mdl, x, (k0 + i) * dt, fp, ip, ws)
        if substeps == 0:
            if mismatch:  # the planner's momentum matrices were the model's; the base moves by the plant's
                momentum_into(body, x, ws)
            velocity_into(v0, x, dq, h, ws)
            for j in range(6):
                out_v[i, j] = v0[j]
            for j in range(12):
                out_v[i, 6 + j] = dq[j]
                out_dq[i, j] = dq[j]
                out_tau[i, j] = 0.0
        else:
            for j in range(18):
                out_v[i, j] = x[X_V + j]
            for j in range(12):
                out_dq[i, j] = x[X_V + 6 + j]  # the rate at the sample: what a final sample records
        for j in range(19):
            out_x[i, j] = x[j]
        out_err[i, 0] = math.sqrt(logged[0] * logged[0] + logged[1] * logged[1] + logged[2] * logged[2])
        out_err[i, 1] = math.sqrt(logged[3] * logged[3] + logged[4] * logged[4] + logged[5] * logged[5])
        out_err[i, 2] = math.sqrt(e0[0] * e0[0] + e0[1] * e0[1] + e0[2] * e0[2])
        out_err[i, 3] = math.sqrt(e0[3] * e0[3] + e0[4] * e0[4] + e0[5] * e0[5])
        out_clear[i] = clear
        out_self[i] = self_c
        for arm in range(2):
            out_mu[i, arm], out_cdf[i, arm], out_smin[i, arm] = mu[arm], cdf[arm], smin[arm]
        rows += 1
        if record_only:
            return x_owner, rows, STATUS_OK
        if substeps == 0:
            midpoint_into(x, body, x, v0, dq, dt, h, ws)
        else:  # the drives follow the planned rates; the step's rates are those the joints made
            servo_period_into(x, body, dq, drive, dt, substeps, h, ws, out_tau[i])
            for j in range(12):
                dq[j] = (x[7 + j] - out_x[i, 7 + j]) / dt
                out_dq[i, j] = dq[j]
        if stop_on_violation:
            status = _violation(dq, clear, self_c, fp, ip)
            if status != STATUS_OK:
                return x_owner, rows, status
    return x_owner, rows, STATUS_OK


@njit(cache=True, error_model="numpy")
def observe(mdl, x, t, fp, ip):
    """EE error (6), base error (6), obstacle-relative vector (3) and clearance [m] at (t, x)."""
    ws, rel = workspace(len(mdl.cap_radius)), np.zeros(3)
    clear = observe_into(mdl, ws, x, t, fp, ip, rel)
    return ws.e1, ws.e0, rel, clear


@njit(cache=True, error_model="numpy")
def observe_into(mdl_owner, ws_owner, x_owner, t, fp_owner, ip_owner, rel):
    """:func:`observe` in the caller's workspace (errors in ``ws.e1``, ``ws.e0``; ``rel`` filled); returns the clearance."""
    mdl, ws, x, fp, ip = borrowed(mdl_owner), borrowed(ws_owner), borrowed(x_owner), borrowed(fp_owner), borrowed(ip_owner)
    plan(mdl, x, t, fp, ip, ws)
    clear = np.inf
    if ip[I_N_OBS] > 0 or ip[I_BODY] == 1:
        capsule_ends_into(mdl, ws, x)
    if ip[I_N_OBS] > 0:
        clear = _nearest_obstacle(mdl, ws, x, t, fp, ip)
        rel[:] = ws.rel
    if ip[I_BODY] == 1:
        clear = min(clear, _body_clearance(mdl, ws, x, t, fp, ip))
    return clear
