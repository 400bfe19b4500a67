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


@pytest.mark.slow
def test_brax_wrappers_step_the_env_without_retracing():
    from brax.envs.wrappers.training import wrap

    env = wrap(FFSRBraxEnv("easy", "train", indices=[0, 1, 2]), episode_length=200)
    state = jax.jit(env.reset)(jax.random.split(jax.random.PRNGKey(0), 3))
    step = jax.jit(env.step)
    for _ in range(3):
        state = step(state, jnp.zeros((3, 12), dtype=jnp.float32))
    assert step._cache_size() == 1
    assert state.obs.shape == (3, 53) and np.all(np.isfinite(np.asarray(state.reward)))


@pytest.mark.parametrize("decisions", [pytest.param(200, marks=pytest.mark.slow), 25])
def test_the_vector_env_plays_what_the_kernel_env_plays(decisions):
    """Its spaces, info contract, observations and rewards against ``FFSR-Residual-v2`` on the same tasks: the first
    25 decisions; with ``-m slow`` whole episodes, whose rewards sum to the score minus 1."""
    env = FFSRJaxVectorEnv(2, task="easy", split="test")
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    assert {k for k in info if not k.startswith("_")} == set(info_dtypes(env.rule))
    indices, returns, scores, rewards, seen = info["task_index"].copy(), np.zeros(2), None, [], [obs.copy()]
    for _ in range(decisions):
        obs, reward, terminated, truncated, info = env.step(np.zeros((2, 12), np.float32))
        returns += reward
        rewards.append(reward)
        seen.append(obs.copy())
        assert all(np.asarray(info[key]).dtype == dtype for key, dtype in info_dtypes(env.rule).items())
        if np.any(terminated | truncated):
            assert np.all(truncated) and not np.any(terminated)
            scores = info["score"].copy()
            break
    for copy, index in enumerate(indices):
        with gymnasium.make("FFSR-Residual-v2", task="easy", split="test") as kernel_env:
            kernel_obs, _ = kernel_env.reset(options={"task_index": int(index)})
            np.testing.assert_allclose(seen[0][copy], kernel_obs, rtol=0, atol=2e-6)
            for k in range(decisions):
                kernel_obs, kernel_reward, _, _, kernel_info = kernel_env.step(np.zeros(12, np.float32))
                if k < 25:  # before the end's chatter: the same numbers
                    assert rewards[k][copy] == pytest.approx(kernel_reward, rel=1e-9, abs=1e-13)
                    np.testing.assert_allclose(seen[k + 1][copy], kernel_obs, rtol=0, atol=2e-6)
        if scores is not None:
            assert kernel_info["success"] and scores[copy] == pytest.approx(kernel_info["score"], rel=2e-3)
            assert returns[copy] == pytest.approx(scores[copy] - 1.0, abs=1e-12)
    with pytest.raises(InvalidInputError, match="finite"):
        env.step(np.full((2, 12), np.nan))


@pytest.mark.slow
def test_brax_ppo_trains_on_the_env_without_adapter_code():
    """``brax.training.agents.ppo.train`` on the environment as it is: a few thousand steps, evaluated by Brax on
    its own, whose episode reward is the score minus 1 (the rewards' sum, by construction)."""
    from brax.training.agents.ppo import train as ppo

    seen = []
    ppo.train(environment=FFSRBraxEnv("easy", "train", indices=list(range(8))), num_timesteps=4096,
              episode_length=200, num_envs=16, batch_size=16, unroll_length=16, num_minibatches=2,
              num_updates_per_batch=2, num_evals=2, seed=0, normalize_observations=True, num_eval_envs=8,
              progress_fn=lambda steps, metrics: seen.append(dict(metrics)))
    assert len(seen) == 2
    for metrics in seen:
        assert float(metrics["eval/episode_reward"]) == pytest.approx(float(metrics["eval/episode_score"]) - 1.0,
                                                                       abs=1e-6)
        assert float(metrics["eval/episode_success"]) == 1.0  # near-zero residuals keep the planner's successes
