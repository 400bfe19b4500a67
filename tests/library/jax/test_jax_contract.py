"""The JAX envs meet the kernel envs' input contract: the same inputs get the same named errors, side by side (seeds,
reset options, actions, a closed env), and the JAX-only inputs (``residual``, a pool's indices, a Brax action's size)
are refused by name. The JAX vector env needs only the ``jax`` extra: it imports nothing of Brax."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("jax")

import gymnasium  # noqa: E402

import ffsr_gym  # noqa: E402, F401 - registers the ids
from ffsr_gym.exceptions import InvalidInputError  # noqa: E402
from ffsr_gym.jax.pool_env import PoolEnv  # noqa: E402
from ffsr_gym.jax.vector import FFSRJaxVectorEnv  # noqa: E402

N = 2
BAD_SEEDS = ["42", -1, 1.7, True, [0], [0, "1"]]
BAD_OPTIONS = [{"bogus": 1}, {"task_index": [0]}, {"task_index": 0}, {"reset_mask": [True, True]},
               {"reset_mask": np.zeros(N, bool)}, ["task_index"]]
BAD_ACTIONS = ["abc", np.ones((N, 12), bool), np.zeros((N, 3)), np.zeros(12), np.full((N, 12), np.nan), None]


def _error(call) -> str:
    with pytest.raises(InvalidInputError) as caught:
        call()
    return str(caught.value)


@pytest.fixture(scope="module")
def pair():
    jax_env = FFSRJaxVectorEnv(N, task="easy", split="train")
    kernel_env = gymnasium.make_vec("FFSR-Residual-v2", num_envs=N, vectorization_mode="vector_entry_point",
                                    task="easy", split="train")
    yield jax_env, kernel_env
    jax_env.close()
    kernel_env.close()


def test_the_same_bad_reset_gets_the_same_error(pair):
    jax_env, kernel_env = pair
    for seed in BAD_SEEDS:
        assert _error(lambda: jax_env.reset(seed=seed)) == _error(lambda: kernel_env.reset(seed=seed)), seed
    for options in BAD_OPTIONS:
        assert _error(lambda: jax_env.reset(options=options)) == _error(lambda: kernel_env.reset(options=options)), \
            options


def test_the_same_bad_action_gets_the_same_error(pair):
    jax_env, kernel_env = pair
    jax_env.reset(seed=0)
    kernel_env.reset(seed=0)
    for actions in BAD_ACTIONS:
        assert _error(lambda: jax_env.step(actions)) == _error(lambda: kernel_env.step(actions)), actions


def test_task_index_and_reset_mask_are_honoured(pair):
    jax_env, _ = pair
    _, info = jax_env.reset(seed=0, options={"task_index": [3, 5]})
    assert list(info["task_index"]) == [3, 5]
    _, info = jax_env.reset(options={"task_index": [7, 9], "reset_mask": np.array([False, True])})
    assert info["task_index"][1] == 9 and list(info["_task_index"]) == [False, True]  # only the reset copy reports
    with pytest.raises(InvalidInputError, match=r"allowed: integers in \[0, 199\]"):
        jax_env.reset(options={"task_index": [0, -1]})


def test_the_jax_only_inputs_are_refused_by_name():
    with pytest.raises(InvalidInputError, match="residual = 'no'; allowed: True or False"):
        PoolEnv("easy", "train", residual="no")
    with pytest.raises(InvalidInputError, match=r"indices = \[-1\]"):
        PoolEnv("easy", "train", indices=[-1])
    with pytest.raises(InvalidInputError, match="allowed on the JAX loop"):
        PoolEnv("servo", "train")
    env = PoolEnv("easy", "train", indices=[0])
    import jax

    state = jax.eval_shape(env.reset, jax.random.PRNGKey(0))  # traced, not run: the check is at trace time
    with pytest.raises(InvalidInputError, match=r"action of shape \(\); allowed: \(12,\)"):
        jax.eval_shape(env.step, state, jax.numpy.asarray(0.5))  # never spread over the joints
    assert jax.eval_shape(env.step, state, jax.numpy.zeros(12)).obs.shape == (53,)


def test_a_closed_jax_vector_env_refuses_to_step_or_reset():
    env = FFSRJaxVectorEnv(1, task="easy", split="train")
    env.close()
    with pytest.raises(InvalidInputError, match="closed"):
        env.reset(seed=0)


def test_the_jax_vector_env_imports_nothing_of_brax():
    code = ("import sys; import ffsr_gym.jax.vector; "
            "assert not [m for m in sys.modules if m == 'brax' or m.startswith('brax.')], 'brax imported'")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
