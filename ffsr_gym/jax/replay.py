"""Whole episodes of a pool's tasks in one compiled call: every task's certificate (or any constant action)
played by the JAX episode at once (``vmap`` over the tasks, ``lax.scan`` over the decisions).

This is how the JAX loop is checked against the kernel: the stored certificates of a tier's pool, replayed, must
give the stored verdicts and scores (``experiments/jax_agreement.py``).
"""

from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np

from ffsr_gym.jax.collision import shapes_of
from ffsr_gym.jax.episode import EpisodeTask, reset, stacked, step
from ffsr_gym.jax.physics import jax, jnp
from ffsr_gym.jax.scenario import episode_task
from ffsr_gym.model.obstacles import obstacle_field
from ffsr_gym.sim.setup import robot_assets
from ffsr_gym.tasks.splits import pool, task_scenario
from ffsr_gym.versions.registry import load_benchmark


def pool_tasks(tier: str, split: str, *, residual: bool = True, version: str = "v2",
               indices: list[int] | None = None, certificates: bool = False):
    """``(model, rules, tasks, records)``: a pool's tasks (or ``indices`` of it) as one stacked
    :class:`EpisodeTask` (obstacle rows padded to the pool's most), with the task's own (m, T_c), or with each
    certificate's; ``records``: the pool's task records (seed, certificate, stored score)."""
    benchmark = load_benchmark(version)
    chosen = list(pool(tier, split, version=version))
    chosen = chosen if indices is None else [chosen[i] for i in indices]
    scenarios = [task_scenario(tier, t.seed, benchmark) for t in chosen]
    most = max(len(obstacle_field(s)) for s in scenarios)
    built = [episode_task(s, residual=residual, version=version, obstacles=most,
                          **({"m": t.certificate.m, "T_c": t.certificate.T_c_s} if certificates else {}))
             for s, t in zip(scenarios, chosen)]
    return built[0][0], built[0][1], stacked([b[2] for b in built]), chosen


def certificate_tasks(tier: str, split: str = "test", *, version: str = "v2", indices: list[int] | None = None):
    """``(model, rules, tasks, actions, stored)`` of a pool's certificates: the stacked :class:`EpisodeTask` of
    each task with its certificate's (m, T_c), the certificate's residual action (zeros for a constant one, as
    float32 the environments see, in float64) and the stored certificate scores."""
    model, rules, tasks, chosen = pool_tasks(tier, split, version=version, indices=indices, certificates=True)
    actions = np.array([np.asarray(t.certificate.residual if t.certificate.residual is not None else np.zeros(12),
                                   dtype=np.float32) for t in chosen], dtype=np.float64)
    return model, rules, tasks, jnp.asarray(actions), np.array([t.certificate_score for t in chosen])


def _episode(model: Any, shapes: Any, rules: Any, task: EpisodeTask, action: jnp.ndarray) -> dict:
    """One task played to its end with a constant action."""
    state, _ = reset(model, shapes, rules, task)

    def decide(carry, _):
        state, score, success = carry
        state, _, _, info = step(model, shapes, rules, task, state, action)
        return (state, info["score"], info["success"]), None

    decisions = -(-task.n_steps // task.steps_per_decision)
    (state, score, success), _ = jax.lax.scan(decide, (state, jnp.zeros(()), jnp.zeros((), bool)), None,
                                              length=decisions)
    return {"score": score, "success": success, "status": state.status, "cost": state.cost, "peak": state.peak,
            "min_clear": state.min_clear, "min_self": state.min_self, "x": state.x, "k": state.k}


@partial(jax.jit, static_argnums=2)
def _play(model: Any, shapes: Any, rules: Any, tasks: EpisodeTask, actions: jnp.ndarray) -> dict:
    return jax.vmap(lambda task, action: _episode(model, shapes, rules, task, action))(tasks, actions)


def play(model: Any, rules: Any, tasks: EpisodeTask, actions: jnp.ndarray) -> dict[str, np.ndarray]:
    """Play every stacked task to its end with its constant action: score, success, status, smoothness cost,
    peak rates [deg/s], smallest clearances [m], the final state and step, one row per task. Compiled once per
    shape of the stack (obstacle rows, tasks) and planner rules."""
    out = _play(model, shapes_of(robot_assets("ffsr_dual_arm").kernel), rules, tasks, actions)
    return {key: np.asarray(value) for key, value in out.items()}


@partial(jax.jit, static_argnums=(2, 5))
def _play_policy(model: Any, shapes: Any, rules: Any, tasks: EpisodeTask, params: Any, act: Any) -> jnp.ndarray:
    def one(task):
        state, seen = reset(model, shapes, rules, task)

        def decide(carry, _):
            state, obs, score = carry
            state, seen, _, info = step(model, shapes, rules, task, state, act(params, obs).astype(jnp.float64))
            return (state, seen.obs, info["score"]), None

        decisions = -(-task.n_steps // task.steps_per_decision)
        (_, _, score), _ = jax.lax.scan(decide, (state, seen.obs, jnp.zeros(())), None, length=decisions)
        return score

    return jax.vmap(one)(tasks)


def play_policy(model: Any, rules: Any, tasks: EpisodeTask, params: Any, act: Any) -> np.ndarray:
    """Every stacked task's score under a JAX policy ``act(params, obs) -> action`` (deterministic; the same
    ``act`` object compiles once, whatever its ``params``): how a checkpoint is scored on a whole pool."""
    return np.asarray(_play_policy(model, shapes_of(robot_assets("ffsr_dual_arm").kernel), rules, tasks, params, act))
