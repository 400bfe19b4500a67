"""A v2 episode as pure JAX functions: ``reset`` and ``step`` (one decision: the action's mapping, the physics steps
of the decision interval, the smoothness increment, the reward, the next observation and the episode's end).

The same episode as ``FFSR-v2`` and ``FFSR-Residual-v2`` on the kinematic plant (``ffsr_gym.kernel.decision``):
the action is clipped to [-1, 1] and mapped to (m, T_c) in the rule file's box or to residual rates that fade out
over the desired motion's last seconds; every physics step plans, adds the residual, measures the clearances,
moves the robot by the midpoint rule and ends the episode on a rate above the limit or a collision; the reward is
the change of the episode's value 1 / (1 + C); at the end the score is 1 / (1 + C) on success, else 0. The
episode's numbers (:class:`EpisodeTask`) come from the same task files and settings as the environments'.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from ffsr_gym.jax.collision import Shapes, capsule_ends, obstacle_clearance, self_clearance
from ffsr_gym.jax.physics import Model, jax, jnp, kinematics, midpoint
from ffsr_gym.jax.planner import PlanRules, PlanTask, plan
from ffsr_gym.kernel import layout

#: Status codes of a decision (``ffsr_gym.kernel.layout``): running, a rate above the limit, a collision, and a
#: non-finite action (nothing is done, the episode ends as failed; a compiled function cannot raise, so this is how
#: a NaN action shows instead of NaN states).
STATUS_OK, STATUS_RATE, STATUS_COLLISION, STATUS_BAD_ACTION = (layout.STATUS_OK, layout.STATUS_RATE,
                                                               layout.STATUS_COLLISION, layout.STATUS_BAD_ACTION)
RESIDUAL, PARAMETERS = layout.MODE_RESIDUAL, layout.MODE_PARAMETERS
#: The decision's settings vector: the native :class:`ffsr_gym._native.DecisionSettings`' fields, in this order.
SETTINGS = ("rate_scale", "fade_s", "motion_s", "m_lo", "m_hi", "T_lo", "T_hi", "rate_limit_deg_s", "clear_scale",
            "alpha", "beta", "E_ref", "V_ref")
(D_RATE_SCALE, D_FADE_S, D_MOTION_S, D_M_LO, D_M_HI, D_T_LO, D_T_HI, D_RATE_LIMIT, D_CLEAR_SCALE,
 D_SCORE) = range(10)
#: The observation's clip bounds (docs/envs.md).
OBS_RATE, OBS_ERROR, OBS_RELATIVE, OBS_CLEARANCE = 20.0, 10.0, 10.0, 10.0


def settings_vector(settings) -> np.ndarray:
    """A native decision's settings as the vector the JAX episode reads (:data:`SETTINGS`' order)."""
    return np.array([getattr(settings, name) for name in SETTINGS], dtype=float)


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class EpisodeTask:
    """One task as the JAX episode plays it (a pytree; the static fields are the version's, shared by a pool).

    ``plan``: the planner's numbers; ``plant``: the robot the physics moves (the planner's own unless the task
    changes its inertials); ``obstacle_radius`` (n,) [m]; ``keep_out`` [m]; ``settings``: the decision's vector
    (:data:`SETTINGS`: residual scale, fade, motion time, the (m, T_c) box, rate limit, cost scale, score
    settings); ``tolerances``: final end-effector position [m] and attitude errors; ``x0`` (19,).
    """

    plan: PlanTask
    plant: Model
    obstacle_radius: jnp.ndarray
    keep_out: jnp.ndarray
    settings: jnp.ndarray
    tolerances: jnp.ndarray
    x0: jnp.ndarray
    dt: float = field(metadata={"static": True})
    n_steps: int = field(metadata={"static": True})
    steps_per_decision: int = field(metadata={"static": True})
    mode: int = field(metadata={"static": True})
    balance_scope: bool = field(metadata={"static": True})
    twist: bool = field(default=False, metadata={"static": True})


class EpisodeState(NamedTuple):
    """Where an episode stands: state ``x`` (19,), step ``k``, the last applied rates (12,), the smoothness cost so
    far, the (m, T_c) in force, the status, the peak rate of each arm [deg/s], the smallest clearances [m] (to the
    obstacles and self), and whether it ended."""

    x: jnp.ndarray
    k: jnp.ndarray
    last_rates: jnp.ndarray
    cost: jnp.ndarray
    m: jnp.ndarray
    T_c: jnp.ndarray
    status: jnp.ndarray
    peak: jnp.ndarray
    min_clear: jnp.ndarray
    min_self: jnp.ndarray
    done: jnp.ndarray


class Observed(NamedTuple):
    """What an observation is made of, at a state: the 53 (or 59) floats, the end-effector error (6), the obstacle
    clearance and the self clearance [m]."""

    obs: jnp.ndarray
    ee_error: jnp.ndarray
    clearance: jnp.ndarray
    self_clearance: jnp.ndarray


def _clearances(model: Model, shapes: Shapes, task: EpisodeTask, t, x):
    """Obstacle clearance [m] (inf without obstacle), the vector robot → nearest obstacle, and self clearance."""
    kin = kinematics(model, x)
    A, B = capsule_ends(shapes, kin, x)
    n = task.plan.n_obstacles
    if n == 0:
        return jnp.inf, jnp.zeros(3), self_clearance(shapes, kin.R_b, x[:3], A, B)
    positions = task.plan.obstacle_position + task.plan.obstacle_velocity * t
    values, rels = jax.vmap(lambda p, r: obstacle_clearance(shapes, kin.R_b, x[:3], A, B, p, r))(
        positions, task.obstacle_radius)
    values = jnp.where(task.plan.obstacle_mask > 0.0, values, jnp.inf)
    nearest = jnp.argmin(values)  # ties keep the first, as the kernel
    return values[nearest], rels[nearest], self_clearance(shapes, kin.R_b, x[:3], A, B)


def _planned(task: EpisodeTask, m, T_c) -> PlanTask:
    return replace(task.plan, m=m, T_c=T_c)


def observe(model: Model, shapes: Shapes, rules: PlanRules, task: EpisodeTask, state: EpisodeState) -> Observed:
    """The observation at ``state`` (the native decision's, docs/envs.md), float32."""
    t = state.k * task.dt
    decided = plan(model, _planned(task, state.m, state.T_c), rules, t, state.x)
    clearance, rel, self_c = _clearances(model, shapes, task, t, state.x)
    clip = lambda v, bound: jnp.clip(v, -bound, bound)  # noqa: E731
    parts = [jnp.sin(state.x[7:]), jnp.cos(state.x[7:]), clip(state.last_rates, OBS_RATE),
             clip(decided.ee_error, OBS_ERROR), clip(decided.base_error, OBS_ERROR),
             clip(rel, OBS_RELATIVE), clip(jnp.atleast_1d(clearance), OBS_CLEARANCE),
             jnp.atleast_1d(jnp.minimum(1.0, state.k / task.n_steps))]
    return Observed(jnp.concatenate(parts).astype(jnp.float32), decided.ee_error, clearance, self_c)


def reset(model: Model, shapes: Shapes, rules: PlanRules, task: EpisodeTask) -> tuple[EpisodeState, Observed]:
    """The episode's first state and observation (the task's own (m, T_c), no rate applied yet)."""
    state = EpisodeState(task.x0, jnp.zeros((), jnp.int64), jnp.zeros(12), jnp.zeros(()), task.plan.m, task.plan.T_c,
                         jnp.full((), STATUS_OK, jnp.int64), jnp.zeros(2), jnp.full((), jnp.inf), jnp.full((), jnp.inf),
                         jnp.zeros((), bool))  # strong types: a jitted step takes its own output again, no retrace
    seen = observe(model, shapes, rules, task, state)
    return state._replace(min_clear=seen.clearance, min_self=seen.self_clearance), seen


def _fade(task: EpisodeTask, t):
    s = task.settings
    start = s[D_MOTION_S] - s[D_FADE_S]
    return jnp.where(t <= start, 1.0, jnp.where(t >= s[D_MOTION_S], 0.0, 0.5 * (
        1.0 + jnp.cos(jnp.pi * (t - start) / s[D_FADE_S]))))


def _physics_step(model, shapes, rules, task, residual, carry, i):
    """One physics step of a decision (``ffsr_gym.kernel.loop.run_into``), skipped once the episode stopped."""
    x, k, status, m, T_c = carry
    active = (k + i < task.n_steps) & (status == STATUS_OK)
    t = (k + i) * task.dt
    dq = plan(model, _planned(task, m, T_c), rules, t, x).dq + residual
    clear, _, self_c = _clearances(model, shapes, task, t, x)
    x_next = midpoint(task.plant, x, dq, task.plan.momentum, task.dt)[0]
    scope = dq[6:] if task.balance_scope else dq
    too_fast = jnp.any(jnp.abs(scope) * (180.0 / jnp.pi) > task.settings[D_RATE_LIMIT])
    hit = (clear < task.keep_out) | (self_c < 0.0)
    new_status = jnp.where(too_fast, STATUS_RATE, jnp.where(hit, STATUS_COLLISION, STATUS_OK))
    carry = (jnp.where(active, x_next, x), k, jnp.where(active, new_status, status), m, T_c)
    return carry, (dq, clear, self_c, active)


def step(model: Model, shapes: Shapes, rules: PlanRules, task: EpisodeTask, state: EpisodeState,
         action: jnp.ndarray) -> tuple[EpisodeState, Observed, jnp.ndarray, dict]:
    """One decision: ``(state, observed, reward, info)``; ``info`` holds the smoothness increment, the violation
    cost, the rows stepped, the status and, once ``state.done``, the score and success. A finished episode's
    step changes nothing and rewards 0. A non-finite action moves nothing and ends the episode as failed
    (status :data:`STATUS_BAD_ACTION`, score 0)."""
    s = task.settings
    bad = ~jnp.all(jnp.isfinite(action))
    a = jnp.clip(jnp.where(bad, 0.0, action), -1.0, 1.0)
    t0 = state.k * task.dt
    if task.mode == RESIDUAL:
        residual = _fade(task, t0) * (s[D_RATE_SCALE] * a)
        m, T_c = state.m, state.T_c
    else:
        residual = jnp.zeros(12)
        m = s[D_M_LO] + 0.5 * (a[0] + 1.0) * (s[D_M_HI] - s[D_M_LO])
        T_c = s[D_T_LO] + 0.5 * (a[1] + 1.0) * (s[D_T_HI] - s[D_T_LO])
    carry = (state.x, state.k, jnp.where(state.done, -1, STATUS_OK), m, T_c)
    (x, _, status, _, _), (rates, clear, self_c, active) = jax.lax.scan(
        lambda c, i: _physics_step(model, shapes, rules, task, residual, c, i), carry,
        jnp.arange(task.steps_per_decision))
    rows = jnp.sum(active)
    applied = jnp.where(active[:, None], rates, 0.0)
    before = jnp.concatenate((state.last_rates[None], applied[:-1]))
    jumps = jnp.where(active[:, None], applied - before, 0.0) ** 2
    energy = jnp.array([jnp.sum(applied[:, :6] ** 2), jnp.sum(applied[:, 6:] ** 2)]) * task.dt
    variation = jnp.array([jnp.sum(_root(jnp.sum(jumps[:, :6], axis=1))), jnp.sum(_root(jnp.sum(jumps[:, 6:], axis=1)))])
    increment = _cost(s, energy, variation)
    peak = jnp.max(jnp.abs(applied).reshape(-1, 2, 6), axis=(0, 2)) * (180.0 / jnp.pi)
    depth = jnp.maximum(0.0, jnp.max(jnp.where(active, jnp.maximum(task.keep_out - clear, -self_c), 0.0)))
    cost = depth / s[D_CLEAR_SCALE] + jnp.maximum(0.0, jnp.max(peak) / s[D_RATE_LIMIT] - 1.0)
    last = jnp.where(rows > 0, applied[jnp.maximum(rows - 1, 0)], state.last_rates)
    k = state.k + rows
    status = jnp.where(state.done, state.status, status)
    moved = EpisodeState(x, k, last, state.cost + increment, m, T_c, status, jnp.maximum(state.peak, peak),
                         jnp.minimum(state.min_clear, jnp.min(jnp.where(active, clear, jnp.inf))),
                         jnp.minimum(state.min_self, jnp.min(jnp.where(active, self_c, jnp.inf))), state.done)
    seen = observe(model, shapes, rules, task, moved)
    ended = (status != STATUS_OK) | (k >= task.n_steps)
    final = moved._replace(min_clear=jnp.minimum(moved.min_clear, seen.clearance),
                           min_self=jnp.minimum(moved.min_self, seen.self_clearance), done=ended)
    success, score = judge(task, final, seen.ee_error)
    value_before = 1.0 / (1.0 + state.cost)
    reward = jnp.where(ended, score - value_before, 1.0 / (1.0 + final.cost) - value_before)
    refused = bad & ~state.done  # nothing moves; the episode ends, failed
    kept = state._replace(status=jnp.full((), STATUS_BAD_ACTION, jnp.int64), done=jnp.ones((), bool))
    final = jax.tree_util.tree_map(lambda new, old: jnp.where(refused, old, new), final, kept)
    reward = jnp.where(refused, -value_before, reward)
    reward = jnp.where(state.done, 0.0, reward)
    final = jax.tree_util.tree_map(lambda new, old: jnp.where(state.done, old, new), final, state)
    status = jnp.where(refused, STATUS_BAD_ACTION, status)
    success, score = success & ~refused, jnp.where(refused, 0.0, score)
    seen = jax.tree_util.tree_map(lambda new, old: jnp.where(refused, old, new), seen,
                                  observe(model, shapes, rules, task, state))  # a refused decision shows where it was
    increment, cost, rows = (jnp.where(refused, 0, v) for v in (increment, cost, rows))
    info = {"smoothness_increment": increment, "cost": cost, "rows": rows, "status": status, "score": score,
            "success": success, "terminated": status != STATUS_OK, "truncated": (status == STATUS_OK) & ended}
    return final, seen, reward, info


def _root(value):
    positive = value > 0.0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, value, 1.0)), 0.0)


def _cost(s, energy, variation):
    """C = α (E₁/E_ref + V₁/V_ref) + β (E₂/E_ref + V₂/V_ref) (the native kernel's ``smoothness_cost``)."""
    score = s[D_SCORE:]
    ref_e, ref_v = score[2], score[3]
    return score[0] * (energy[0] / ref_e + variation[0] / ref_v) + score[1] * (energy[1] / ref_e + variation[1] / ref_v)


def judge(task: EpisodeTask, state: EpisodeState, ee_error: jnp.ndarray) -> tuple[jnp.ndarray, jnp.ndarray]:
    """``(success, score)`` of an episode that ends at ``state`` with the final error ``ee_error``
    (``ffsr_gym.scoring.score.score_episode``): no rate above the limit, no collision, final errors within the
    tolerances; the score 1 / (1 + C) on success, else 0."""
    position, attitude = jnp.linalg.norm(ee_error[:3]), jnp.linalg.norm(ee_error[3:])
    success = ((state.status == STATUS_OK) & jnp.all(state.peak <= task.settings[D_RATE_LIMIT])
               & (state.min_clear >= task.keep_out) & (state.min_self >= 0.0)
               & (position <= task.tolerances[0]) & (attitude <= task.tolerances[1]))
    return success, jnp.where(success, 1.0 / (1.0 + state.cost), 0.0)


def stacked(tasks: list[EpisodeTask]) -> EpisodeTask:
    """Tasks of one pool as one :class:`EpisodeTask` whose arrays have a leading task axis (same static fields)."""
    return jax.tree_util.tree_map(lambda *leaves: jnp.stack(leaves), *tasks)


def pick(tasks: EpisodeTask, index) -> EpisodeTask:
    """Task ``index`` of :func:`stacked` tasks."""
    return jax.tree_util.tree_map(lambda leaf: leaf[index], tasks)


def as_numpy(tree):
    """A pytree's leaves as numpy arrays (for the project's own scoring code)."""
    return jax.tree_util.tree_map(np.asarray, tree)
