"""What a leaderboard must not be fooled by: cut-short episodes, protocol-changing arguments, tampered entries.

Each test fails with its guard removed (checked once per guard when it was written).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym
from ffsr_gym.exceptions import InvalidInputError

INDICES = [0, 1, 2, 3]


def zero_policy(_obs):
    return np.zeros(2, dtype=np.float32)


def test_a_cut_short_episode_never_outscores_the_full_one():
    full = ffsr_gym.evaluate(zero_policy, "FFSR-v1", task="easy", indices=INDICES)
    with pytest.raises(InvalidInputError, match="max_episode_steps.*protocol"):
        ffsr_gym.evaluate(zero_policy, "FFSR-v1", task="easy", indices=INDICES, env_kwargs={"max_episode_steps": 5})
    env = gym.make("FFSR-v1", task="easy", split="test", max_episode_steps=5)  # cut after 0.5 s
    rule = env.unwrapped.engine.rule
    for index, row in zip(INDICES, full.episodes):
        env.reset(seed=index, options={"task_index": index})
        done = False
        while not done:
            _, _, terminated, truncated, _ = env.step(zero_policy(None))
            done = terminated or truncated
        cut = rule.result(env.unwrapped.trajectory, env.unwrapped.scenario)  # the one scoring path
        assert cut.failure == "incomplete" and not cut.success and cut.score == 0.0 < row["score"]


def test_a_cut_short_v0_episode_is_infeasible():
    env = gym.make("FFSR-v0", max_episode_steps=3)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(np.zeros(2, dtype=np.float32))
        done = terminated or truncated
    terms = env.unwrapped.engine.rule.result(env.unwrapped.trajectory, env.unwrapped.scenario)
    assert not terms.feasible and terms.score == float("inf")
