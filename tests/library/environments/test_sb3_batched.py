"""stable-baselines3 on the batched kernel: the adapter plays what SB3's make_vec_env of single envs plays."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import torch
from gymnasium.vector import AutoresetMode
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env

from ffsr_gym.environments.sb3_vec_env import BatchedVecEnv
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.optim.rl import train, training_env

POOL = {"task": "easy", "split": "train"}


def _parameters(model) -> np.ndarray:
    return torch.nn.utils.parameters_to_vector(model.policy.parameters()).detach().numpy().copy()


@pytest.mark.parametrize("env_id", ["FFSR-v2", "FFSR-Residual-v2"])
def test_one_ppo_update_on_the_adapter_equals_one_on_single_envs(env_id):
    torch.set_num_threads(1)
    models = []
    for env in (make_vec_env(env_id, n_envs=2, seed=3, env_kwargs=POOL), BatchedVecEnv(env_id, 2, **POOL)):
        model = PPO("MlpPolicy", env, n_steps=256, batch_size=128, n_epochs=2, seed=3, device="cpu")
        before = _parameters(model)
        model.learn(512)
        assert not np.array_equal(before, _parameters(model))  # it did update
        models.append(model)
    single, batched = (m.rollout_buffer for m in models)
    assert single.episode_starts[1:].any()  # an episode ended inside the update: autoreset was exercised
    for name in ("observations", "actions", "rewards", "episode_starts", "values", "log_probs", "advantages"):
        assert np.array_equal(getattr(single, name), getattr(batched, name)), name
    assert np.array_equal(_parameters(models[0]), _parameters(models[1]))


def test_the_adapter_reports_ends_as_sb3_single_envs_do():
    single, batched = make_vec_env("FFSR-v2", n_envs=3, seed=5, env_kwargs=POOL), BatchedVecEnv("FFSR-v2", 3, **POOL)
    for env in (single, batched):
        env.seed(5)
    obs = [single.reset(), batched.reset()]
    assert np.array_equal(*obs)
    rng, ends = np.random.default_rng(0), 0
    for _ in range(230):  # past the 200-decision truncation
        actions = rng.uniform(-1.2, 1.2, (3, 2)).astype(np.float32)
        single.step_async(actions)
        batched.step_async(actions)
        (o1, r1, d1, i1), (o2, r2, d2, i2) = single.step_wait(), batched.step_wait()
        assert np.array_equal(o1, o2) and np.array_equal(r1, r2) and np.array_equal(d1, d2)
        for a, b in zip(i1, i2):
            assert a["TimeLimit.truncated"] == b["TimeLimit.truncated"]
            if "terminal_observation" in a:
                ends += 1
                assert np.array_equal(a["terminal_observation"], b["terminal_observation"])
                assert (a["episode"]["l"], a["score"]) == (b["episode"]["l"], b["score"])
                assert a["episode"]["r"] == pytest.approx(b["episode"]["r"], abs=1e-6)  # Monitor sums in float32
    assert ends >= 3


def test_same_step_autoreset_reports_the_final_observation():
    venv = gym.make_vec("FFSR-v2", num_envs=2, vectorization_mode="vector_entry_point",
                        autoreset_mode=AutoresetMode.SAME_STEP, task="easy")
    reference = gym.make_vec("FFSR-v2", num_envs=2, vectorization_mode="vector_entry_point", task="easy")
    venv.reset(seed=0)
    reference.reset(seed=0)
    action = np.full((2, 2), 1.0, dtype=np.float32)
    for _ in range(200):
        obs, _, term, trunc, info = venv.step(action)
        ref_obs, _, ref_term, ref_trunc, ref_info = reference.step(action)
        assert np.array_equal(term, ref_term) and np.array_equal(trunc, ref_trunc)
        done = term | trunc
        if done.any():
            break
    assert done.any()
    for i in np.flatnonzero(done):
        assert np.array_equal(info["final_obs"][i], ref_obs[i]) and info["final_info"]["score"][i] == ref_info["score"][i]
    ref_obs, *_ = reference.step(action)  # next-step mode resets now: its reset observation is the same-step one
    assert np.array_equal(obs[done], ref_obs[done])


def test_train_uses_the_adapter_for_n_envs(tmp_path):
    _, record = train("ppo", "FFSR-Residual-v2", seed=0, out=tmp_path / "a", task="easy", timesteps=256, n_envs=2,
                      curve_every=10_000, curve_tasks=1, progress=False)
    assert (record["n_envs"], record["vec_env"]) == (2, "batched")
    assert json.loads((tmp_path / "a" / "train_record.json").read_text())["vec_env"] == "batched"
    with pytest.raises(InvalidInputError, match="vec_env"):
        training_env("FFSR-v2", 2, 0, POOL, "threads")
    with pytest.raises(InvalidInputError, match="n_envs"):
        training_env("FFSR-v2", 0, 0, POOL)


def test_the_old_module_name_warns_and_gives_the_same_class():
    import ffsr_gym.optim.sb3_vec_env as old

    with pytest.warns(DeprecationWarning, match="ffsr_gym.environments.sb3_vec_env"):
        assert old.BatchedVecEnv is BatchedVecEnv
    with pytest.raises(AttributeError, match="Nope"):
        old.Nope
