"""Gradients through the closed loop: an episode's smoothness cost as a function of a residual schedule's knots
(``ffsr_gym.tasks.schedule``), differentiable with ``jax.grad``, and a projected gradient search over the knots.

:func:`schedule_actions` turns K knots into the action of every decision exactly as
:meth:`~ffsr_gym.tasks.schedule.Schedule.actions` does (linear in the decision index over the decisions that start
before the desired motion ends, then held), but in float64 and without the environments' float32 rounding, so that
it has a derivative. :func:`episode` plays the schedule with :func:`ffsr_gym.jax.episode.step` and returns the
smoothness cost C, the success and the margins of the success test.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

from ffsr_gym.jax.episode import EpisodeTask, reset, step
from ffsr_gym.jax.physics import jax, jnp


class Played(NamedTuple):
    """An episode of a schedule: smoothness cost C, success, score, peak rate [deg/s], smallest obstacle and self
    clearances [m] and the final end-effector position error [m]."""

    cost: jnp.ndarray
    success: jnp.ndarray
    score: jnp.ndarray
    peak: jnp.ndarray
    min_clear: jnp.ndarray
    min_self: jnp.ndarray
    final_error: jnp.ndarray


def span(task: EpisodeTask, decision_interval_s: float, motion_time_s: float) -> int:
    """Decisions a residual schedule's knots spread over (:meth:`~ffsr_gym.tasks.schedule.Schedule.span`)."""
    decisions = -(-task.n_steps // task.steps_per_decision)
    return min(decisions, math.ceil(motion_time_s / decision_interval_s - 1e-9))


def schedule_actions(knots: jnp.ndarray, decisions: int, spread: int | jnp.ndarray) -> jnp.ndarray:
    """(decisions, width) actions of (K, width) ``knots``: linear in the decision index over the first ``spread``
    decisions, held after, clipped to [-1, 1]. ``spread`` may be traced (one compilation for every spread)."""
    at = jnp.minimum(jnp.arange(decisions), spread - 1).astype(jnp.float64)
    k = knots.shape[0]
    where = jnp.linspace(0.0, spread - 1.0, k) if k > 1 else jnp.zeros(1)
    columns = [jnp.interp(at, where, knots[:, j]) for j in range(knots.shape[1])]
    return jnp.clip(jnp.stack(columns, axis=1), -1.0, 1.0)


def episode(model: Any, shapes: Any, rules: Any, task: EpisodeTask, knots: jnp.ndarray,
            spread: int | jnp.ndarray) -> Played:
    """Play the residual schedule ``knots`` on ``task`` to the episode's end."""
    decisions = -(-task.n_steps // task.steps_per_decision)
    actions = schedule_actions(knots, decisions, spread)
    state, seen = reset(model, shapes, rules, task)

    def decide(carry, action):
        state, error, success, score = carry
        state, seen, _, info = step(model, shapes, rules, task, state, action)
        return (state, jnp.linalg.norm(seen.ee_error[:3]), info["success"], info["score"]), None

    start = (state, jnp.linalg.norm(seen.ee_error[:3]), jnp.zeros((), bool), jnp.zeros(()))
    (state, error, success, score), _ = jax.lax.scan(decide, start, actions)
    return Played(state.cost, success, score, jnp.max(state.peak), state.min_clear, state.min_self, error)


def descend(cost_and_grad: Callable[[jnp.ndarray], tuple[Any, jnp.ndarray]], knots: jnp.ndarray, *, steps: int,
            rate: float, accept: Callable[[Any], bool], stop: Callable[[], bool] | None = None,
            min_rate: float = 0.0) -> tuple[jnp.ndarray, list]:
    """A projected gradient descent on C over the knots, kept in [-1, 1]: a step is taken only when the episode it
    leads to still succeeds with margins (``accept(played)``) and lowers C; otherwise the step size halves.
    ``cost_and_grad(knots) -> (played, gradient)``; at most ``steps`` steps, fewer when ``stop()`` turns true (read
    after each) or the step size falls below ``min_rate``. Returns the best knots and the history of (C, step size)."""
    played, gradient = cost_and_grad(knots)
    history = [(float(played.cost), rate)]
    for _ in range(steps):
        if (stop is not None and stop()) or rate < min_rate:
            break
        trial = jnp.clip(knots - rate * gradient, -1.0, 1.0)
        trial_played, trial_gradient = cost_and_grad(trial)
        if bool(accept(trial_played)) and float(trial_played.cost) < float(played.cost):
            knots, played, gradient = trial, trial_played, trial_gradient
            rate *= 1.5
        else:
            rate *= 0.5
        history.append((float(played.cost), rate))
    return knots, history
