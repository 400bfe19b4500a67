"""One info contract: the same keys at reset, at every step and at the episode's end, one numeric dtype each, in the
single env, the batched env and Gymnasium's vector envs (what replay buffers such as tianshou's and torchrl's read)."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym
from ffsr_gym.environments.info import FAILURES, docs_section, failure_name, info_dtypes
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.provenance import splice_generated
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.versions.registry import spec_for_env_id

IDS = ["FFSR-v2", "FFSR-Residual-v2", "FFSR-v0", "FFSR-Residual-v0", "FFSR-Capture-Residual-v0"]
KINDS = {np.int64: int, np.float64: float, np.bool_: bool}


def _episode_infos(env, seed):
    _, info = env.reset(seed=seed)
    infos, done = [info], False
    while not done:
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        infos.append(info)
        done = terminated or truncated
    return infos


@pytest.mark.parametrize("env_id", IDS)
def test_every_info_has_every_key_with_its_dtype_from_reset_to_the_end(env_id):
    """A buffer-style consumer: stacks each key over the episode into an array of its dtype, and refuses a missing key,
    a None, a text or a NaN (tianshou's MalformedBufferError)."""
    env = gym.make(env_id)
    env.action_space.seed(0)
    dtypes = info_dtypes(score_rule(spec_for_env_id(env_id)))
    for seed in (0, 1):
        infos = _episode_infos(env, seed)
        for info in infos:
            assert list(info) == list(dtypes), env_id
            for key, value in info.items():
                assert type(value) is KINDS[dtypes[key]], (key, value)
        stacked = {key: np.array([info[key] for info in infos], dtype=dtype) for key, dtype in dtypes.items()}
        assert not any(np.isnan(values).any() for values in stacked.values() if values.dtype.kind == "f")
        assert stacked["episode_end"].tolist() == [False] * (len(infos) - 1) + [True]
    if "v0" not in env_id or "Capture" in env_id:  # a pool task
        assert failure_name(infos[-1]["failure"]) in FAILURES and infos[0]["task_index"] >= 0


def test_failure_codes_name_their_failures():
    assert [failure_name(code) for code in range(len(FAILURES))] == [None, "rate_limit", "collision", "final_error",
                                                                    "incomplete", "no_capture"]
    for bad in (-1, 6, "1", True, 1.0):
        with pytest.raises(InvalidInputError, match="failure code"):
            failure_name(bad)
    assert ffsr_gym.failure_name is failure_name


def test_the_docs_table_is_the_contract():
    text = (Path(__file__).resolve().parents[3] / "docs" / "envs.md").read_text(encoding="utf-8")
    assert splice_generated(text, "<!-- info-keys:begin -->", "<!-- info-keys:end -->", docs_section()) == text, \
        "run: ffsr-gym tasks tables --docs docs/envs.md"


@pytest.mark.parametrize("mode", ["vector_entry_point", "async"])
def test_vector_envs_carry_every_key_at_every_step(mode):
    """torchrl-style reads: every key of the contract at reset and at every step, through an episode's end and the
    autoreset after it, in the batched env and in Gymnasium's async vector env of the id."""
    env = gym.make_vec("FFSR-v2", num_envs=2, vectorization_mode=mode, task="easy")
    dtypes = info_dtypes(score_rule(spec_for_env_id("FFSR-v2")))
    _, info = env.reset(seed=[0, 1])
    ends = 0
    for _ in range(210):
        for key in dtypes:
            assert info[key].shape == (2,) and info[f"_{key}"].all(), key
            assert np.asarray(info[key]).dtype.kind == np.dtype(dtypes[key]).kind, key
        _, _, terminated, truncated, info = env.step(np.tile(np.array([0.2, -0.3], np.float32), (2, 1)))
        ends += int(np.sum(terminated | truncated))
    assert ends >= 2
    env.close()
