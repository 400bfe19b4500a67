"""The learned timing (``ffsr_gym.bench.learned_go``, ``baselines/learned_go.py``): its network reads as the closed
form it holds, and the score its threshold is tuned on, read off simulated data, is what the env plays."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import script_module

import ffsr_gym
from ffsr_gym.bench.capture_heuristic import TIME_INDEX
from ffsr_gym.bench.learned_go import LearnedGo, Regressor
from ffsr_gym.exceptions import InvalidInputError


def clock(width: int = 76) -> Regressor:
    """A one-layer network whose prediction is the episode's elapsed time [s] (60 s times the observed fraction)."""
    weight = np.zeros((width, 1))
    weight[TIME_INDEX, 0] = 60.0
    return Regressor(np.zeros(width), np.ones(width), (weight,), (np.zeros(1),))


def test_the_network_computes_its_closed_form():
    rng = np.random.default_rng(0)
    mean, scale = rng.normal(size=4), rng.uniform(0.5, 2.0, 4)
    w1, b1, w2, b2 = rng.normal(size=(4, 3)), rng.normal(size=3), rng.normal(size=(3, 1)), rng.normal(size=1)
    net = Regressor(mean, scale, (w1, w2), (b1, b2))
    x = rng.normal(size=(5, 4))
    expected = [float(np.maximum(((row - mean) / scale) @ w1 + b1, 0.0) @ w2[:, 0] + b2[0]) for row in x]
    assert net(x) == pytest.approx(expected, rel=1e-12)
    assert Regressor.from_dict(net.as_dict())(x) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("data", [
    {"mean": [0.0], "scale": [0.0], "weights": [[[1.0]]], "biases": [[0.0]]},
    {"mean": [0.0], "scale": [1.0], "weights": [[[1.0, 1.0]]], "biases": [[0.0, 0.0]]},
    {"mean": [0.0], "scale": [1.0]},
])
def test_a_malformed_network_is_refused_by_name(data):
    with pytest.raises(InvalidInputError, match="Regressor"):
        Regressor.from_dict(data)


def test_the_tuned_score_read_off_the_data_is_what_the_env_plays():
    """With a network that predicts the elapsed time, the policy goes in at the ``confirm``-th 0.5 s moment at or after
    the threshold [s]: the score ``offline_score`` reads off one validation task's simulated data must be the score of
    the episode ``ffsr_gym.evaluate`` plays with the policy (its own decisions, stepped through the env), up to the
    env action's float32 rounding of (m, T_c) (the data are simulated with (0.3, 4 s) exactly: 3e-7 relative)."""
    script = script_module("learned_go", "baselines")
    tier, index = "sweep", 7
    observations, scores = script.task_data(tier, "validation", index)
    assert observations.shape == (120, 76) and scores.shape == (120,)
    assert observations[:, TIME_INDEX] * 60.0 == pytest.approx(np.arange(120) * 0.5, abs=1e-4)
    best = float(np.argmax(scores)) * 0.5
    for threshold, confirm in ((best - 0.2, 1), (3.0, 1), (best - 0.7, 2)):
        offline = script.offline_score(clock(), threshold, [(observations, scores)], 49.02, confirm)
        policy = LearnedGo(regressor=clock(), threshold=threshold, confirm=confirm)
        report = ffsr_gym.evaluate(policy, "FFSR-Capture-v1", task=tier, split="validation", indices=[index])
        assert report.episodes[0]["score"] == pytest.approx(offline, rel=1e-6, abs=0.0)
        assert report.episodes[0]["success"] == (offline > 0.0)
    assert scores.max() > 0.0
