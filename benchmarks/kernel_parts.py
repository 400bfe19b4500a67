"""Per-call wall time of the parts of one kernel physics step (``bench.py`` renders them in the README).

Each part runs ``n`` times in a compiled loop at one mid-episode state of ``paper`` (the planner
step, the collision distances, the base velocity, the midpoint step), on borrowed arrays as in the
kernel's own loop, so the numbers add up to about one step of the rollout.
"""

from __future__ import annotations

import time

import numpy as np
from numba import njit

from ffsr_gym.kernel import loop, physics, planner
from ffsr_gym.kernel.borrow import borrowed
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.sim.compiled import KernelRollout

#: Part name -> what the README calls it.
PARTS = {"kinematics": "forward kinematics (done twice per step: at the state and at the midpoint)",
         "momentum": "momentum matrices H_b, H_bm (twice per step)",
         "plan": "planner step at the state (kinematics, momentum, errors, danger field, two filtered inverses)",
         "clearances": "collision distances (obstacle, arm-arm, arm-base)",
         "velocity": "momentum-conserving base velocity",
         "midpoint": "midpoint integration (kinematics, momentum and base velocity at the half step)"}


def operation_counts(joints: int = 12, capsules: int = 8, base_pairs: int = 6, obstacles: int = 1,
                     exact_pairs: float = 2.5) -> dict[str, int]:
    """Floating-point operations of one physics step's parts, counted from the kernel's loops (each add,
    subtract, multiply, divide, square root or ``math`` call one; comparisons and index arithmetic not
    counted). ``exact_pairs``: self-clearance pairs measured exactly per step (2.6 on ``paper``, the rest
    culled by their bounds). An estimate of the arithmetic, not a measurement: the processor's counters are
    not readable here.
    """
    arm = joints // 2
    kinematics = 30 + joints * (18 + 63 + 2) + 2 * (45 + 18)  # base rotation; per joint: origin, two mixed columns, cos/sin
    momentum = 75 + joints * (21 + 75 + 3 + 28 + 54 + 10)  # base inertia; per body: CoM, inertia, composite, column, parent
    householder = sum(2 * m * m + 2 * m * (m + 1) + 5 * m + 10 for m in range(arm - 1, 1, -1))
    singular = 2 * (21 * 11 + householder + 6 * 14 + 3 * 6 * 7)  # both arms: Gram, reduction, Laguerre, ~3 Newton steps
    field = 2 * obstacles * arm * 60  # both arms: one logarithm and four square roots per segment and obstacle
    gradient = obstacles * (arm * 20 + 45 * arm * (arm + 1) // 2)  # one arm, only while its blend acts
    planner_rest = 130 + 250 + 6 * joints + 150 + 2 * 200 + 2 * 72  # base and EE tasks, Jacobian, targets, LU, norms
    pairs = (capsules // 2) ** 2 + base_pairs
    clearances = capsules * 36 + (70 + capsules * 25) * obstacles + capsules * 16 + pairs * 14 + int(exact_pairs * 350)
    velocity, integrate = 260, 100
    return {"kinematics": kinematics, "momentum": momentum, "singular values": singular, "danger field": field,
            "field gradient (while avoiding)": gradient, "rest of the planner step": planner_rest,
            "clearances": clearances, "base velocity": velocity, "integration": integrate,
            "step": 2 * kinematics + 2 * momentum + singular + field + planner_rest + clearances + 2 * velocity
            + 2 * integrate}


@njit(cache=True)
def _kinematics(mdl_owner, x_owner, ws_owner, n):
    mdl, x, ws = borrowed(mdl_owner), borrowed(x_owner), borrowed(ws_owner)
    for _ in range(n):
        physics.kinematics_into(mdl, x, ws)


@njit(cache=True)
def _momentum(mdl_owner, x_owner, ws_owner, n):
    mdl, x, ws = borrowed(mdl_owner), borrowed(x_owner), borrowed(ws_owner)
    for _ in range(n):
        physics.momentum_into(mdl, x, ws)


@njit(cache=True)
def _plan(mdl_owner, x_owner, t, fp_owner, ip_owner, ws_owner, n):
    mdl, x, fp, ip, ws = borrowed(mdl_owner), borrowed(x_owner), borrowed(fp_owner), borrowed(ip_owner), borrowed(ws_owner)
    for _ in range(n):
        planner.plan(mdl, x, t, fp, ip, ws)


@njit(cache=True)
def _clearances(mdl_owner, x_owner, t, fp_owner, ip_owner, ws_owner, n):
    mdl, x, fp, ip, ws = borrowed(mdl_owner), borrowed(x_owner), borrowed(fp_owner), borrowed(ip_owner), borrowed(ws_owner)
    total = 0.0
    for _ in range(n):
        clear, self_c = loop._clearances(mdl, x, t, fp, ip, ws)
        total += clear + self_c
    return total


@njit(cache=True)
def _velocity(x_owner, h, ws_owner, n):
    x, ws = borrowed(x_owner), borrowed(ws_owner)
    for _ in range(n):
        physics.velocity_into(ws.v0, x, ws.dq, h, ws)


@njit(cache=True)
def _midpoint(mdl_owner, x_owner, h, dt, ws_owner, n):
    mdl, x, ws = borrowed(mdl_owner), borrowed(x_owner), borrowed(ws_owner)
    out = np.empty(19)
    for _ in range(n):
        physics.midpoint_into(out, mdl, x, ws.v0, ws.dq, dt, h, ws)


def measure_parts(n: int = 20_000) -> dict[str, float]:
    """Seconds per call of each part of :data:`PARTS`, and ``step``: one step of the 20 s ``paper`` rollout."""
    rollout = KernelRollout(load_scenario("paper"))
    rollout.advance(600)  # t = 6 s: the avoidance acts
    mdl, fp, ip, x, t = rollout._mdl, rollout.fp, rollout.ip, rollout.x.copy(), rollout.t
    ws, h = physics.workspace(len(mdl[13])), np.zeros(6)
    planner_call = (_plan, (mdl, x, t, fp, ip, ws))
    calls = {"kinematics": (_kinematics, (mdl, x, ws)), "momentum": (_momentum, (mdl, x, ws)), "plan": planner_call,
             "clearances": (_clearances, (mdl, x, t, fp, ip, ws)), "velocity": (_velocity, (x, h, ws)),
             "midpoint": (_midpoint, (mdl, x, h, rollout.dt, ws))}
    out = {}
    for key, (function, args) in calls.items():
        planner_call[0](*planner_call[1], 1)  # the workspace holds the planner's results at x
        function(*args, 10)
        best = np.inf
        for _ in range(3):
            start = time.perf_counter()
            function(*args, n)
            best = min(best, (time.perf_counter() - start) / n)
        out[key] = best
    whole = KernelRollout(load_scenario("paper"))
    start = time.perf_counter()
    whole.advance(whole.n_steps)
    out["step"] = (time.perf_counter() - start) / whole.n_steps
    return out
