"""``FFSR-v2`` in JAX behind Brax's ``Env`` interface (``pip install "ffsr-gym[brax]"``), so that Brax's trainers
(``brax.training.agents.ppo.train``) train on a tier's pool without adapter code.

The episode is :class:`ffsr_gym.jax.pool_env.PoolEnv`'s (Brax-free, shared with the Gymnasium vector env): a reset
draws a task of the pool uniformly from its key (the kernel environments draw from numpy's generator instead, so the
two draw different task sequences); a step is one decision. ``done`` is 1 at a violation and at the horizon: the
last reward holds the episode's score, so nothing is left to bootstrap from.

Brax 0.14's trainers call ``jax.device_put_replicated``, which JAX 0.10 removed (google/brax#671, open). Importing
this module puts a single-process replacement in its place when JAX lacks it (:func:`_replicated`): it stacks a
copy of the pytree per device, which is what Brax's trainers expect of it.
"""

from __future__ import annotations

from ffsr_gym.exceptions import MissingDependencyError
from ffsr_gym.jax.physics import jax, jnp
from ffsr_gym.jax.pool_env import PoolEnv, PoolState

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
    """One tier's pool as a Brax environment: :class:`~ffsr_gym.jax.pool_env.PoolEnv` behind Brax's ``Env``.

    Args:
        tier: a kinematic tier of v2 (``easy``, ``medium``, ``hard``, ``debris``).
        split: the pool (``train`` to learn on; ``validation`` to pick checkpoints).
        residual: residual actions (12, ``FFSR-Residual-v2``), else (m, T_c) actions (2, ``FFSR-v2``).
        indices: only these tasks of the pool (default: all).

    Raises:
        InvalidInputError: as :func:`~ffsr_gym.jax.pool_env.check_pool_inputs`; at a step, an action of another size.
    """

    def __init__(self, tier: str = "easy", split: str = "train", *, residual: bool = True,
                 indices: list[int] | None = None) -> None:
        self.core = PoolEnv(tier, split, residual=residual, indices=indices)
        self.model, self.rules, self.tasks, self.records = (self.core.model, self.core.rules, self.core.tasks,
                                                            self.core.records)
        self.shapes, self.tier, self.split, self.n_tasks = self.core.shapes, tier, split, self.core.n_tasks
        self.decisions = self.core.decisions

    def task(self, index):
        """Task ``index`` of the pool (an :class:`~ffsr_gym.jax.episode.EpisodeTask`)."""
        return self.core.task(index)

    def reset(self, rng: jax.Array) -> State:
        return State(**self.core.reset(rng)._asdict())

    def step(self, state: State, action: jax.Array) -> State:
        core = PoolState(state.pipeline_state, state.obs, state.reward, state.done, state.metrics, state.info)
        return state.replace(**self.core.step(core, action)._asdict())

    @property
    def observation_size(self) -> int:
        return self.core.observation_size

    @property
    def action_size(self) -> int:
        return self.core.action_size

    @property
    def backend(self) -> str:
        return "ffsr_gym.jax"
