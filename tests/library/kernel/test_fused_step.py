"""The native v2 decision (``ffsr_gym._native.Episode.decide``) against the step-by-step path it replaces.

The single v2 env steps through one compiled call on the kernel backend. With its episode
switched off (``env.unwrapped.compiled_step = False``) the same env goes through the
:class:`~ffsr_gym.sim.rollout.Rollout` interface: physics by ``advance``, the increment from
``scoring.score``, the observation assembled in Python. Both must give the same numbers bit for
bit, also when the planner step of the observation is reused by the next decision and when
(m, T_c) changes between decisions. The parts are also checked against independent numpy.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym  # noqa: F401  (registers the environments)
from ffsr_gym import _native
from ffsr_gym.environments.actions import OBS_CLIP, assemble_observation
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.versions.registry import load_benchmark

BENCH = load_benchmark("v2")


def episode(env_id, task, actions, *, compiled, seed=0, index=3, parameters=None, **kwargs):
    """Observations, rewards, ends and infos of one episode (or ``len(actions)`` decisions)."""
    env = gym.make(env_id, task=task, **kwargs)
    obs, _ = env.reset(seed=seed, options={"task_index": index})
    if not compiled:
        env.unwrapped.compiled_step = False
    out = [(obs,)]
    for action in actions:
        if parameters is not None:
            step = env.unwrapped.step_with_parameters(*parameters)
        else:
            step = env.step(action)
        out.append(step)
        if step[2] or step[3]:
            break
    return out


def assert_same(a, b):
    assert len(a) == len(b)
    np.testing.assert_array_equal(a[0][0], b[0][0])
    for (obs_a, r_a, te_a, tr_a, info_a), (obs_b, r_b, te_b, tr_b, info_b) in zip(a[1:], b[1:]):
        np.testing.assert_array_equal(obs_a, obs_b)
        assert obs_a.dtype == np.float32
        assert (r_a, te_a, tr_a) == (r_b, te_b, tr_b)
        assert list(info_a) == list(info_b)
        for key in info_a:
            assert info_a[key] == info_b[key] or (info_a[key] != info_a[key] and info_b[key] != info_b[key]), key


CASES = [("FFSR-Residual-v2", "easy", 0.4), ("FFSR-Residual-v2", "debris", 0.4), ("FFSR-Residual-v2", "robust", 0.4),
         ("FFSR-v2", "easy", 1.3), ("FFSR-v2", "hard", 1.0), ("FFSR-Residual-v2", "medium", 1.5)]


@pytest.mark.parametrize(("env_id", "task", "scale"), CASES)
def test_compiled_step_equals_the_step_by_step_path(env_id, task, scale):
    """Random actions (some clipped): same observations, rewards, ends and info, bit for bit, to the episode end."""
    size = 12 if "Residual" in env_id else 2
    rng = np.random.default_rng(7)
    actions = [(rng.uniform(-1, 1, size) * scale).astype(np.float32) for _ in range(200)]
    compiled = episode(env_id, task, actions, compiled=True)
    assert_same(compiled, episode(env_id, task, actions, compiled=False))
    assert compiled[-1][2] or compiled[-1][3]  # ran to the episode's end
    if scale > 1.0:
        assert compiled[-1][4]["clipped_actions"] > 0


def test_compiled_step_equals_the_step_by_step_path_in_the_other_modes():
    """Graded violations (no termination), dense shaping, float64 and list actions, ``step_with_parameters``."""
    rng = np.random.default_rng(3)
    actions = [rng.uniform(-1, 1, 12) * 2.0 for _ in range(200)]  # float64: the checks in Python
    for kwargs in ({"terminate_on_violation": False}, {"dense_shaping": True}):
        compiled = episode("FFSR-Residual-v2", "hard", actions, compiled=True, **kwargs)
        assert_same(compiled, episode("FFSR-Residual-v2", "hard", actions, compiled=False, **kwargs))
    lists = [list(map(float, a)) for a in actions[:30]]
    assert_same(episode("FFSR-Residual-v2", "easy", lists, compiled=True),
                episode("FFSR-Residual-v2", "easy", lists, compiled=False))
    fixed = [None] * 200
    assert_same(episode("FFSR-v2", "medium", fixed, compiled=True, parameters=(0.45, 5.0)),
                episode("FFSR-v2", "medium", fixed, compiled=False, parameters=(0.45, 5.0)))


def test_non_finite_action_raises_the_project_error_and_changes_nothing():
    env = gym.make("FFSR-Residual-v2", task="easy")
    env.reset(seed=0)
    before = env.unwrapped.rollout.x.copy()
    bad = np.zeros(12, dtype=np.float32)
    bad[4] = np.nan
    with pytest.raises(InvalidInputError, match=r"finite.*\[-1, 1\]"):
        env.step(bad)
    np.testing.assert_array_equal(env.unwrapped.rollout.x, before)
    assert env.unwrapped.rollout.k == 0
    env.step(np.zeros(12, dtype=np.float32))  # the episode goes on
    assert env.unwrapped.rollout.k == 10


def test_reference_backend_keeps_the_python_path_and_agrees():
    """``backend="pinocchio"`` has no compiled episode; its rewards agree with the kernel's to 1e-9."""
    actions = [np.full(12, 0.1, dtype=np.float32)] * 6
    reference = episode("FFSR-Residual-v2", "easy", actions, compiled=True, backend="pinocchio")
    kernel = episode("FFSR-Residual-v2", "easy", actions, compiled=True)
    for (obs_r, r_r, *_), (obs_k, r_k, *_) in zip(reference[1:], kernel[1:]):
        assert r_r == pytest.approx(r_k, rel=0, abs=1e-9)
        np.testing.assert_allclose(obs_r, obs_k, rtol=0, atol=1e-6)


def test_compiled_fade_is_the_benchmark_fade():
    motion, fade = 4.3, BENCH.action.residual_fade_s
    times = np.concatenate((np.linspace(0.0, 20.0, 2001), [motion - fade, motion, np.nextafter(motion - fade, 9.0)]))
    for t in times:
        assert _native.residual_fade(float(t), motion, fade) == BENCH.residual_fade(float(t), motion)


def test_observation_is_the_documented_layout():
    """The reference pipeline's assembly (which the native decision's observation equals bit for bit, above) against
    an independent numpy one, with entries beyond every clip bound and an infinite clearance."""
    rng = np.random.default_rng(5)
    angles, rates = rng.uniform(-7, 7, 12), rng.uniform(-40, 40, 12)
    ee, base, rel = rng.uniform(-20, 20, 6), rng.uniform(-20, 20, 6), rng.uniform(-20, 20, 3)
    twist = rng.uniform(-20, 20, 6)
    for clearance, fraction in ((math.inf, 0.5), (-12.0, 1.2), (0.03, 0.0)):
        obs = assemble_observation(angles, rates, ee, base, rel, clearance, fraction)
        longer = assemble_observation(angles, rates, ee, base, rel, clearance, fraction, twist)
        expected = np.concatenate([np.sin(angles), np.cos(angles), np.clip(rates, -20, 20), np.clip(ee, -10, 10),
                                   np.clip(base, -10, 10), np.clip(rel, -10, 10), [np.clip(clearance, -10, 10)],
                                   [min(1.0, fraction)]]).astype(np.float32)
        np.testing.assert_array_equal(obs, expected)  # 53 floats: the twist is only in a capture spec's observation
        np.testing.assert_array_equal(longer, np.concatenate([expected, np.clip(twist, -10, 10).astype(np.float32)]))
    assert OBS_CLIP == {"rates": 20.0, "errors": 10.0, "relative": 10.0, "clearance": 10.0, "twist": 10.0}


def test_batched_step_with_parameters_equals_single_envs():
    """``step_with_parameters`` in the batch (mode: (m, T_c) already set) against single envs, to the end."""
    venv = gym.make_vec("FFSR-v2", num_envs=2, task="hard", vectorization_mode="vector_entry_point",
                           record_trajectories=True)
    singles = [gym.make("FFSR-v2", task="hard") for _ in range(2)]
    obs, _ = venv.reset(seed=4)
    np.testing.assert_array_equal(obs, np.stack([env.reset(seed=4 + i)[0] for i, env in enumerate(singles)]))
    done = [False, False]
    for _ in range(200):
        obs, rewards, terminated, truncated, info = venv.unwrapped.step_with_parameters(0.35, 6.0)
        for i, env in enumerate(singles):
            if done[i]:
                continue
            s_obs, s_reward, s_term, s_trunc, s_info = env.unwrapped.step_with_parameters(0.35, 6.0)
            np.testing.assert_array_equal(obs[i], s_obs)
            assert (rewards[i], terminated[i], truncated[i]) == (s_reward, s_term, s_trunc)
            done[i] = s_term or s_trunc
            if done[i]:
                assert info["score"][i] == s_info["score"]
                assert venv.unwrapped.trajectory(i).info["m"] == 0.35
        if all(done):
            break
    assert all(done)
