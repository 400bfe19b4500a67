"""One tier's pool as pure JAX functions of a state: the core the Brax environment and the Gymnasium vector env share,
with nothing of Brax (``pip install "ffsr-gym[jax]"`` is enough).

A reset draws a task of the pool uniformly from its key (:meth:`PoolEnv.reset`), or plays the task it is given
(:meth:`PoolEnv.reset_task`); a step is one decision of :func:`ffsr_gym.jax.episode.step`. ``done`` is 1 at a
violation and at the horizon: the last reward holds the episode's score. ``metrics`` carry the score and success of
finished episodes. The inputs meet the kernel environments' contract (the same errors for the same inputs): a tier and
split of v2's pools, indices inside the pool, ``residual`` a bool, and actions of the env's size.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.jax.collision import shapes_of
from ffsr_gym.jax.episode import RESIDUAL, pick, reset, step
from ffsr_gym.jax.physics import jax, jnp
from ffsr_gym.jax.replay import pool_tasks
from ffsr_gym.sim.setup import robot_assets
from ffsr_gym.tasks.splits import check_tier_split, pool

#: The tiers the JAX loop plays (kinematic plant, exact target, nominal inertials: robust and servo are the kernel's).
JAX_TIERS = ("easy", "medium", "hard", "debris")


class PoolState(NamedTuple):
    """One copy's state: the episode's (``pipeline_state``), what the policy sees, the last reward, whether it is done
    (1.0) and the metrics and info of the step (the fields of Brax's ``State``)."""

    pipeline_state: Any
    obs: Any
    reward: Any
    done: Any
    metrics: dict
    info: dict


def check_pool_inputs(tier: Any, split: Any, residual: Any, indices: Any) -> list[int] | None:
    """The checked ``indices`` (None: the whole pool); a named error for any input the kernel envs refuse.

    Raises:
        InvalidInputError: a tier or split v2 has no pool for on the JAX loop, ``residual`` not a bool, indices not a
            non-empty list of distinct integers inside the pool (each named, with what is allowed).
    """
    if not isinstance(tier, str) or tier not in JAX_TIERS:
        raise InvalidInputError(f"task {str(tier)[:40]!r}; allowed on the JAX loop: {list(JAX_TIERS)}")
    check_tier_split(tier, split, "v2")  # any split that is not one of v2's names, a string or not, is named
    if not isinstance(residual, bool):
        raise InvalidInputError(f"residual = {str(residual)[:40]!r}; allowed: True or False")
    if indices is None:
        return None
    size = len(pool(tier, split, version="v2"))
    if not isinstance(indices, (list, tuple, np.ndarray)) or len(indices) == 0 or not all(
            isinstance(i, (int, np.integer)) and not isinstance(i, bool) and 0 <= int(i) < size for i in indices) \
            or len(set(int(i) for i in indices)) != len(indices):
        raise InvalidInputError(f"indices = {str(indices)[:80]}; allowed: a non-empty list of distinct integers in "
                                f"[0, {size - 1}] ({tier}/{split} holds {size} tasks)")
    return [int(i) for i in indices]


class PoolEnv:
    """One tier's pool on the JAX loop.

    Args:
        tier: a kinematic tier of v2 (:data:`JAX_TIERS`).
        split: the pool (``train`` to learn on; ``validation`` to pick checkpoints).
        residual: residual actions (12, ``FFSR-Residual-v2``), else (m, T_c) actions (2, ``FFSR-v2``).
        indices: only these tasks of the pool (default: all).
    """

    def __init__(self, tier: str = "easy", split: str = "train", *, residual: bool = True,
                 indices: list[int] | None = None) -> None:
        indices = check_pool_inputs(tier, split, residual, indices)
        self.model, self.rules, self.tasks, self.records = pool_tasks(tier, split, residual=residual,
                                                                      indices=indices)
        self.shapes = shapes_of(robot_assets("ffsr_dual_arm").kernel)
        self.tier, self.split, self.n_tasks = tier, split, len(self.records)
        self.action_size = 12 if self.tasks.mode == RESIDUAL else 2
        self.observation_size = 59 if self.tasks.twist else 53
        self.decisions = -(-self.tasks.n_steps // self.tasks.steps_per_decision)

    def task(self, index: Any) -> Any:
        """Task ``index`` of the pool (an :class:`~ffsr_gym.jax.episode.EpisodeTask`)."""
        return pick(self.tasks, index)

    def reset(self, rng: jax.Array) -> PoolState:
        """A task drawn uniformly from ``rng``, at its start."""
        return self.reset_task(jax.random.randint(rng, (), 0, self.n_tasks))

    def reset_task(self, index: jax.Array) -> PoolState:
        """Task ``index`` of the pool (or of ``indices``), at its start."""
        state, seen = reset(self.model, self.shapes, self.rules, self.task(index))
        zero = jnp.zeros(())  # JAX's default float, as Brax's wrappers make theirs: no retrace between steps
        now = {"clearance_m": seen.clearance, "ee_position_error_m": jnp.linalg.norm(seen.ee_error[:3]),
               "smoothness_increment": zero, "cost": zero, "penalty": zero}
        return PoolState(pipeline_state=state, obs=seen.obs, reward=zero, done=zero,
                         metrics={"score": zero, "success": zero}, info={"task_index": index, **now})

    def step(self, state: PoolState, action: jax.Array) -> PoolState:
        """One decision with ``action`` (of :attr:`action_size`; its shape is checked when traced).

        Raises:
            InvalidInputError: an action of another shape (a scalar is never spread over the joints).
        """
        if tuple(jnp.shape(action)) != (self.action_size,):
            raise InvalidInputError(f"action of shape {tuple(jnp.shape(action))}; allowed: ({self.action_size},) "
                                    "finite numbers in [-1, 1]")
        task = self.task(state.info["task_index"])
        moved, seen, reward, info = step(self.model, self.shapes, self.rules, task, state.pipeline_state,
                                         jnp.asarray(action).astype(jnp.float64))
        real = jnp.zeros(()).dtype
        metrics = {**state.metrics, "score": jnp.where(moved.done, info["score"], 0.0).astype(real),
                   "success": (moved.done & info["success"]).astype(real)}
        failed = moved.done & ~info["success"] & ~state.pipeline_state.done
        now = {"clearance_m": seen.clearance, "ee_position_error_m": jnp.linalg.norm(seen.ee_error[:3]),
               "smoothness_increment": info["smoothness_increment"], "cost": info["cost"],
               "penalty": jnp.where(failed, 1.0 / (1.0 + moved.cost), 0.0)}
        return PoolState(pipeline_state=moved, obs=seen.obs, reward=reward.astype(real),
                         done=moved.done.astype(real), metrics=metrics, info={**state.info, **now})
