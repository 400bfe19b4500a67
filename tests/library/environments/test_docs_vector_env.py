"""docs/envs.md's batched-env paragraph, statement by statement, against the code: each quoted sentence is in the
page, and the behaviour it states is what the batched env does."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path

import gymnasium as gym
import numpy as np

import ffsr_gym  # noqa: F401 - registers the ids

PAGE = " ".join((Path(__file__).resolve().parents[3] / "docs" / "envs.md").read_text(encoding="utf-8").split())
N = 2


@contextmanager
def _make(mode: str):
    envs = gym.make_vec("FFSR-v2", num_envs=N, vectorization_mode="vector_entry_point", task="easy", split="test",
                        autoreset_mode=mode)
    try:
        yield envs
    finally:
        envs.close()


def _to_the_end(envs, mode: str):
    """Step with (m, T_c) = the box's middle until some copy's episode ends; that step's returns."""
    action = np.zeros((N, 2), np.float32)
    for _ in range(10_000):
        out = envs.step(action)
        if np.any(out[2] | out[3]):
            return out
    raise AssertionError(f"no episode ended ({mode})")


def test_disabled_mode_holds_an_ended_copy_until_a_masked_reset():
    assert "a copy whose episode ended holds, neither stepped nor rewarded, until the next `reset()`" in PAGE
    assert 'or those of `options={"reset_mask": mask}` (a numpy bool array, one entry per copy' in PAGE
    with _make("Disabled") as envs:
        envs.reset(seed=0, options={"task_index": [0, 0]})
        _, _, terminated, truncated, _ = _to_the_end(envs, "Disabled")
        ended = terminated | truncated
        assert ended.all()  # the same task and actions: both end together
        _, reward, terminated, truncated, _ = envs.step(np.zeros((N, 2), np.float32))
        assert np.all(reward == 0.0) and not np.any(terminated | truncated)  # held, not stepped or rewarded
        mask = np.array([True, False])
        _, info = envs.reset(options={"reset_mask": mask, "task_index": [1, 1]})
        assert list(info["_task_index"]) == [True, False] and info["task_index"][0] == 1
        _, reward, _, _, _ = envs.step(np.zeros((N, 2), np.float32))
        assert reward[1] == 0.0  # the copy left out of the mask still holds


def test_same_step_mode_puts_the_ended_episode_in_final_info():
    assert "`info[\"final_obs\"]` (an object array, masked by `_final_obs`)" in PAGE
    assert "`info[\"final_info\"]` (a dict of arrays with their `_key` masks, masked by `_final_info`" in PAGE
    assert "the ended episode's `score` is in `info[\"final_info\"][\"score\"]`, not in the step's own info" in PAGE
    with _make("SameStep") as envs, _make("NextStep") as reference:
        envs.reset(seed=0, options={"task_index": [0, 1]})
        reference.reset(seed=0, options={"task_index": [0, 1]})
        obs, _, terminated, truncated, info = _to_the_end(envs, "SameStep")
        _, _, ref_terminated, ref_truncated, ref_info = _to_the_end(reference, "NextStep")
        ended = terminated | truncated
        assert np.array_equal(ended, ref_terminated | ref_truncated)
        assert info["final_obs"].dtype == object and np.array_equal(info["_final_obs"], ended)
        final = info["final_info"]
        assert isinstance(final, dict) and np.array_equal(info["_final_info"], ended)
        assert np.array_equal(final["_score"], ended)
        assert np.array_equal(final["score"][ended], ref_info["score"][ended])  # the ended episode's score
        assert np.all(info["score"][ended] == 0.0)  # the step's own info belongs to the new episode
        assert np.any(final["score"][ended] > 0.0)
