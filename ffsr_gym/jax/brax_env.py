"""``FFSR-v2`` in JAX behind Brax's ``Env`` interface (``pip install "ffsr-gym[brax]"``), so that Brax's trainers
(``brax.training.agents.ppo.train``) train on a tier's pool without adapter code.

A reset draws a task of the pool uniformly from its key (the Gymnasium environments draw from numpy's generator
instead, so the two draw different task sequences); a step is one decision of :func:`ffsr_gym.jax.episode.step`.
``done`` is 1 at a violation and at the horizon: the last reward holds the episode's score, so nothing is left to
bootstrap from. ``metrics`` carry the score and success of finished episodes.

Brax 0.14's trainers call ``jax.device_put_replicated``, which JAX 0.10 removed (google/brax#671, open). Importing
this module puts a single-process replacement in its place when JAX lacks it (:func:`_replicated`): it stacks a
copy of the pytree per device, which is what Brax's trainers expect of it.
"""

from __future__ import annotations

from ffsr_gym.exceptions import MissingDependencyError
from ffsr_gym.jax.collision import shapes_of
from ffsr_gym.jax.episode import RESIDUAL, pick, reset, step
from ffsr_gym.jax.physics import jax, jnp
from ffsr_gym.jax.replay import pool_tasks
from ffsr_gym.sim.setup import robot_assets

try:
    from brax.envs.base import Env, State
except ImportError as exc:
    raise MissingDependencyError('ffsr_gym.jax.brax_env needs Brax: pip install "ffsr-gym[brax]"') from exc


def _replicated(tree, devices):
    """``jax.device_put_replicated`` as JAX < 0.10 had it: the pytree stacked once per device (leading axis)."""
    return jax.tree.map(lambda leaf: jax.device_put(jnp.stack([jnp.asarray(leaf)] * len(devices)), devices[0]), tree)


if not hasattr(jax, "device_put_replicated"):
    jax.device_put_replicated = _replicated


class FFSRBraxEnv(Env):
    """One tier's pool as a Brax environment.

    Args:
        tier: a kinematic tier of v2 (``easy``, ``medium``, ``hard``, ``debris``).
        split: the pool (``train`` to learn on; ``validation`` to pick checkpoints).
        residual: residual actions (12, ``FFSR-Residual-v2``), else (m, T_c) actions (2, ``FFSR-v2``).
        indices: only these tasks of the pool (default: all).
    """

    def __init__(self, tier: str = "easy", split: str = "train", *, residual: bool = True,
                 indices: list[int] | None = None) -> None:
        self.model, self.rules, self.tasks, self.records = pool_tasks(tier, split, residual=residual,
                                                                      indices=indices)
        self.shapes = shapes_of(robot_assets("ffsr_dual_arm").kernel)
        self.tier, self.split, self.n_tasks = tier, split, len(self.records)
        self._action_size = 12 if self.tasks.mode == RESIDUAL else 2
        self.decisions = -(-self.tasks.n_steps // self.tasks.steps_per_decision)

    def task(self, index):
        """Task ``index`` of the pool (an :class:`~ffsr_gym.jax.episode.EpisodeTask`)."""
        return pick(self.tasks, index)

    def reset(self, rng: jax.Array) -> State:
        index = jax.random.randint(rng, (), 0, self.n_tasks)
        state, seen = reset(self.model, self.shapes, self.rules, self.task(index))
        zero = jnp.zeros(())  # JAX's default float, as Brax's wrappers make theirs: no retrace between steps
        now = {"clearance_m": seen.clearance, "ee_position_error_m": jnp.linalg.norm(seen.ee_error[:3]),
               "smoothness_increment": zero, "cost": zero, "penalty": zero}
        return State(pipeline_state=state, obs=seen.obs, reward=zero, done=zero,
                     metrics={"score": zero, "success": zero}, info={"task_index": index, **now})

    def step(self, state: State, action: jax.Array) -> State:
        task = self.task(state.info["task_index"])
        moved, seen, reward, info = step(self.model, self.shapes, self.rules, task, state.pipeline_state,
                                         action.astype(jnp.float64))
        real = jnp.zeros(()).dtype
        metrics = {**state.metrics, "score": jnp.where(moved.done, info["score"], 0.0).astype(real),
                   "success": (moved.done & info["success"]).astype(real)}
        failed = moved.done & ~info["success"] & ~state.pipeline_state.done
        now = {"clearance_m": seen.clearance, "ee_position_error_m": jnp.linalg.norm(seen.ee_error[:3]),
               "smoothness_increment": info["smoothness_increment"], "cost": info["cost"],
               "penalty": jnp.where(failed, 1.0 / (1.0 + moved.cost), 0.0)}
        return state.replace(pipeline_state=moved, obs=seen.obs, reward=reward.astype(real),
                             done=moved.done.astype(real), metrics=metrics, info={**state.info, **now})

    @property
    def observation_size(self) -> int:
        return 59 if self.tasks.twist else 53

    @property
    def action_size(self) -> int:
        return self._action_size

    @property
    def backend(self) -> str:
        return "ffsr_gym.jax"
