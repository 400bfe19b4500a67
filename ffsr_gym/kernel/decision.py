"""Compiled (numba) decision of a bounded-score (v2) episode: one call per environment ``step``.

:func:`decide` does everything a v2 step computes from numbers: the action check (finite,
clipped to [-1, 1]), its mapping (the fading residual or (m, T_c)), the physics steps of
:func:`ffsr_gym.kernel.loop.run_into`, the step's smoothness-cost increment
(:mod:`ffsr_gym.kernel.score_terms`), its violation cost, and the next observation, written
into a preallocated float32 buffer. The single environment calls it through :func:`step_episode`
(one argument holds the episode's arrays, so a call costs about a microsecond of dispatch), the
batched environments through :func:`ffsr_gym.kernel.batch.decide_batch`: same function, same
numbers. What stays in Python is what Gymnasium needs as objects (the info dict) and the
episode's final score, computed once from the whole trajectory.

Observation layout (53 floats): sin (12), cos (12) of the joint angles; last applied rates
[rad/s] (12, clipped to ±``OBS_RATE``); EE pose error (6) and base pose error (6), clipped to
±``OBS_ERROR``; obstacle position relative to the nearest robot point [m] (3, ±``OBS_RELATIVE``,
zeros without obstacle); clearance [m] (±``OBS_CLEARANCE``; the bound without obstacle); elapsed
fraction of the episode (≤ 1). A capture spec (``[observation] target_twist``) appends the desired end-effector
twist V_ed (6) [m/s, rad/s] of the planner's step, ±``OBS_TWIST``: the approach's, the grasp frame's own once the
approach has arrived (59 floats).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.experimental import structref

from ffsr_gym.kernel.borrow import borrowed
from ffsr_gym.kernel.flags import runtime_flag
from ffsr_gym.kernel.loop import STATUS_NONFINITE, observe_into, run_into
from ffsr_gym.kernel.physics import workspace
from ffsr_gym.kernel.score_terms import N_SCORE, smoothness_cost, smoothness_into
from ffsr_gym.kernel.settings import F_DT, F_KEEP_OUT, F_M, F_TC

#: Settings of a decision (vector ``ds``): residual scale [rad/s per unit action], fade length [s],
#: desired motion time [s], the (m, T_c [s]) action box, the rate limit [deg/s], the violation
#: cost's clearance scale [m], then the :mod:`~ffsr_gym.kernel.score_terms` settings.
D_RATE_SCALE, D_FADE_S, D_MOTION_S, D_M_LO, D_M_HI, D_T_LO, D_T_HI, D_RATE_LIMIT, D_CLEAR_SCALE, D_SCORE = range(10)
N_DS = D_SCORE + N_SCORE
#: What the action is: residual rates, (m, T_c) in the action box, or ignored ((m, T_c) already set in ``fp``).
MODE_RESIDUAL, MODE_PARAMETERS, MODE_SET = 0, 1, 2
#: :func:`decide`'s status besides :mod:`ffsr_gym.kernel.loop`'s: a NaN or infinite action (nothing done).
STATUS_BAD_ACTION = 4
OBS_RATE, OBS_ERROR, OBS_RELATIVE, OBS_CLEARANCE, OBS_TWIST = 20.0, 10.0, 10.0, 10.0, 10.0
#: The observation's length, and with the desired end-effector twist appended (a capture spec's ``[observation]``).
N_OBS, N_OBS_TWIST = 53, 59
#: Scratch floats of a decision: residual rates (12), score terms (4), obstacle-relative vector (3),
#: then what the last observation's plan was computed with (``_PLANNED``: flag, step, m, T_c).
_PLANNED = 19
N_SCRATCH = _PLANNED + 4


@njit(cache=True, error_model="numpy", inline="always")
def _clip(value, bound):
    return min(max(value, -bound), bound)


@njit(cache=True, error_model="numpy")
def residual_fade(t, motion_time_s, fade_s):
    """The residual's weight f(t) ∈ [0, 1]: 1, a half-cosine over the last ``fade_s`` [s] of the motion, then 0."""
    start = motion_time_s - fade_s
    if t <= start:
        return 1.0
    if t >= motion_time_s:
        return 0.0
    return 0.5 * (1.0 + math.cos(math.pi * (t - start) / fade_s))


@njit(cache=True, error_model="numpy")
def observation_into(obs, angles, last_rates, ee_error, base_error, relative, clearance, time_fraction, twist):
    """Write the 53-float observation (module docstring) into ``obs`` (float32); a 59-float ``obs`` also gets the
    desired end-effector twist ``twist`` (6) [m/s, rad/s], clipped to ±``OBS_TWIST``."""
    if obs.shape[0] > N_OBS:
        for j in range(6):
            obs[N_OBS + j] = _clip(twist[j], OBS_TWIST)
    for j in range(12):
        obs[j] = math.sin(angles[j])
        obs[12 + j] = math.cos(angles[j])
        obs[24 + j] = _clip(last_rates[j], OBS_RATE)
    for j in range(6):
        obs[36 + j] = _clip(ee_error[j], OBS_ERROR)
        obs[42 + j] = _clip(base_error[j], OBS_ERROR)
    for j in range(3):
        obs[48 + j] = _clip(relative[j], OBS_RELATIVE)
    obs[51] = _clip(clearance, OBS_CLEARANCE)
    obs[52] = min(1.0, time_fraction)


@njit(cache=True, error_model="numpy")
def _apply_action(action, mode, t, fp, ds, residual):
    """Residual rates [rad/s] (or the (m, T_c) in ``fp``) of a finite action; returns whether it was clipped."""
    clipped = False
    for j in range(len(action)):
        raw = float(action[j])
        value = min(max(raw, -1.0), 1.0)
        clipped = clipped or value != raw
        if mode == MODE_RESIDUAL:
            residual[j] = value  # scaled below, once the fade is known
        elif mode == MODE_PARAMETERS and j == 0:
            fp[F_M] = ds[D_M_LO] + 0.5 * (value + 1.0) * (ds[D_M_HI] - ds[D_M_LO])
        elif mode == MODE_PARAMETERS and j == 1:
            fp[F_TC] = ds[D_T_LO] + 0.5 * (value + 1.0) * (ds[D_T_HI] - ds[D_T_LO])
    if mode == MODE_RESIDUAL:
        fade = residual_fade(t, ds[D_MOTION_S], ds[D_FADE_S])
        for j in range(12):
            residual[j] = fade * (ds[D_RATE_SCALE] * residual[j])
    else:
        residual[:] = 0.0
    return clipped


def forget_plan(scratch: np.ndarray) -> None:
    """Mark decision scratch, one (:data:`N_SCRATCH`,) row or (N, :data:`N_SCRATCH`) rows, as holding
    no planner step (a new episode's, or a clone's without its workspace)."""
    scratch[..., _PLANNED] = 0.0


@njit(cache=True, error_model="numpy")
def decide(mdl_owner, plant_owner, ws_owner, x, k, n_total, n_max, fp, ip, ds, action, mode, stop, logs_owner, row0,
           last_rates, scratch, obs, own_workspace):
    """One decision from step ``k``: up to ``n_max`` physics steps, then the next observation into ``obs``.

    ``logs``: the 10 trajectory arrays of :class:`~ffsr_gym.sim.compiled.KernelRollout`, written
    from row ``row0``; ``x`` and ``last_rates`` (12) advance in place; ``stop``: end on a violation.
    ``own_workspace``: nothing else writes to ``ws`` between decisions, so the planner step the
    observation computed is reused by the next decision's first physics step when its state and
    (m, T_c) are unchanged (the planner keeps no state between steps: same numbers).

    Returns ``(rows, status, clipped, increment, cost, clearance, ee_error)``: physics steps taken,
    :mod:`~ffsr_gym.kernel.loop` status (or :data:`STATUS_BAD_ACTION`), whether the action was
    clipped, the smoothness-cost increment, the violation cost (0 without violation, else
    depth inside the keep-out distance (or of arm-arm / arm-base contact) / scale + relative excess
    of the peak rate), the clearance [m] and the
    end-effector position error [m] at the new state.
    """
    for j in range(len(action)):
        if not math.isfinite(action[j]):
            return 0, STATUS_BAD_ACTION, False, 0.0, 0.0, 0.0, 0.0
    mdl, ws, logs = borrowed(mdl_owner), borrowed(ws_owner), borrowed(logs_owner)
    residual, terms, rel = scratch[:12], scratch[12:16], scratch[16:19]
    dt = fp[F_DT]
    clipped = _apply_action(action, mode, k * dt, fp, ds, residual)
    planned = (own_workspace and scratch[_PLANNED] == 1.0 and scratch[_PLANNED + 1] == k
               and scratch[_PLANNED + 2] == fp[F_M] and scratch[_PLANNED + 3] == fp[F_TC])
    scratch[_PLANNED] = 0.0
    LX, LV, LDQ, LERR, LCLEAR, LSELF, LMU, LCDF, LSMIN, LTAU = logs
    _, rows, status = run_into(mdl, plant_owner, ws, x, k, n_total, n_max, fp, ip, residual, runtime_flag(stop),
                               runtime_flag(False), runtime_flag(planned),
                               LX[row0:],
                               LV[row0:], LDQ[row0:], LERR[row0:], LCLEAR[row0:], LSELF[row0:], LMU[row0:],
                               LCDF[row0:], LSMIN[row0:], LTAU[row0:])
    if rows == 0 or status == STATUS_NONFINITE:
        return rows, status, clipped, 0.0, 0.0, 0.0, 0.0
    applied = LDQ[row0:row0 + rows]
    smoothness_into(applied, rows, dt, last_rates, terms)
    increment = smoothness_cost(terms, ds[D_SCORE:])
    peak, depth = 0.0, 0.0
    for i in range(rows):
        for j in range(12):
            peak = max(peak, abs(applied[i, j]))
        depth = max(depth, fp[F_KEEP_OUT] - LCLEAR[row0 + i], -LSELF[row0 + i])
    excess = max(0.0, peak * (180.0 / math.pi) / ds[D_RATE_LIMIT] - 1.0)
    cost = depth / ds[D_CLEAR_SCALE] + excess
    last_rates[:] = applied[rows - 1]
    rel[:] = 0.0
    clearance = observe_into(mdl, ws, x, (k + rows) * dt, fp, ip, rel)
    if own_workspace:
        scratch[_PLANNED], scratch[_PLANNED + 1], scratch[_PLANNED + 2], scratch[_PLANNED + 3] = 1.0, k + rows, fp[F_M], fp[F_TC]
    e1 = ws.e1
    observation_into(obs, x[7:19], last_rates, e1, ws.e0, rel, clearance, (k + rows) / n_total, ws.V_ed)
    ee_error = math.sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2])
    return rows, status, clipped, increment, cost, clearance, ee_error


@structref.register
class EpisodeType(types.StructRef):
    """numba type of :class:`Episode`."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(kind)) for name, kind in fields)


class Episode(structref.StructRefProxy):
    """The arrays :func:`decide` needs for one episode, passed to :func:`step_episode` as one argument.

    Fields: ``mdl``, ``plant``, ``ws`` (tuples of the kernel model, plant and workspace), ``x``
    (``ffsr_gym.kernel.servo.N_STATE``,), ``fp``, ``ip``, ``ds`` (:data:`N_DS`), ``logs`` (10 trajectory arrays), ``last_rates``
    (12,), ``scratch`` (:data:`N_SCRATCH`). The arrays are shared, not copied: the episode's
    owner sees them advance.
    """


structref.define_proxy(Episode, EpisodeType, ["mdl", "plant", "ws", "x", "fp", "ip", "ds", "logs", "last_rates",
                                              "scratch"])


@njit(cache=True, error_model="numpy")
def step_episode(episode, action, mode, stop, k, row0, n_total, n_max, obs):
    """:func:`decide` on an :class:`Episode` (same returns)."""
    return decide(episode.mdl, episode.plant, episode.ws, episode.x, k, n_total, n_max, episode.fp, episode.ip,
                  episode.ds, action, mode, runtime_flag(stop), episode.logs, row0, episode.last_rates,
                  episode.scratch, obs, runtime_flag(True))


@njit(cache=True, error_model="numpy")
def new_episode(mdl, plant, x, fp, ip, ds, logs, last_rates):
    """An :class:`Episode` over the given arrays, with a fresh workspace and scratch."""
    return Episode(mdl, plant, workspace(len(mdl.cap_radius)), x, fp, ip, ds, logs, last_rates, np.zeros(N_SCRATCH))
