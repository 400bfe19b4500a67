"""Benchmark versions are data: a spec file written here becomes a version with no new module.

The version is registered from ``tmp_path``, stepped, evaluated and rendered through the one code
path every shipped version uses; its score is checked against the score rule applied to the
trajectory by hand, and its table against the entry's rows.
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym
from ffsr_gym.environments.registration import unregister_spec
from ffsr_gym.exceptions import ScenarioError
from ffsr_gym.model.resources import envs_dir
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.scoring.score import score_episode
from ffsr_gym.versions.registry import all_specs, load_benchmark
from ffsr_gym_lab.board import leaderboard

SPEC = """
schema_version = 1
version = "v9"
description = "a test version: the v2 score on the free-space scenario, scored on two seeds"
status = "live"

[ids]
parameters = "FFSR-Test-v9"
residual = "FFSR-Test-Residual-v9"
max_episode_steps = 200

[score]
rule = "bounded_smoothness"
rules_file = "v2.toml"
text = "test score"

[actions]
boxes = "rules"
residual_fades = true

[reward]
kind = "score_change"
options = ["dense_shaping"]

[tasks]
kind = "scenario"
keyword = "scenario"
default = "free_space"

[evaluation]
protocol = "seeds"
default_task = "free_space"
parameters_seeds = [0, 2]
residual_seeds = [5, 7]

[leaderboard]
folder = "{version}/{env_id}"
ranking = "ci_separation"
title = "Benchmark v9"
ci = "score_iqm_ci95"
rate = "success_rate"
rate_column = "success"
marker = "leaderboard-v9"
"""


@pytest.fixture()
def version_v9(tmp_path):
    path = tmp_path / "spec_v9.toml"
    path.write_text(SPEC)
    spec = ffsr_gym.register_spec(path)
    yield spec
    unregister_spec("v9")


def test_a_spec_file_is_a_version_that_steps_evaluates_and_renders(version_v9, tmp_path):
    assert "FFSR-Test-v9" in gym.registry and "v9" in all_specs()
    env = gym.make("FFSR-Test-Residual-v9")
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs) and env.action_space.shape == (12,)
    rewards, done = [], False
    while not done:
        obs, reward, terminated, truncated, info = env.step(np.zeros(12, dtype=np.float32))
        rewards.append(reward)
        done = terminated or truncated
    # The v2 rule, applied by hand to the trajectory, and the rewards' sum (score minus 1).
    task = load_benchmark("v2").task(load_scenario("free_space"))
    expected = score_episode(env.unwrapped.trajectory, task, load_benchmark("v2"))
    assert info["score"] == expected.score and info["success"] == expected.success
    assert sum(rewards) == pytest.approx(expected.score - 1.0, abs=1e-12)

    report = ffsr_gym.evaluate((0.3, 4.0), "FFSR-Test-v9")
    assert [row["seed"] for row in report.episodes] == [0, 1]  # the spec's public seeds
    assert report.metrics["success_rate"] == np.mean([row["success"] for row in report.episodes])
    root = tmp_path / "board"
    root.mkdir()
    report.name = "planner_default"
    saved = report.save(root / version_v9.folder("FFSR-Test-v9", ""))
    assert saved.parent == root / "v9" / "FFSR-Test-v9"
    assert leaderboard.write_readme(root)
    text = (root / "README.md").read_text()
    start, end = version_v9.leaderboard.markers()
    table = text[text.index(start):text.index(end)]
    entry = json.loads(saved.read_text())
    assert "`planner_default`" in table and f"{entry['metrics']['score_iqm']:.3f}" in table
    recomputed = leaderboard.recompute(entry)
    assert recomputed.keys() == entry["metrics"].keys()
    for key, value in recomputed.items():
        assert np.allclose(entry["metrics"][key], value, rtol=1e-12), key


def test_a_malformed_spec_names_its_key(tmp_path):
    path = tmp_path / "spec_bad.toml"
    path.write_text(SPEC.replace('ranking = "ci_separation"', 'ranking = "by_vibes"'))
    with pytest.raises(ScenarioError, match=r"leaderboard.ranking.*by_vibes"):
        ffsr_gym.register_spec(path)
    taken = tmp_path / "spec_taken.toml"
    taken.write_text(SPEC.replace('parameters = "FFSR-Test-v9"', 'parameters = "FFSR-v2"'))
    with pytest.raises(ScenarioError, match="FFSR-v2"):
        ffsr_gym.register_spec(taken)
    assert not (envs_dir() / "benchmark" / "spec_v9.toml").exists()


def test_shipped_versions_are_registered_from_their_specs():
    for spec in all_specs().values():
        for env_id in spec.env_ids:
            assert gym.spec(env_id).kwargs["version"] == spec.version


@pytest.mark.parametrize(("retired", "live"), [("FFSR-v1", "FFSR-v2"), ("FFSR-Residual-v1", "FFSR-Residual-v2")])
def test_the_retired_v1_ids_name_v2_in_gymnasiums_own_error(retired, live):
    from gymnasium.error import DeprecatedEnv

    assert retired not in gym.registry and live in gym.registry
    with pytest.raises(DeprecatedEnv, match=f"Please use `{live}`"):
        gym.make(retired)
    assert "v1" not in all_specs()
    assert not (envs_dir() / "benchmark" / "v1.toml").exists()  # nothing of v1 stays runnable
