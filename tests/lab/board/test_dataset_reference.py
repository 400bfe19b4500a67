"""A dataset's Minari metadata: its id in Minari's grammar, its reference returns from the frozen reference and the
lower reference (played here by hand), and ``minari.get_normalized_score`` against the leaderboard's normalised
column on the same episodes."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

from ffsr_gym.bench.policies import uniform_random_residual
from ffsr_gym.model.resources import envs_dir
from ffsr_gym_lab.board import normalise
from ffsr_gym_lab.publish.dataset import dataset_id, write_dataset

minari = pytest.importorskip("minari")
pytest.importorskip("h5py")


def test_ids_follow_minaris_grammar():
    from minari.dataset.minari_dataset import parse_dataset_id

    assert dataset_id("easy", "FFSR-Residual-v2") == "ffsr/easy/best-known-v0"
    parsed = parse_dataset_id(dataset_id("hard", "FFSR-v2", "validation"))
    assert parsed == ("ffsr/hard", "best-known-mtc-validation", 0)


def test_normalised_scores_of_a_dataset_equal_the_leaderboards_on_its_episodes(tmp_path):
    dataset = write_dataset("easy", "FFSR-Residual-v2", split="validation", root=tmp_path,
                            author="A. Tester", author_email="tester@example.org")
    meta = dataset.storage.metadata
    episodes = list(dataset.iterate_episodes())
    indices = [int(ep.infos["task_index"][0]) for ep in episodes]
    assert dataset.spec.dataset_id == "ffsr/easy/best-known-validation-v0" and len(indices) == 50
    assert meta["author"] == {"A. Tester"} and meta["author_email"] == {"tester@example.org"}
    assert "commit" in meta["code_permalink"] or "ffsr-gym" in meta["code_permalink"]
    assert json.loads(meta["eval_env_spec"])["kwargs"]["split"] == "test"

    # ref_max_score: the frozen reference file's scores of these tasks, read directly, minus 1
    frozen = json.loads((envs_dir() / "benchmark" / "v2_reference.json").read_text())["scores"]["easy"]["validation"]
    assert meta["ref_max_score"] == pytest.approx(np.mean([frozen[i] for i in indices]) - 1.0, abs=1e-12)
    # ref_min_score: the uniform random residual played by hand on the same tasks (a return is the sum of rewards)
    env = gym.make("FFSR-Residual-v2", task="easy", split="validation")
    returns = []
    for i in indices:
        obs, _ = env.reset(seed=0, options={"task_index": i})
        total, done = 0.0, False
        while not done:
            obs, reward, terminated, truncated, _ = env.step(uniform_random_residual(obs))
            total, done = total + reward, terminated or truncated
        returns.append(total)
    assert meta["ref_min_score"] == pytest.approx(np.mean(returns), abs=1e-9)

    # the same episodes: Minari's normalised score of their mean return, and the leaderboard's column
    dataset_returns = np.array([ep.rewards.sum() for ep in episodes])
    theirs = float(minari.get_normalized_score(dataset, dataset_returns.mean()))
    entry = {"episodes": [{"task_index": i, "score": r + 1.0} for i, r in zip(indices, dataset_returns)],
             "extra": {"evaluation_pool": "easy/validation"}}
    ours = normalise.normalised_mean(entry, "v2")
    assert theirs == pytest.approx(ours, abs=1e-9) and ours == pytest.approx(1.0, abs=1e-9)
    # one affine map for the pool is not the per-task ratio: the random residual's episodes are 0 by Minari's map
    assert float(minari.get_normalized_score(dataset, np.mean(returns))) == pytest.approx(0.0, abs=1e-9)
