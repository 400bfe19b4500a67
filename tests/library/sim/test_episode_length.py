"""One rule for an episode's length: a task's duration over its decision interval, whole numbers, on every path.

A 40 s custom task plays 400 decisions and gets one score through ``gymnasium.make``, ``evaluate``
(a callable), the batched env, SB3's ``make_vec_env`` and Gymnasium's ``make_vec``; a duration or
interval that is not whole numbers of steps is refused by name instead of being cut or stretched.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym
from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.model.resources import scenario_path
from ffsr_gym.model.scenario import load_scenario

ACTION = np.array([0.25, -0.4], dtype=np.float32)


def _custom(tmp_path, old: str, new: str) -> str:
    path = tmp_path / "long.toml"
    text = scenario_path("free_space").read_text()
    assert old in text
    path.write_text(text.replace(old, new).replace('name = "free_space"', 'name = "long"'))
    return str(path)


def _sb3_stepper(venv):
    """Copy 0's (done, score) of an SB3 VecEnv, one constant action at a time (reset first)."""
    venv.reset()

    def step():
        _, _, dones, infos = venv.step(ACTION[None])
        return bool(dones[0]), infos[0].get("score")
    return step


def _played(venv_step) -> tuple[int, float]:
    """(decisions, score) of copy 0 of a vector env, stepped until its first episode ends."""
    decisions = 0
    while True:
        decisions += 1
        done, score = venv_step()
        if done:
            return decisions, score


def test_a_40_s_custom_task_plays_400_decisions_and_one_score_on_every_path(tmp_path):
    task = _custom(tmp_path, "duration_s = 20.0", "duration_s = 40.0")
    env = gym.make("FFSR-v2", task=task)
    assert env.spec.max_episode_steps == 400
    env.reset(seed=0)
    decisions, done = 0, False
    while not done:
        _, _, terminated, truncated, info = env.step(ACTION)
        decisions, done = decisions + 1, terminated or truncated
    assert decisions == 400 and info["success"] and "score" in info
    scores = {"gymnasium.make": info["score"]}
    scores["evaluate"] = ffsr_gym.evaluate(lambda _obs: ACTION, "FFSR-v2", task=task, seeds=[0]).episodes[0]["score"]

    from stable_baselines3.common.env_util import make_vec_env

    from ffsr_gym.environments.sb3_vec_env import BatchedVecEnv

    batched = BatchedVecEnv("FFSR-v2", 1, task=task)
    batched.seed(0)
    for name, venv in (("BatchedVecEnv", batched), ("make_vec_env", make_vec_env("FFSR-v2", n_envs=1, seed=0,
                                                                                  env_kwargs={"task": task}))):
        steps, scores[name] = _played(_sb3_stepper(venv))
        assert steps == 400, name
    vector = gym.make_vec("FFSR-v2", num_envs=1, vectorization_mode="vector_entry_point", task=task)
    vector.reset(seed=0)

    def vector_step():
        _, _, terminated, truncated, infos = vector.step(ACTION[None])
        return bool(terminated[0] or truncated[0]), (float(infos["score"][0]) if "score" in infos else None)

    steps, scores["make_vec"] = _played(vector_step)
    assert steps == 400
    assert len(set(scores.values())) == 1 and scores["evaluate"] > 0, scores
    fixed = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task=task, seeds=[0]).episodes[0]
    assert fixed["success"] and fixed["score"] > 0  # played to its end: an incomplete episode scores 0


@pytest.mark.parametrize("old, new, key", [
    ("decision_interval_s = 0.1", "decision_interval_s = 0.015", "env.decision_interval_s"),
    ("duration_s = 20.0", "duration_s = 20.005", "simulation.duration_s"),
])
def test_a_duration_or_interval_of_no_whole_steps_is_refused_by_name(tmp_path, old, new, key):
    with pytest.raises(ScenarioError, match=f"'{key}' = .* is not a whole number of .*; allowed: a whole multiple"):
        load_scenario(_custom(tmp_path, old, new))


def test_a_custom_scenario_with_a_tier_or_split_is_refused(tmp_path, capsys):
    from ffsr_gym.cli.main import main

    task = _custom(tmp_path, "duration_s = 20.0", "duration_s = 20.0")
    argv = ["evaluate", "--env-id", "FFSR-v2", "--policy", "0.3,4", "--scenario", task, "--no-progress"]
    assert main([*argv, "--task", "hard", "--split", "train"]) == 2
    assert "--task hard and --split train with --scenario" in capsys.readouterr().err
    with pytest.raises(InvalidInputError):
        ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task=task, split="train")
