"""The commanded approach (docs/model.md §23): the method's command moves the approach and the insertion within
their speed and acceleration limits and stops them on target; the desired pose is the start pose, the pre-grasp
frame and the grasp frame where it must be, and its twist is the derivative of its pose; the kernel computes the
same as the readable reference, step by step and over a closed loop whose commands change mid-run; bad commands
and settings are refused by name."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_moving_target import _tumbling_toml

from ffsr_gym import _native
from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.kernel.planner import planner_settings
from ffsr_gym.model import quaternion as quat
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.planning.timed_approach import ApproachLimits, TimingState, timed_desired
from ffsr_gym.sim.setup import prepare
from ffsr_gym.sim.simulate import make_rollout

LIMITS = ApproachLimits(standoff_m=0.15, approach_speed=1.0 / 6.0, approach_accel=1.0 / 9.0, insert_speed=0.5,
                        insert_accel=1.0)
APPROACH = "\n[commanded_approach]\napproach_time_s = 6.0\napproach_ramp_s = 1.5\ninsertion_time_s = 2.0\n" \
           "insertion_ramp_s = 0.5\ncommand = {command}\n"


def _scenario(tmp_path, command: float = 1.0, **changes):
    path = _tumbling_toml(tmp_path, standoff_m=0.15, danger_radius_m=0.1, **changes)
    with open(path, "a") as f:
        f.write(APPROACH.format(command=command))
    return load_scenario(path)


def _profile(command: float, steps: int, dt: float = 0.01, start: TimingState | None = None) -> np.ndarray:
    state = start or TimingState()
    state.set_command(command)
    rows = [state.values()]
    for _ in range(steps):
        state.advance(LIMITS, dt)
        rows.append(state.values())
    return np.array(rows)


def test_the_approach_and_the_insertion_take_their_trapezoids_time_and_stop_on_target():
    dt = 0.01
    rows = _profile(2.0, 1500, dt)
    s, s_dot, w, w_dot = rows[:, 1], rows[:, 2], rows[:, 3], rows[:, 4]
    arrived, inserted = int(np.argmax(s == 1.0)), int(np.argmax(w == 1.0))
    # a trapezoid over [0, 1] at top speed v and acceleration a takes 1/v + v/a: 7.5 s and 2.5 s here
    assert arrived * dt == pytest.approx(6.0 + 1.5, abs=2 * dt)
    assert (inserted - arrived) * dt == pytest.approx(2.0 + 0.5, abs=2 * dt)
    assert s_dot.max() == pytest.approx(LIMITS.approach_speed, rel=1e-12) and w_dot.max() == pytest.approx(0.5)
    # rates change by at most a dt a step (the last step onto the target by at most 2 a dt), never overshoot
    assert np.abs(np.diff(s_dot)).max() <= 2 * LIMITS.approach_accel * dt * (1 + 1e-12)
    assert np.abs(np.diff(w_dot)).max() <= 2 * LIMITS.insert_accel * dt * (1 + 1e-12)
    assert np.all(np.diff(s) >= 0.0) and s.max() == 1.0 and w.max() == 1.0
    assert np.all(w[:arrived + 1] == 0.0)  # the insertion waits for the arrival
    assert np.all(rows[-1, 1:] == [1.0, 0.0, 1.0, 0.0])


def test_a_command_below_one_withdraws_the_tool_before_the_approach_goes_back():
    dt = 0.01
    inserted = _profile(2.0, 1200, dt)[-1]
    state = TimingState(*inserted)
    rows = _profile(0.25, 1500, dt, start=state)
    s, w = rows[:, 1], rows[:, 3]
    out = int(np.argmax(w == 0.0))
    assert out > 0 and np.all(s[:out + 1] == 1.0)  # s holds at 1 until the tool is out
    assert np.all(np.diff(s[out:]) <= 0.0) and rows[-1, 1] == 0.25 and rows[-1, 2] == 0.0
    # a command reversed mid-approach: the rate turns within the acceleration limit
    mid = TimingState(*_profile(1.0, 300, dt)[-1])
    back = _profile(0.0, 600, dt, start=mid)
    assert np.abs(np.diff(back[:, 2])).max() <= 2 * LIMITS.approach_accel * dt * (1 + 1e-12)
    assert back[-1, 1] == 0.0 and back[-1, 2] == 0.0


def test_the_kernel_profile_is_the_reference_bit_for_bit(tmp_path):
    settings = planner_settings(prepare(_scenario(tmp_path)), method="predefined_time", m=0.3, T_c=4.0)
    rng = np.random.default_rng(3)
    state = TimingState()
    for command in rng.uniform(0.0, 2.0, 12):
        state.set_command(float(command))
        native = _native.timing_profile(settings, np.array(state.values()), 137)
        np.testing.assert_array_equal(native, _profile(float(command), 137, settings.dt, TimingState(*state.values())))
        state = TimingState(*native[-1])


def _pose_at(setup, state: TimingState, k: int):
    path = setup.path
    twist = path.twist[k]
    return timed_desired(path.limits, state, path.start_position, path.start_attitude, path.position_m[k],
                         path.attitude[k], twist)


def test_the_desired_pose_is_the_start_the_pre_grasp_and_the_grasp_frame_where_it_must_be(tmp_path):
    setup = prepare(_scenario(tmp_path))
    path, k = setup.path, 250
    p, q, twist = _pose_at(setup, TimingState(), k)
    np.testing.assert_allclose(p, path.start_position, atol=1e-15)
    assert min(np.abs(q - path.start_attitude).max(), np.abs(q + path.start_attitude).max()) < 1e-15
    np.testing.assert_allclose(twist, 0.0, atol=1e-15)
    grasp_p, grasp_q = path.position_m[k], path.attitude[k]
    axis = quat.to_rotation(grasp_q)[:, 2]
    p, q, twist = _pose_at(setup, TimingState(2.0, 1.0, 0.0, 0.0, 0.0), k)  # at the pre-grasp frame
    np.testing.assert_allclose(p, grasp_p - 0.15 * axis, atol=1e-15)
    np.testing.assert_array_equal(q, grasp_q)
    omega = path.twist[k, 3:]
    np.testing.assert_allclose(twist, np.r_[path.twist[k, :3] - 0.15 * np.cross(omega, axis), omega], atol=1e-15)
    p, q, twist = _pose_at(setup, TimingState(2.0, 1.0, 0.0, 1.0, 0.0), k)  # inserted: the grasp frame
    np.testing.assert_allclose(p, grasp_p, atol=1e-15)
    np.testing.assert_allclose(twist, path.twist[k], atol=1e-15)
    # s -> 1 from below: the attitude law meets the frame (no jump on arrival)
    p, q, twist = _pose_at(setup, TimingState(2.0, 1.0 - 1e-12, 0.0, 0.0, 0.0), k)
    assert min(np.abs(q - grasp_q).max(), np.abs(q + grasp_q).max()) < 1e-11


@pytest.mark.parametrize("state", [(2.0, 0.3, 0.12, 0.0, 0.0), (2.0, 0.8, -0.05, 0.0, 0.0),
                                   (2.0, 1.0, 0.0, 0.4, 0.3), (0.0, 1.0, 0.0, 0.6, -0.2)])
def test_the_desired_twist_is_the_derivative_of_the_desired_pose(tmp_path, state):
    """Central differences over ±1 step of the grasp frame's samples, s and w moving at their rates: second order,
    so within dt² of the twist."""
    setup = prepare(_scenario(tmp_path, omega_body_deg_s=[4.0, -6.0, 3.0]))
    dt, k = setup.scenario.simulation.dt_s, 300
    command, s, s_dot, w, w_dot = state

    def pose(step: int):
        h = (step - k) * dt
        return _pose_at(setup, TimingState(command, s + s_dot * h, s_dot, w + w_dot * h, w_dot), step)

    (p0, q0, _), (p1, q1, _), (_, _, twist) = pose(k - 1), pose(k + 1), pose(k)
    velocity = (p1 - p0) / (2 * dt)
    turn = quat.multiply(q1, quat.conjugate(q0))  # world frame: σ(t+dt) σ(t-dt)*
    omega = quat.rotation_vector(turn) / (2 * dt)
    np.testing.assert_allclose(velocity, twist[:3], atol=1e-6)
    np.testing.assert_allclose(omega, twist[3:], atol=1e-6)


def test_the_kernel_desired_pose_is_the_reference(tmp_path):
    scenario = _scenario(tmp_path, omega_body_deg_s=[4.0, -6.0, 3.0])
    setup = prepare(scenario)
    settings = planner_settings(setup, method="predefined_time", m=0.3, T_c=4.0)
    rng = np.random.default_rng(5)
    for _ in range(200):
        state = TimingState(rng.uniform(0, 2), float(rng.choice([rng.uniform(), 0.0, 1.0])), rng.normal() * 0.1,
                           rng.uniform(), rng.normal() * 0.1)
        k = int(rng.integers(0, scenario.n_steps))
        native = _native.timed_desired(settings, np.array(state.values()), k * settings.dt)
        reference = _pose_at(setup, state, k)
        for ours, theirs in zip((native["p_d"], native["sigma_d"], native["V_ed"]), reference):
            np.testing.assert_allclose(ours, theirs, atol=1e-14)


def test_the_kernel_step_map_is_the_references_while_the_commands_change(tmp_path):
    """Every state of a reference run whose commands change mid-run (approach, insertion, withdrawal and way back),
    replayed through one kernel step with its approach state: the sample and the next state within 1e-9. Whole
    runs part after a few hundred steps: tracking the moving frame within ~2e-5 m, the predefined-time feedback's
    gain is high enough to double a 1e-15 difference every step or two, as on the random family (docs/model.md
    §12), so the step map is what must agree."""
    scenario = _scenario(tmp_path, command=1.0)
    reference = make_rollout(scenario, backend="pinocchio", m=0.3, T_c=4.0)
    kernel = make_rollout(scenario, backend="kernel", m=0.3, T_c=4.0)
    states = []
    for k in range(1200):
        if k in (300, 900):
            reference.set_command({300: 2.0, 900: 0.4}[k])
        states.append(reference.timing)
        reference.advance(1)
    assert states[-1][0] == 0.4 and states[-1][3] == 0.0 and states[-1][1] < 1.0  # withdrawn, on the way back
    traj = reference.trajectory()
    scale = {name: max(1.0, float(np.max(np.abs(getattr(traj, name))))) for name in
             ("v", "dq_joints", "ee_position_error_m", "ee_attitude_error", "base_position_error_m",
              "base_attitude_error", "clearance_m", "self_clearance_m", "mu", "cdf", "sigma_min")}
    for k in range(0, 1199, 3):
        sample, q_next = kernel.replay_step(traj.q[k], k, states[k])
        assert np.max(np.abs(q_next - traj.q[k + 1])) <= 1e-9, f"q at step {k + 1}"
        for name, value in sample.items():
            expected = getattr(traj, name)[k]
            assert np.max(np.abs(value - expected)) <= 1e-9 * scale[name], f"{name} at step {k}"
    # and the whole run's approach state: the kernel's, advanced by the same commands, bit for bit
    for k in range(0, 1200, 10):
        if k in (300, 900):
            kernel.set_command({300: 2.0, 900: 0.4}[k])
        kernel.advance(10)
    np.testing.assert_array_equal(kernel.timing, reference.timing)


def test_bad_commands_and_settings_are_refused_by_name(tmp_path):
    scenario = _scenario(tmp_path)
    rollout = make_rollout(scenario, backend="kernel")
    for bad in (-0.1, 2.5, math.nan, "go"):
        with pytest.raises(InvalidInputError, match=r"approach command .*allowed: a number in \[0, 2\]"):
            rollout.set_command(bad)
    plain = make_rollout(load_scenario(_tumbling_toml(tmp_path)), backend="kernel")
    with pytest.raises(InvalidInputError, match="has no \\[commanded_approach\\]"):
        plain.set_command(1.0)
    settings = planner_settings(prepare(scenario), method="predefined_time", m=0.3, T_c=4.0)
    with pytest.raises(ValueError, match=r"standoff: allowed \[0, 1\] m"):
        settings.set_timing(-0.1, 0.2, 0.1, 0.5, 1.0)
    with pytest.raises(ValueError, match=r"insert_accel: allowed \(0, 1000\]"):
        settings.set_timing(0.1, 0.2, 0.1, 0.5, 0.0)
    with pytest.raises(ValueError, match=r"timing\[0\] \(the command\): allowed \[0, 2\]"):
        _native.timed_desired(settings, np.array([3.0, 0, 0, 0, 0]), 0.0)
    with pytest.raises(ValueError, match="timing: allowed finite values"):
        _native.timing_profile(settings, np.array([1.0, math.nan, 0, 0, 0]), 3)
    free = load_scenario("free_space")
    with pytest.raises(ScenarioError, match="'commanded_approach' without 'tumbling_target'"):
        free.replace(commanded_approach=scenario.commanded_approach)


def test_an_environment_plays_a_custom_tasks_commanded_approach_and_pickles_it(tmp_path):
    """A capture id given a scenario with [commanded_approach] as its task follows the scenario's command (no action
    sets it yet), step for step as a kernel rollout of the same scenario, and a pickled copy continues the same."""
    import pickle

    import gymnasium as gym

    import ffsr_gym  # noqa: F401  (registers the ids)

    scenario = _scenario(tmp_path, command=2.0)
    env = gym.make("FFSR-Capture-Residual-v0", task=scenario)
    env.reset(seed=0)
    engine = env.unwrapped.engine
    for _ in range(20):
        env.step(np.zeros(12, np.float32))
    timing = engine.episodes[0].timing
    assert timing[0] == 2.0 and 0.0 < timing[1] < 1.0  # approaching, at the scenario's command
    rollout = make_rollout(scenario, backend="kernel", m=scenario.planner.m, T_c=scenario.planner.T_c_s)
    rollout.advance(20 * engine.steps_per_decision)
    np.testing.assert_array_equal(timing, rollout.timing)
    clone = pickle.loads(pickle.dumps(env.unwrapped))
    for _ in range(10):
        obs, *_ = env.step(np.zeros(12, np.float32))
        clone_obs, *_ = clone.step(np.zeros(12, np.float32))
        np.testing.assert_array_equal(obs, clone_obs)
    np.testing.assert_array_equal(clone.engine.episodes[0].timing, engine.episodes[0].timing)
