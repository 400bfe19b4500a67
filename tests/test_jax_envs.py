"""The JAX loop behind Brax's ``Env`` interface and as a Gymnasium ``VectorEnv``: Brax's own training wrappers
step it without retracing; the vector env has the kernel env's spaces and info contract, its rewards sum to the
score minus 1, its episodes score what ``FFSR-Residual-v2`` scores on the same tasks, and a NaN action gets the
project's error."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("brax")

import gymnasium  # noqa: E402
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import ffsr_gym  # noqa: E402, F401
from ffsr_gym.environments.info import info_dtypes  # noqa: E402
from ffsr_gym.exceptions import InvalidInputError  # noqa: E402
from ffsr_gym.jax.brax_env import FFSRBraxEnv  # noqa: E402
from ffsr_gym.jax.vector import FFSRJaxVectorEnv  # noqa: E402


def test_brax_wrappers_step_the_env_without_retracing():
    from brax.envs.wrappers.training import wrap

    env = wrap(FFSRBraxEnv("easy", "train", indices=[0, 1, 2]), episode_length=200)
    state = jax.jit(env.reset)(jax.random.split(jax.random.PRNGKey(0), 3))
    step = jax.jit(env.step)
    for _ in range(3):
        state = step(state, jnp.zeros((3, 12), dtype=jnp.float32))
    assert step._cache_size() == 1
    assert state.obs.shape == (3, 53) and np.all(np.isfinite(np.asarray(state.reward)))


def test_the_vector_env_plays_what_the_kernel_env_plays():
    env = FFSRJaxVectorEnv(2, task="easy", split="test")
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    assert {k for k in info if not k.startswith("_")} == set(info_dtypes(env.rule))
    indices, returns, scores = info["task_index"].copy(), np.zeros(2), None
    for _ in range(200):
        obs, reward, terminated, truncated, info = env.step(np.zeros((2, 12), np.float32))
        returns += reward
        assert all(np.asarray(info[key]).dtype == dtype for key, dtype in info_dtypes(env.rule).items())
        if np.any(terminated | truncated):
            assert np.all(truncated) and not np.any(terminated)
            scores = info["score"].copy()
            break
    np.testing.assert_allclose(returns, scores - 1.0, atol=1e-12)
    for index, score in zip(indices, scores):
        with gymnasium.make("FFSR-Residual-v2", task="easy", split="test") as kernel_env:
            kernel_env.reset(options={"task_index": int(index)})
            ended = False
            while not ended:
                _, _, terminated, truncated, kernel_info = kernel_env.step(np.zeros(12, np.float32))
                ended = terminated or truncated
        assert kernel_info["success"] and score == pytest.approx(kernel_info["score"], rel=2e-3)
    with pytest.raises(InvalidInputError, match="finite"):
        env.step(np.full((2, 12), np.nan))
