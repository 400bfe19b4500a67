"""docs/envs.md's statements about the env's API (spaces, the action maps, the step's limits, keywords, v0's
arguments), each quoted from the page and checked against what ``gymnasium.make`` returns. The info table is
generated from the code (test_info_contract); the batched-env paragraph has test_docs_vector_env."""

from __future__ import annotations

import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym
from ffsr_gym.exceptions import InvalidInputError, UnknownArgumentError

PAGE = " ".join((Path(__file__).resolve().parents[3] / "docs" / "envs.md").read_text(encoding="utf-8").split())
PAPER = Path(__file__).resolve().parents[3] / "envs" / "scenarios" / "paper.toml"


def _make(env_id: str, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the frozen v0 ids say they are out of date
        return gym.make(env_id, **kwargs)


def _says(*sentences: str) -> None:
    for sentence in sentences:
        assert " ".join(sentence.split()) in PAGE, f"docs/envs.md no longer says: {sentence}"


@pytest.mark.parametrize("env_id, width", [("FFSR-v2", 2), ("FFSR-Residual-v2", 12), ("FFSR-v0", 2),
                                           ("FFSR-Residual-v0", 12)])
def test_the_spaces_are_the_ones_the_page_gives(env_id, width):
    _says(f"`Box(-1, 1, ({width},), float32)`", "`Box(float32, (53,))`")
    env = _make(env_id)
    try:
        assert env.action_space == gym.spaces.Box(-1.0, 1.0, (width,), np.float32)
        assert env.observation_space.shape == (53,) and env.observation_space.dtype == np.float32
        assert np.all(np.isfinite(env.observation_space.low)) and np.all(np.isfinite(env.observation_space.high))
        assert env.spec.max_episode_steps == 200
    finally:
        env.close()


def test_v2_maps_its_action_linearly_onto_the_box():
    _says("a₀ → m ∈ [0.05, 0.6], a₁ → T_c ∈ [1, 10] s, linear")
    env = _make("FFSR-v2")
    try:
        to_physical = env.unwrapped.action_to_parameters
        assert np.allclose(to_physical(np.array([-1.0, -1.0], np.float32)), (0.05, 1.0))
        assert np.allclose(to_physical(np.array([1.0, 1.0], np.float32)), (0.6, 10.0))
        assert np.allclose(to_physical(np.array([0.0, 0.5], np.float32)), (0.325, 7.75))  # midpoint, 3/4 of T_c's
    finally:
        env.close()


def test_v0_maps_its_action_onto_the_scenario_env_table():
    _says("with the scenario's `[env] m_bounds` (`env.unwrapped.scenario.env.m_bounds`; paper: [0.05, 0.95])",
          "with `[env] T_c_bounds_s` (paper: [0.5, 10] s)", "`[env] residual_rate_deg_s` (paper: ±20 deg/s)")
    env = _make("FFSR-v0")
    try:
        table = env.unwrapped.scenario.env
        assert tuple(table.m_bounds) == (0.05, 0.95) and tuple(table.T_c_bounds_s) == (0.5, 10.0)
        assert table.residual_rate_deg_s == 20.0
        to_physical = env.unwrapped.action_to_parameters
        assert np.allclose(to_physical(np.array([-1.0, 1.0], np.float32)), (0.05, 10.0))
        assert np.allclose(to_physical(np.array([0.0, -1.0], np.float32)), (0.5, 0.5))
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ["FFSR-v2", "FFSR-v0"])
def test_an_out_of_range_action_is_clipped_and_counted_a_bad_one_refused(env_id):
    _says("clipped, counted in `info[\"clipped_actions\"]`; NaN, inf or a wrong shape: `InvalidInputError` (a "
          "`ValueError`)")
    env = _make(env_id)
    try:
        env.reset(seed=0)
        _, _, _, _, info = env.step(np.array([-3.0, 0.5], np.float32))  # m at its lower end: a gentle step
        assert info["clipped_actions"] == 1
        _, _, _, _, info = env.step(np.array([0.0, 0.0], np.float32))
        assert info["clipped_actions"] == 1  # "so far this episode"
        for bad in (np.array([np.nan, 0.0], np.float32), np.array([np.inf, 0.0], np.float32),
                    np.zeros(3, np.float32)):
            with pytest.raises(InvalidInputError) as caught:
                env.step(bad)
            assert isinstance(caught.value, ValueError)
    finally:
        env.close()


def test_a_custom_task_takes_no_split_and_an_unknown_keyword_lists_the_allowed_ones():
    _says("`split` does not apply to it (an error if given)",
          "Any keyword an environment does not take is an error that lists the ones it does.")
    with pytest.raises(InvalidInputError, match="split"):
        _make("FFSR-v2", task=str(PAPER), split="test")
    with pytest.raises(UnknownArgumentError) as caught:
        _make("FFSR-v2", horizon=3)
    for allowed in ("dense_shaping", "dt_s", "split", "task", "terminate_on_violation"):
        assert allowed in str(caught.value)


@pytest.mark.parametrize("dt_s, fine", [(0.005, True), (0.0025, True), (0.03, False), (0.3, False)])
def test_dt_s_must_divide_the_decision_and_the_episode(dt_s, fine):
    _says("(0.1 s / dt_s and 20 s / dt_s must be whole numbers)")
    if fine:
        env = _make("FFSR-v2", dt_s=dt_s)
        assert env.unwrapped.steps_per_decision == round(0.1 / dt_s) and env.spec.max_episode_steps == 200
        env.close()
    else:
        with pytest.raises(InvalidInputError, match="dt_s"):
            _make("FFSR-v2", dt_s=dt_s)


def test_the_tiers_and_splits_are_the_ones_the_page_lists():
    _says("`task` in `easy` (default), `medium`, `hard`, `debris`, `robust`, `servo` and `split` in `train` "
          "(default), `validation`, `test`")
    env = _make("FFSR-v2")
    assert (env.unwrapped.task_name, env.unwrapped.split) == ("easy", "train")
    env.close()
    for tier in ("medium", "hard", "debris", "robust", "servo"):
        for split in ("validation", "test"):
            env = _make("FFSR-v2", task=tier, split=split)
            assert (env.unwrapped.task_name, env.unwrapped.split) == (tier, split)
            env.close()
    with pytest.raises(InvalidInputError):
        _make("FFSR-v2", task="easy", split="holdout")
    assert ffsr_gym.InvalidInputError is InvalidInputError
