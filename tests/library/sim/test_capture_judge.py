"""The native capture judge (docs/model.md §23): over a commanded approach's trajectory it says what the readable
judge (Pinocchio's kinematics, numpy's windows) says; an episode's judge, run as the episode runs, is the judge of
its recorded trajectory bit for bit, also across a pickled state; bad rules are refused by name."""

from __future__ import annotations

import numpy as np
import pytest
from test_timed_approach import _scenario

from ffsr_gym import _native
from ffsr_gym.kernel.planner import planner_settings
from ffsr_gym.scoring.capture import QUANTITIES, capture, episode_relative_motion, native_capture
from ffsr_gym.sim.compiled import initial_state
from ffsr_gym.sim.setup import prepare
from ffsr_gym.sim.simulate import make_rollout
from ffsr_gym.versions.registry import load_benchmark

RULE = load_benchmark("capture-v0").capture
BOUNDS = np.array([getattr(RULE, name) for name in QUANTITIES])


def _run(scenario, commands=((0, 2.0),)):
    rollout = make_rollout(scenario, backend="kernel", m=0.3, T_c=4.0)
    schedule = dict(commands)
    for k in range(0, scenario.n_steps, 10):
        if k in schedule:
            rollout.set_command(schedule[k])
        rollout.advance(10)
    rollout.finish()
    return rollout.trajectory()


def test_the_native_judge_says_what_the_readable_judge_says(tmp_path):
    scenario = _scenario(tmp_path, command=2.0)
    setup = prepare(scenario)
    traj = _run(scenario)
    relative = episode_relative_motion(setup, traj)
    readable = capture(traj.t, relative, RULE)
    native = native_capture(setup, traj, RULE)
    assert readable.captured and native.captured and native.time_s == readable.time_s
    # the readable judge's 2 acos(|σ_h · σ_e|) resolves small angles to ~1e-8 rad; the native one's atan2 form
    # to the last bits: the attitude ratio (bound 1 deg) agrees to 1e-6, the rest to 1e-7
    np.testing.assert_allclose(native.worst_ratio, readable.worst_ratio, rtol=1e-7, atol=1e-6)
    assert native.margin_ratio == pytest.approx(readable.margin_ratio, rel=1e-7)
    # the four quantities themselves, at samples along the approach, the insertion and the hold
    settings = planner_settings(setup, method="predefined_time", m=0.3, T_c=4.0)
    model = setup.assets.kernel
    for k in (0, 150, 600, 900, 1100, len(traj.t) - 1):
        x, v = np.zeros((k + 1, 19)), np.zeros((k + 1, 18))
        x[:, :7], x[:, 7:] = traj.q[:k + 1, :7], traj.q[:k + 1, model.q_index]
        v[:, :6], v[:, 6:] = traj.v[:k + 1, :6], traj.v[:k + 1, model.v_index]
        last = _native.capture_of(setup.assets.native, settings, x, v, BOUNDS, RULE.hold_s)["last"]
        np.testing.assert_allclose(last[[0, 2, 3]], relative[k, [0, 2, 3]], rtol=1e-9, atol=1e-12)
        assert abs(last[1] - relative[k, 1]) <= 3e-8  # acos's resolution near 1


def test_a_capture_missed_by_withdrawing_is_no_capture_in_either_judge(tmp_path):
    scenario = _scenario(tmp_path, command=1.0)  # held at the pre-grasp frame: 15 cm off, never captured
    setup = prepare(scenario)
    traj = _run(scenario, ((0, 1.0),))
    readable = capture(traj.t, episode_relative_motion(setup, traj), RULE)
    native = native_capture(setup, traj, RULE)
    assert not readable.captured and not native.captured
    assert native.margin_ratio == pytest.approx(readable.margin_ratio, rel=1e-7) and native.margin_ratio > 10


def _episode(setup, settings, timing):
    logs = {name: np.zeros((setup.scenario.n_steps + 1, width) if width else setup.scenario.n_steps + 1)
            for name, width in (("x", 19), ("v", 18), ("dq", 12), ("err", 4), ("clear", 0), ("self", 0), ("mu", 2),
                                ("cdf", 2), ("smin", 2), ("tau", 12))}
    episode = _native.Episode(setup.assets.native, settings, _native.DecisionSettings(),
                              initial_state(setup, setup.q0), setup.scenario.n_steps, logs=logs)
    episode.timing = timing
    episode.judge_capture(BOUNDS, RULE.hold_s)
    return episode, logs


def test_an_episodes_judge_is_its_trajectorys_judge_bit_for_bit_also_across_a_pickled_state(tmp_path):
    scenario = _scenario(tmp_path, command=1.0)
    setup = prepare(scenario)
    settings = planner_settings(setup, method="predefined_time", m=0.3, T_c=4.0)
    start = np.array(setup.path.state.values())
    episode, logs = _episode(setup, settings, start)
    obs, none = np.zeros(53, np.float32), np.zeros(12)
    k, saved = 0, None
    while k < scenario.n_steps:
        if k == 400:
            timing = episode.timing
            timing[0] = 2.0  # go in
            episode.timing = timing
        if k == 700:
            saved = (episode.state(), episode.timing, episode.capture_state, episode.last_rates, episode.totals, k)
        k += episode.decide(none, 2, False, k, 10, obs)[0]
    episode.finish(k)
    judged = episode.capture
    recorded = _native.capture_of(setup.assets.native, settings, logs["x"], logs["v"], BOUNDS, RULE.hold_s)
    assert judged["captured_at"] > 0 and judged["samples"] == scenario.n_steps + 1
    for key in ("samples", "captured_at", "margin"):
        assert judged[key] == recorded[key], key
    np.testing.assert_array_equal(judged["worst"], recorded["worst"])
    # a clone from the state saved at step 700 ends with the same judge
    x, timing, state, rates, totals, k = saved
    clone = _native.Episode(setup.assets.native, settings, _native.DecisionSettings(), x, scenario.n_steps)
    clone.timing, clone.capture_state, clone.last_rates, clone.totals = timing, state, rates, totals
    while k < scenario.n_steps:
        k += clone.decide(none, 2, False, k, 10, obs)[0]
    clone.finish(k)
    assert clone.capture["captured_at"] == judged["captured_at"] and clone.capture["margin"] == judged["margin"]
    np.testing.assert_array_equal(clone.capture["worst"], judged["worst"])


def test_bad_rules_are_refused_by_name(tmp_path):
    scenario = _scenario(tmp_path)
    setup = prepare(scenario)
    settings = planner_settings(setup, method="predefined_time", m=0.3, T_c=4.0)
    episode, _ = _episode(setup, settings, np.array(setup.path.state.values()))
    with pytest.raises(ValueError, match="bounds: allowed four finite numbers > 0"):
        episode.judge_capture(np.array([0.005, 0.0, 0.005, 0.01]), 1.0)
    with pytest.raises(ValueError, match=r"hold_s: allowed \[0, 600\] s"):
        episode.judge_capture(BOUNDS, -1.0)
    with pytest.raises(ValueError, match="capture_state: allowed a state read from capture_state"):
        episode.capture_state = np.zeros(5)
    plain = prepare(scenario.replace(commanded_approach=None))
    plain_settings = planner_settings(plain, method="predefined_time", m=0.3, T_c=4.0)
    with pytest.raises(ValueError, match="the capture judge needs a commanded approach"):
        _native.capture_of(plain.assets.native, plain_settings, np.zeros((2, 19)), np.zeros((2, 18)), BOUNDS, 1.0)
