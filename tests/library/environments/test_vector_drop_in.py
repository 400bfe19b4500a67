"""The batched env is a drop-in Gymnasium 1.x vector env: the same seeds through ``SyncVectorEnv`` (single envs) and
the batched env give equal observations, rewards, ends and infos in all three autoreset modes, and Gymnasium's vector
wrappers run on it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import ffsr_gym  # noqa: F401 - registers the ids
from ffsr_gym.environments.vector_env import FFSRVectorEnv

MODES = [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED]


def _pair(mode):
    sync = gym.vector.SyncVectorEnv([lambda: gym.make("FFSR-v2", task="easy") for _ in range(3)], autoreset_mode=mode)
    return sync, FFSRVectorEnv(3, "v2", task="easy", autoreset_mode=mode)


def _same(a, b, where):
    if isinstance(a, tuple):
        assert isinstance(b, tuple) and len(a) == len(b), where
        for k, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{k}]")
    elif isinstance(a, dict):
        assert set(a) == set(b), (where, set(a) ^ set(b))
        for key in a:
            _same(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert a.shape == b.shape, where
        for k, (x, y) in enumerate(zip(a, b)):
            _same(x, y, f"{where}[{k}]")
    else:
        assert np.array_equal(np.asarray(a), np.asarray(b)), (where, a, b)
        assert np.asarray(a).dtype == np.asarray(b).dtype, (where, np.asarray(a).dtype, np.asarray(b).dtype)


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.value)
def test_sync_and_batched_agree_in_every_autoreset_mode(mode):
    sync, batched = _pair(mode)
    assert batched.autoreset_mode == mode == sync.autoreset_mode
    _same(sync.reset(seed=[0, 1, 2]), batched.reset(seed=[0, 1, 2]), "reset")
    rng = np.random.default_rng(0)
    ends = 0
    for step in range(450):
        actions = rng.uniform(-1.0, 1.0, (3, 2)).astype(np.float32)
        a, b = sync.step(actions), batched.step(actions)
        _same(a, b, f"step {step}")
        ended = a[2] | a[3]
        ends += int(ended.sum())
        if mode == AutoresetMode.DISABLED and ended.any():
            options = {"reset_mask": ended.copy()}
            _same(sync.reset(options=dict(options)), batched.reset(options=dict(options)), f"reset at {step}")
    assert ends >= 6


@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP], ids=lambda m: m.value)
def test_gymnasiums_vector_wrappers_run_on_the_batched_env(mode):
    from gymnasium.wrappers.vector import NormalizeReward, RecordEpisodeStatistics

    sync, batched = _pair(mode)
    wrapped = [NormalizeReward(RecordEpisodeStatistics(env)) for env in (sync, batched)]
    for env in wrapped:
        env.reset(seed=[0, 1, 2])
    rng = np.random.default_rng(1)
    episodes = 0
    for _ in range(300):
        actions = rng.uniform(-1.0, 1.0, (3, 2)).astype(np.float32)
        (_, ra, ta, ua, ia), (_, rb, tb, ub, ib) = (env.step(actions) for env in wrapped)
        assert np.array_equal(ra, rb) and np.array_equal(ta | ua, tb | ub)
        if "episode" in ia:
            assert np.array_equal(ia["episode"]["r"][ia["_episode"]], ib["episode"]["r"][ib["_episode"]])
            assert np.array_equal(ia["episode"]["l"][ia["_episode"]], ib["episode"]["l"][ib["_episode"]])
            episodes += int(ia["_episode"].sum())
    assert episodes >= 3
