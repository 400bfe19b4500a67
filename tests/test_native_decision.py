"""The native decision (C++, ``ffsr_gym._native.Episode.decide``) against the numba kernel's ``step_episode``: whole
episodes of random actions, the parameter box and the fading residual, every return, every observation and the
episode's logs to the bit, on paper, debris and a capture task (its 59-float observation); a NaN action does
nothing in both."""

from __future__ import annotations

import numpy as np
import pytest
from test_native_planner import _scenario

from ffsr_gym import _native
from ffsr_gym.kernel import decision
from ffsr_gym.native.planner import planner_settings
from ffsr_gym.native.robot import native_plant, native_robot
from ffsr_gym.sim.compiled import LOG_FIELDS, KernelRollout, settings_vectors
from ffsr_gym.sim.setup import prepare

DS = (np.radians(20.0), 2.0, 10.0, 0.05, 0.6, 1.0, 10.0, 200.0, 0.01, 0.35, 0.65, 1.0, 10.0)
DECISION_FIELDS = ("rate_scale", "fade_s", "motion_s", "m_lo", "m_hi", "T_lo", "T_hi", "rate_limit_deg_s",
                   "clear_scale", "alpha", "beta", "E_ref", "V_ref")


def _episodes(name: str):
    scenario = _scenario(name)
    setup, rollout = prepare(scenario), KernelRollout(scenario)
    mdl, n = rollout._mdl, scenario.n_steps
    fp, ip = settings_vectors(setup, method="predefined_time", m=0.3, T_c=4.0)
    logs = tuple(np.zeros((n, *shape)) for shape in LOG_FIELDS.values())
    numba_episode = decision.new_episode(mdl, rollout.plant, rollout.x.copy(), fp, ip, np.array(DS), logs,
                                         np.zeros(12))
    settings = _native.DecisionSettings()
    for field, value in zip(DECISION_FIELDS, DS):
        setattr(settings, field, value)
    robot = native_robot(mdl)
    native = _native.Episode(robot, planner_settings(setup, method="predefined_time", m=0.3, T_c=4.0), settings,
                             rollout.x.copy(), n, plant=native_plant(mdl, rollout.plant))
    return scenario, numba_episode, logs, native


@pytest.mark.parametrize("name, mode", [("paper", 1), ("v2/debris", 1), ("paper", 0), ("v2/servo", 0),
                                        ("capture-v0/fast", 0)])
def test_an_episode_of_decisions_is_the_numba_kernels_to_the_bit(name, mode):
    scenario, numba_episode, logs, native = _episodes(name)
    rng, n, width = np.random.default_rng(41), scenario.n_steps, 12 if mode == 0 else 2
    size = 59 if scenario.tumbling_target is not None else 53
    obs_numba, obs_native = np.zeros(size, np.float32), np.zeros(size, np.float32)
    k, decisions = 0, 0
    while k < n:
        action = rng.uniform(-1.2, 1.2, width).astype(np.float32)  # some clipped
        expected = decision.step_episode(numba_episode, action, mode, True, k, k, n, 10, obs_numba)
        got = native.decide(action.astype(np.float64), mode, True, k, 10, obs_native)
        assert got == tuple(expected), (k, got, expected)
        assert np.array_equal(obs_native, obs_numba), k
        k += expected[0]
        decisions += 1
        if expected[1] != 0:
            break
    assert decisions > 5
    native_logs = native.logs()
    for key, array in zip(LOG_FIELDS, logs):
        assert np.array_equal(native_logs[key][:k], array[:k]), key


def test_a_nan_action_does_nothing():
    scenario, numba_episode, _, native = _episodes("paper")
    obs = np.zeros(53, np.float32)
    bad = np.array([np.nan, 0.0], np.float32)
    assert native.decide(bad.astype(np.float64), 1, True, 0, 10, obs)[:2] == (0, 4)
    assert tuple(decision.step_episode(numba_episode, bad, 1, True, 0, 0, scenario.n_steps, 10, obs))[:2] == (0, 4)
    assert np.array_equal(native.state(), KernelRollout(scenario).x) and not obs.any()  # nothing moved


def _pool_episode(tier: str, index: int):
    from ffsr_gym.model.spec import spec_for_version
    from ffsr_gym.scoring.rules import score_rule
    from ffsr_gym.tasks.splits import pool, task_scenario

    scenario = task_scenario(tier, pool(tier, "test", version="v2")[index].seed,
                             score_rule(spec_for_version("v2")).benchmark)
    setup, rollout = prepare(scenario), KernelRollout(scenario)
    settings = _native.DecisionSettings()
    for field, value in zip(DECISION_FIELDS, DS):
        setattr(settings, field, value)
    robot = native_robot(rollout._mdl)
    episode = _native.Episode(robot, planner_settings(setup, method="predefined_time", m=0.3, T_c=4.0), settings,
                              rollout.x.copy(), scenario.n_steps, plant=native_plant(rollout._mdl, rollout.plant))
    return scenario, episode


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_a_batch_on_threads_is_each_episode_alone(threads):
    """Five tasks of three tiers (the servo plant among them) stepped together, one decision each per call, with
    some copies inactive at times: every return, observation and log equals the same episode stepped alone."""
    tasks = [("easy", 0), ("hard", 1), ("servo", 2), ("debris", 3), ("easy", 4)]
    batch_eps = [_pool_episode(tier, i)[1] for tier, i in tasks]
    alone = [_pool_episode(tier, i)[1] for tier, i in tasks]
    batch = _native.EpisodeBatch(batch_eps, threads)
    n, rng = len(tasks), np.random.default_rng(43)
    k, obs, out = np.zeros(n, np.int64), np.zeros((n, 53), np.float32), np.zeros((n, 7))
    k_alone, obs_alone = np.zeros(n, np.int64), np.zeros((n, 53), np.float32)
    finished = np.zeros(n, bool)
    for call in range(60):
        actions = rng.uniform(-1.0, 1.0, (n, 2))
        active = ~finished & (rng.uniform(size=n) > 0.2)
        batch.decide(actions, active, k, 1, 10, obs, out)
        for e in np.flatnonzero(active):
            got = alone[e].decide(actions[e].copy(), 1, True, int(k_alone[e]), 10, obs_alone[e])
            assert tuple(out[e]) == tuple(float(v) for v in got), (call, e)
            k_alone[e] += got[0]
            finished[e] = got[1] != 0 or k_alone[e] >= 200
        assert np.array_equal(k, k_alone) and np.array_equal(obs, obs_alone)
    for e in range(n):
        for key, value in batch_eps[e].logs().items():
            assert np.array_equal(value, alone[e].logs()[key]), (e, key)


def test_a_batch_refuses_a_wrong_buffer():
    _, episode = _pool_episode("easy", 0)
    batch = _native.EpisodeBatch([episode], 2)
    with pytest.raises(ValueError, match=r"out: shape \(1, 6\); allowed: \(1, 7\)"):
        batch.decide(np.zeros((1, 2)), np.ones(1, bool), np.zeros(1, np.int64), 1, 10, np.zeros((1, 53), np.float32),
                     np.zeros((1, 6)))
    with pytest.raises(ValueError, match="each episode once"):
        _native.EpisodeBatch([episode, episode], 1)
