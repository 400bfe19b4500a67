"""A recurrent policy is scored with its state: ``evaluate`` gives sb3-contrib's RecurrentPPO its LSTM state and the
episode's start, as a hand-written stateful rollout does, and each episode starts afresh."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym

sb3_contrib = pytest.importorskip("sb3_contrib")


@pytest.fixture(scope="module")
def recurrent():
    env = gym.make("FFSR-Residual-v2", task="easy")
    model = sb3_contrib.RecurrentPPO("MlpLstmPolicy", env, n_steps=32, batch_size=32, n_epochs=1, seed=0,
                                     device="cpu", policy_kwargs={"lstm_hidden_size": 8, "net_arch": [8]})
    model.learn(64)
    return model


def _stateful_rollout(model, index: int) -> float:
    env = gym.make("FFSR-Residual-v2", task="easy", split="test")
    obs, _ = env.reset(seed=index, options={"task_index": index})
    state, start, done = None, True, False
    while not done:
        action, state = model.predict(obs, state=state, episode_start=np.array([start]), deterministic=True)
        start = False
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    return info["score"]


def test_a_recurrent_policy_is_scored_with_its_state(recurrent):
    rows = ffsr_gym.evaluate(recurrent, "FFSR-Residual-v2", task="easy", indices=[0, 1, 2]).episodes
    assert [row["score"] for row in rows] == [_stateful_rollout(recurrent, i) for i in (0, 1, 2)]
    stateless = ffsr_gym.evaluate(lambda obs: recurrent.predict(obs, deterministic=True)[0], "FFSR-Residual-v2",
                                  task="easy", indices=[0, 1, 2]).episodes
    traces_differ = [a["smoothness_cost"] != b["smoothness_cost"] for a, b in zip(rows, stateless)]
    assert any(traces_differ)  # the state matters: scoring it without is another policy


def test_the_entry_names_the_library_that_made_the_policy(recurrent):
    from importlib import metadata

    report = ffsr_gym.evaluate(recurrent, "FFSR-Residual-v2", task="easy", indices=[0])
    origin = report.provenance["policy"]
    assert origin["type"] == "sb3_contrib.ppo_recurrent.ppo_recurrent.RecurrentPPO"
    assert origin["package"].replace("_", "-").lower() == "sb3-contrib"  # the distribution, however it spells it
    assert origin["version"] == metadata.version("sb3-contrib")
    wrapped = ffsr_gym.evaluate(lambda obs: recurrent.predict(obs, deterministic=True)[0], "FFSR-Residual-v2",
                                task="easy", indices=[0], policy_library="tianshou 2.0.1")
    assert wrapped.provenance["policy"]["library"] == "tianshou 2.0.1"
    with pytest.raises(ffsr_gym.InvalidInputError, match="policy_library"):
        ffsr_gym.evaluate(lambda obs: obs[:12], "FFSR-Residual-v2", task="easy", indices=[0], policy_library="a\nb")
