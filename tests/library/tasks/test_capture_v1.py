"""Capture v1 (docs/model.md §23): the method owns the timing through the action's last entry, the episode ends at
its capture, and the score weighs the capture's time, the speed of first contact and the rates' smoothness.

Checked against independent computations: the speed of first contact against Pinocchio's kinematics of the
recorded run; the smoothness cost against numpy's sums of the applied rates; the observation's grasp frame against
the scenario's grasp record and Pinocchio's end-effector pose; the environment's early-ended episode against the
whole run of the same timing scored up to its capture; rewards that sum to the score minus one."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym  # noqa: F401 - registers the ids
from ffsr_gym import _native
from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.model.benchmark import action_to_parameters, load_rules
from ffsr_gym.model.quaternion import from_rotation
from ffsr_gym.model.resources import envs_dir
from ffsr_gym.planning.timed_approach import TimingState
from ffsr_gym.scoring.capture import episode_relative_motion
from ffsr_gym.scoring.score import score_episode
from ffsr_gym.sim.setup import prepare
from ffsr_gym.tasks.capture_timed import draw_timed_task, timing_outcomes
from ffsr_gym.tasks.certificate import Certificate, replay, timed_run
from ffsr_gym.versions.registry import load_benchmark

BENCH = load_benchmark("capture-v1")
SEED = 41  # a sweep candidate the default planner captures going straight in, and going in at 32 s


@pytest.fixture(scope="module")
def task():
    drawn = draw_timed_task("sweep", SEED, BENCH)
    assert drawn is not None
    return drawn


def _rates_cost(dq: np.ndarray, dt: float) -> float:
    """v2's smoothness cost C of applied rates (rows held dt each, from rest), by numpy's sums."""
    score = BENCH.score
    cost = 0.0
    for arm, weight in ((slice(0, 6), score.alpha), (slice(6, 12), score.beta)):
        rates = dq[:, arm]
        energy = float(np.sum(rates ** 2) * dt)
        variation = float(np.sum(np.linalg.norm(np.diff(np.vstack([np.zeros(6), rates]), axis=0), axis=1)))
        cost += weight * (energy / score.rate_energy_ref_rad2_s + variation / score.rate_variation_ref_rad_s)
    return cost


def test_the_score_is_its_three_terms_of_independently_computed_quantities(task):
    run = timed_run(task, BENCH.planner.m, BENCH.planner.T_c_s, 0.0)
    result = score_episode(run, task, BENCH)
    assert result.success and result.capture_time_s is not None
    captured = int(round(result.capture_time_s / run.dt))
    # the speed of first contact, from Pinocchio's end-effector pose and twist against the grasp record
    relative = episode_relative_motion(prepare(task), run)
    first = int(np.argmax(relative[:, 0] <= BENCH.capture.contact_m))
    assert 0 < first < captured
    assert result.contact_speed_m_s == pytest.approx(relative[first, 2], rel=1e-9, abs=1e-12)
    # the smoothness cost up to the capture (the captured sample's rates are not applied)
    assert result.smoothness_cost == pytest.approx(_rates_cost(run.dq_joints[:captured], run.dt), rel=1e-10)
    q = BENCH.quality
    expected = (q.time_weight * (1 - result.capture_time_s / task.simulation.duration_s)
                + q.contact_weight / (1 + relative[first, 2] / q.contact_speed_ref_m_s)
                + q.smoothness_weight / (1 + _rates_cost(run.dq_joints[:captured], run.dt)))
    assert result.score == pytest.approx(expected, rel=1e-9)
    assert math.fsum(result.quality_terms) == result.score and 0.0 < result.score < 1.0


def test_a_run_on_after_its_capture_scores_as_the_run_cut_there(task):
    run = timed_run(task, BENCH.planner.m, BENCH.planner.T_c_s, 0.0)
    whole = score_episode(run, task, BENCH)
    cut = score_episode(run.head(int(round(whole.capture_time_s / run.dt)) + 1), task, BENCH)
    assert whole == cut
    assert len(run.t) > int(round(whole.capture_time_s / run.dt)) + 500  # the run went on for seconds more


def test_going_in_later_is_another_capture_and_a_worse_time_term(task):
    outcomes = {o.go_s: o for o in timing_outcomes(task, BENCH)}
    early, late = outcomes[0.0], outcomes[32.0]
    assert early.capture_time_s is not None and late.capture_time_s is not None
    assert late.capture_time_s > early.capture_time_s + 20.0
    a = replay(task, Certificate("timed", 0.3, 4.0, go_s=0.0), BENCH)
    b = replay(task, Certificate("timed", 0.3, 4.0, go_s=32.0), BENCH)
    assert a.quality_terms[0] - b.quality_terms[0] == pytest.approx(
        0.4 * (b.capture_time_s - a.capture_time_s) / 60.0, rel=1e-12)


M_T_ACTION = np.array([-0.1, -2.0 / 3.0], dtype=np.float32)  # (m, T_c) near the defaults (0.3, 4 s)


def _timed_policy(env, go_s: float, parameters: bool = True):
    """Step ``env`` with :data:`M_T_ACTION` (or no residual) holding until ``go_s``, then commanding u = 2."""
    rewards, k, info = [], 0, {}
    while True:
        command = 1.0 if k * 0.1 >= go_s - 1e-9 else -1.0
        action = np.array([*M_T_ACTION, command] if parameters else [0.0] * 12 + [command], dtype=np.float32)
        _, reward, terminated, truncated, info = env.step(action)
        rewards.append(reward)
        k += 1
        if terminated or truncated:
            return rewards, info, terminated


@pytest.mark.parametrize("parameters", [True, False])
def test_the_environment_ends_at_the_capture_with_the_whole_runs_score(task, parameters):
    env_id = "FFSR-Capture-v1" if parameters else "FFSR-Capture-Residual-v1"
    env = gym.make(env_id, task=task)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (76,) and env.action_space.shape == ((3,) if parameters else (13,))
    rewards, info, terminated = _timed_policy(env, 32.0, parameters)
    played = env.unwrapped.engine.scenarios[0]
    m, T_c = action_to_parameters(M_T_ACTION, played) if parameters else (0.3, 4.0)
    expected = replay(task, Certificate("timed", m, T_c, go_s=32.0), BENCH)
    assert terminated and info["success"] and info["capture_time_s"] == expected.capture_time_s
    assert info["score"] == expected.score and info["contact_speed_m_s"] == expected.contact_speed_m_s
    assert len(rewards) == math.ceil(expected.capture_time_s / 0.1 - 1e-9)
    assert math.fsum(rewards) == pytest.approx(info["score"] - 1.0, abs=1e-12)
    env.close()


def test_the_grasp_observation_shows_the_grasp_frame_and_the_approach(task):
    env = gym.make("FFSR-Capture-v1", task=task)
    env.reset(seed=0)
    for _ in range(30):
        obs, *_ = env.step(np.array([0.0, 0.0, 0.0]))  # u = 1: the approach to the pre-grasp frame
    rollout = env.unwrapped.engine.rollout(0)
    setup, k = rollout.setup, rollout.k
    robot = setup.robot
    robot.update_kinematics(_configuration(rollout))
    placement = robot.data.oMf[int(robot.ee_frame_ids[0])]
    grasp = setup.grasp
    np.testing.assert_allclose(obs[59:62], grasp.position_m[k] - placement.translation, atol=2e-6)
    q_e, q_h = from_rotation(placement.rotation), grasp.quaternion[k]
    relative = np.array([q_e[0] * q_h[1:] - q_h[0] * q_e[1:] - np.cross(q_e[1:], q_h[1:])]).ravel()
    sign = 2.0 if float(np.dot(q_e, q_h)) >= 0 else -2.0
    np.testing.assert_allclose(obs[62:65], sign * relative, atol=2e-6)
    np.testing.assert_allclose(obs[65:71], np.hstack([grasp.velocity_m_s[k], grasp.omega_rad_s[k]]), atol=2e-6)
    timing = env.unwrapped.engine.episodes[0].timing
    np.testing.assert_allclose(obs[71:76], timing, atol=2e-6)
    assert timing[0] == 1.0 and 0.0 < timing[1] < 1.0 and timing[3] == 0.0  # approaching, not inserting
    env.close()


def _configuration(rollout) -> np.ndarray:
    """The rollout's configuration in Pinocchio's order (from the kernel state)."""
    x = rollout.x
    q = np.zeros(19)
    model = rollout.setup.assets.kernel
    q[:7], q[model.q_index] = x[:7], x[7:19]
    return q


def test_bad_inputs_are_refused_by_name(task):
    env = gym.make("FFSR-Capture-v1", task=task)
    env.reset(seed=0)
    with pytest.raises(InvalidInputError, match=r"shape \(3,\)"):
        env.step(np.zeros(2))
    with pytest.raises(InvalidInputError, match="finite"):
        env.step(np.array([0.0, 0.0, np.nan]))
    env.close()
    with pytest.raises(InvalidInputError, match="stepped by the native kernel"):
        gym.make("FFSR-Capture-v1", task=task, backend="pinocchio")
    with pytest.raises(InvalidInputError, match="go_s"):
        Certificate("timed", 0.3, 4.0)
    with pytest.raises(InvalidInputError, match="go_s"):
        Certificate("constant", 0.3, 4.0, go_s=3.0)
    with pytest.raises(InvalidInputError, match="capture v1 tier"):
        draw_timed_task("slow", 0, BENCH)
    episode = env.unwrapped.engine.episodes[0]
    with pytest.raises(ValueError, match="contact_m: allowed"):
        episode.judge_capture(np.ones(4), 1.0, 2.0, True)
    assert isinstance(_native.DecisionSettings().command_action, bool)
    state = TimingState()
    state.set_command(np.float32(1.5))  # any real number in [0, 2], numpy's too
    assert state.command == 1.5
    with pytest.raises(InvalidInputError, match="approach command True"):
        state.set_command(True)


def test_a_rule_file_whose_weights_do_not_sum_to_one_is_refused(tmp_path):
    text = (envs_dir() / "benchmark" / "capture-v1.toml").read_text().replace("time_weight = 0.4",
                                                                             "time_weight = 0.5")
    path = tmp_path / "rules.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match="sum to"):
        load_rules(path)


def test_step_with_parameters_commands_the_approach_and_a_pickled_env_ends_alike(task):
    import pickle

    env = gym.make("FFSR-Capture-v1", task=task)
    env.reset(seed=0)
    base = env.unwrapped
    for k in range(600):  # hold until 32 s, then go in: the certificate of (0.3, 4 s) going in at 32 s
        _, _, terminated, truncated, info = base.step_with_parameters(0.3, 4.0, command=2.0 if k >= 320 else 0.0)
        if k == 330:
            clone = pickle.loads(pickle.dumps(base))
        if terminated or truncated:
            break
    expected = replay(task, Certificate("timed", 0.3, 4.0, go_s=32.0), BENCH)
    assert terminated and info["score"] == expected.score and info["capture_time_s"] == expected.capture_time_s
    while True:  # the clone, from mid-approach
        _, _, done, cut, other = clone.step_with_parameters(0.3, 4.0)
        if done or cut:
            break
    assert other["score"] == info["score"] and other["contact_speed_m_s"] == info["contact_speed_m_s"]
    fresh = gym.make("FFSR-Capture-v1", task=task)
    fresh.reset(seed=0)
    with pytest.raises(InvalidInputError, match=r"command = 3.0; allowed: a real number in \[0, 2\]"):
        fresh.unwrapped.step_with_parameters(0.3, 4.0, command=3.0)
    plain = gym.make("FFSR-v2", task="easy", split="train")
    plain.reset(seed=0)
    with pytest.raises(InvalidInputError, match="no approach command"):
        plain.unwrapped.step_with_parameters(0.3, 4.0, command=1.0)
    env.close()


def test_evaluate_plays_a_timed_fixed_policy_and_the_random_residual_commands_too(task):
    from ffsr_gym import evaluate
    from ffsr_gym.bench.policies import uniform_random_residual

    report = evaluate((0.3, 4.0, 32.0), "FFSR-Capture-v1", task=task)
    expected = replay(task, Certificate("timed", 0.3, 4.0, go_s=32.0), BENCH)
    row = report.episodes[0]
    assert row["score"] == expected.score and row["capture_time_s"] == expected.capture_time_s
    assert report.extra["policy"] == {"fixed": [0.3, 4.0, 32.0]}
    random = evaluate(uniform_random_residual, "FFSR-Capture-Residual-v1", task=task)
    assert random.extra["trace"]["action_shape"] == [13] and not random.episodes[0]["success"]
    with pytest.raises(InvalidInputError, match=r"\(m, T_c \[s\], go_s \[s\]\), go_s in \[0, 60\) s"):
        evaluate((0.3, 4.0), "FFSR-Capture-v1", task=task)


def test_the_ensemble_holds_four_spin_members_the_first_as_capture_v0s(task):
    from ffsr_gym.tasks.certificate import ensemble_members

    members = ensemble_members(task, SEED, BENCH.tasks.ensemble, pinocchio=False)
    spins = {m.name: np.array(m.task.tumbling_target.omega_body_deg_s) for m in members if m.name.startswith("omega")}
    assert list(spins) == ["omega", "omega 2", "omega 3", "omega 4"]
    nominal = np.array(task.tumbling_target.omega_body_deg_s)
    for spin in spins.values():
        np.testing.assert_allclose(np.abs(spin - nominal), 0.3, rtol=1e-9)
    signs = np.random.default_rng([SEED, 8]).choice((-1.0, 1.0), 3)  # capture-v0's one member
    np.testing.assert_allclose(spins["omega"], nominal + 0.3 * signs, rtol=1e-12)
    assert len({tuple(np.sign(s - nominal)) for s in spins.values()}) >= 2


def test_the_batched_env_is_the_single_env_batched(task):
    vec = gym.make_vec("FFSR-Capture-Residual-v1", num_envs=2,
                       vectorization_mode="vector_entry_point", task=task)
    single = gym.make("FFSR-Capture-Residual-v1", task=task)
    obs, _ = vec.reset(seed=0)
    one, _ = single.reset(seed=1)
    np.testing.assert_array_equal(obs[1], one)
    rng = np.random.default_rng(5)
    for k in range(500):
        actions = rng.uniform(-0.3, 0.3, (2, 13)).astype(np.float32)
        actions[1, :12] = 0.0  # copy 1: the planner alone, going straight in (it captures at 10.95 s)
        actions[:, 12] = 1.0
        obs, rewards, terminated, truncated, info = vec.step(actions)
        one, reward, done, cut, single_info = single.step(actions[1])
        assert rewards[1] == pytest.approx(reward, abs=1e-12) and terminated[1] == done and truncated[1] == cut
        if done or cut:
            assert info["score"][1] == single_info["score"] and info["failure"][1] == single_info["failure"]
            break
        np.testing.assert_array_equal(obs[1], one)
    assert done and single_info["success"] and single_info["capture_time_s"] == pytest.approx(10.95)
    vec.close()
    single.close()


def _observation(t: float, speed: float) -> np.ndarray:
    obs = np.zeros(76, dtype=np.float32)
    obs[52], obs[65] = t / 60.0, speed
    return obs


def test_the_practitioners_timing_goes_in_after_the_slowest_moment():
    from ffsr_gym.bench.capture_heuristic import SlowestPass

    policy = SlowestPass()
    dips = [(k / 10, 0.05 + 0.02 * abs(k / 10 - 8.0)) for k in range(200)]  # slowest at 8 s
    commands = [float(policy(_observation(t, v))[2]) + 1.0 for t, v in dips]
    first = commands.index(2.0)
    assert dips[first][0] == pytest.approx(8.1) and all(c == 2.0 for c in commands[first:])
    steady = [float(policy(_observation(k / 10, 0.05))[2]) + 1.0 for k in range(40)]  # a new episode at t = 0
    assert steady.index(2.0) == 20  # no slowest moment: in at once after 2 s of watching
    rising = [float(policy(_observation(k / 10, 0.05 + 0.001 * k))[2]) + 1.0 for k in range(600)]
    assert rising.index(2.0) == 20  # the slowest moment was the start: in once the watching is over
    falling = [float(policy(_observation(k / 10, 0.65 - 0.001 * k))[2]) + 1.0 for k in range(600)]
    assert falling.index(2.0) == 491  # slower and slower: in when only the approach's 10.98 s are left
    m, T_c = action_to_parameters(policy.action(0.0)[:2], draw_timed_task("sweep", SEED, BENCH))
    assert m == pytest.approx(0.3, abs=1e-7) and T_c == pytest.approx(4.0, abs=1e-6)


def test_the_batched_env_refuses_a_command_before_its_reset_by_name(task):
    vec = gym.make_vec("FFSR-Capture-v1", num_envs=2, vectorization_mode="vector_entry_point", task=task)
    with pytest.raises(InvalidInputError, match=r"call reset\(\) before step\(\)"):
        vec.unwrapped.step_with_parameters(0.3, 4.0, command=2.0)
    vec.reset(seed=0)
    vec.unwrapped.step_with_parameters(0.3, 4.0, command=2.0)
    assert [e.timing[0] for e in vec.unwrapped.engine.episodes] == [2.0, 2.0]
    vec.close()
