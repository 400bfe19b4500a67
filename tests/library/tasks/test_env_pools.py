"""FFSR-v2 / FFSR-Residual-v2: API checks on every tier, the zero residual is the planner, rewards sum to the score
minus 1, the residual can succeed, ``dt_s`` runs the same task at another step."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import ffsr_gym
from ffsr_gym import failure_name
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.scoring.score import score_episode
from ffsr_gym.versions.registry import load_benchmark

IDS = ("FFSR-v2", "FFSR-Residual-v2")
BENCH = load_benchmark("v2")


def run(env, policy, seed=0, index=0):
    """One episode of the pool task ``index`` (None: drawn from the seed)."""
    obs, _ = env.reset(seed=seed, options=None if index is None else {"task_index": index})
    rewards, infos = [], []
    while True:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        rewards.append(reward)
        infos.append(info)
        if terminated or truncated:
            return np.array(rewards), infos, env.unwrapped.trajectory


@pytest.mark.parametrize("tier", ["easy", "medium", "hard", "debris", "robust"])
@pytest.mark.parametrize("env_id", IDS)
def test_check_env_gymnasium_and_sb3(env_id, tier):
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = gym.make(env_id, task=tier, split="test")
        check_env(env.unwrapped, skip_render_check=True)
        sb3_checker.check_env(env.unwrapped, warn=True)
    assert not caught, [str(w.message) for w in caught]
    assert env.spec.max_episode_steps == 200


def test_arguments_are_checked():
    with pytest.raises(InvalidInputError, match="split"):
        gym.make("FFSR-v2", split="holdout")
    paper = gym.make("FFSR-v2", task="paper").unwrapped  # not a v2 task: a custom one, never ranked (docs/envs.md)
    assert paper.source.custom and paper.pool is None and paper.split is None and paper.scenario.name == "paper"
    with pytest.raises(InvalidInputError, match="custom task"):
        gym.make("FFSR-v2", task="paper", split="test")
    with pytest.raises(InvalidInputError, match="dt_s"):
        gym.make("FFSR-v2", dt_s=0.003)
    with pytest.raises(InvalidInputError, match="task"):
        gym.make("FFSR-v2", task="impossible")
    with pytest.raises(InvalidInputError, match="terminate_on_violation"):
        gym.make("FFSR-v2", terminate_on_violation="no")


def test_zero_residual_is_exactly_the_reference_planner():
    env = gym.make("FFSR-Residual-v2", task="easy")
    rewards, infos, traj = run(env, lambda obs: np.zeros(12, dtype=np.float32))
    reference = ffsr_gym.simulate(env.unwrapped.scenario)
    for field in ("q", "dq_joints", "ee_position_error_m", "clearance_m"):
        assert np.array_equal(getattr(traj, field), getattr(reference, field)), field
    assert (reference.info["m"], reference.info["T_c_s"]) == (BENCH.planner.m, BENCH.planner.T_c_s)
    assert infos[-1]["success"]


def test_rewards_sum_to_score_minus_one_and_info_matches_the_trajectory():
    env = gym.make("FFSR-v2", task="easy")
    rng = np.random.default_rng(1)
    actions = np.clip(rng.normal([0.0, -0.2], 0.05, (200, 2)), -1, 1).astype(np.float32)
    it = iter(actions)
    rewards, infos, traj = run(env, lambda obs: next(it))
    result = score_episode(traj, env.unwrapped.scenario, BENCH)
    assert infos[-1]["score"] == result.score and infos[-1]["success"] == result.success and result.success
    increments = np.array([i["smoothness_increment"] for i in infos])
    assert increments.sum() == pytest.approx(result.smoothness_cost, rel=1e-12)
    assert rewards.sum() == pytest.approx(1.0 / (1.0 + result.smoothness_cost) - 1.0, abs=1e-12)
    values = 1.0 / (1.0 + np.concatenate(([0.0], np.cumsum(increments))))  # closed form of the running value
    assert rewards[:-1] == pytest.approx(np.diff(values)[:-1], abs=1e-14)
    assert all(i["penalty"] == 0.0 for i in infos)


@pytest.mark.parametrize("terminate", [True, False])
def test_a_failure_loses_the_remaining_value(terminate):
    """A rate-limit failure: the return is exactly −1 (score 0), the last reward's penalty is 1 / (1 + C_t)."""
    env = gym.make("FFSR-v2", task="easy", terminate_on_violation=terminate)
    lo = np.array([-1.0, -1.0], dtype=np.float32)  # m = 0.05, T_c = 1 s: 227 deg/s on easy training task 4
    rewards, infos, _ = run(env, lambda obs: lo, index=4)
    assert failure_name(infos[-1]["failure"]) == "rate_limit" and infos[-1]["score"] == 0.0
    assert rewards.sum() == pytest.approx(-1.0, abs=1e-12)
    cost = sum(i["smoothness_increment"] for i in infos)
    assert infos[-1]["penalty"] == pytest.approx(1.0 / (1.0 + cost), rel=1e-12)
    if not terminate:  # the violation did not end the episode: the value is lost at the horizon
        assert len(infos) == 200 and infos[-2]["penalty"] == 0.0


def test_fading_residual_leaves_no_steady_state_error():
    """v0 failed with a constant residual of 0.002 deg/s (final error 1.2e-6 m); the fade removes it."""
    env = gym.make("FFSR-Residual-v2", task="easy")
    outcomes = []
    for size in (0.002 / 20, 0.01, 0.1, 0.5, 1.0):
        _, infos, traj = run(env, lambda obs, size=size: np.full(12, size, dtype=np.float32))
        outcomes.append(failure_name(infos[-1]["failure"]))
        if infos[-1]["failure"] == 0:
            assert traj.ee_position_error_m[-1] < 1e-6
    assert "final_error" not in outcomes and outcomes[0] is None


def test_fade_law():
    t_m, fade = 10.0, BENCH.action.residual_fade_s
    assert BENCH.residual_fade(0.0, t_m) == BENCH.residual_fade(t_m - fade, t_m) == 1.0
    assert BENCH.residual_fade(t_m - fade / 2, t_m) == pytest.approx(0.5, abs=1e-15)
    assert BENCH.residual_fade(t_m, t_m) == BENCH.residual_fade(15.0, t_m) == 0.0
    values = [BENCH.residual_fade(t, t_m) for t in np.linspace(t_m - fade, t_m, 50)]
    assert all(a >= b for a, b in zip(values, values[1:]))


def test_uniform_random_residual_succeeds_unless_it_breaks_a_limit():
    """Random residuals: every episode that neither exceeds the rate limit nor collides reaches the tolerance."""
    env = gym.make("FFSR-Residual-v2", task="easy")
    env.action_space.seed(0)
    failures = [failure_name(run(env, lambda obs: env.action_space.sample(), seed=s)[1][-1]["failure"]) for s in range(6)]
    assert "final_error" not in failures
    assert failures.count(None) >= 4


def test_violations_graded_when_not_terminating():
    env = gym.make("FFSR-v2", task="easy", terminate_on_violation=False)
    lo = np.array([-1.0, -1.0], dtype=np.float32)  # m = 0.05, T_c = 1 s: 227 deg/s on easy training task 4
    rewards, infos, traj = run(env, lambda obs: lo, index=4)
    assert len(infos) == 200 and not any(i.get("success") for i in infos)
    costs = np.array([i["cost"] for i in infos])
    assert costs.max() > 0.1 and failure_name(infos[-1]["failure"]) == "rate_limit"
    rates = np.degrees(np.abs(traj.dq_joints[:-1])).reshape(200, -1).max(axis=1)
    keep_out = BENCH.score.keep_out_m
    clear = np.minimum(traj.clearance_m[:-1] - keep_out, traj.self_clearance_m[:-1]).reshape(200, -1).min(axis=1)
    expected = np.maximum(0, -clear) / BENCH.action.cost_clearance_scale_m + np.maximum(0, rates / 200.0 - 1)
    assert costs == pytest.approx(expected, rel=1e-12, abs=1e-15)
    stopped = gym.make("FFSR-v2", task="easy")
    assert len(run(stopped, lambda obs: lo, index=4)[1]) < 200


def test_dense_shaping_telescopes_and_leaves_the_score():
    plain, shaped = gym.make("FFSR-v2", task="easy"), gym.make("FFSR-v2", task="easy", dense_shaping=True)
    action = np.array([0.0, -0.3], dtype=np.float32)
    r0, i0, _ = run(plain, lambda obs: action)
    r1, i1, _ = run(shaped, lambda obs: action)
    shaping = np.array([i["shaping"] for i in i1])
    assert r1 - r0 == pytest.approx(shaping, abs=1e-12)
    scale = BENCH.action.shaping_position_scale_m
    first = shaped.unwrapped.trajectory.ee_position_error_m[0]
    assert shaping.sum() == pytest.approx((first - i1[-1]["ee_position_error_m"]) / scale, rel=1e-9)
    assert i0[-1]["score"] == i1[-1]["score"]


SCRIPT = """
import hashlib, sys, numpy as np, gymnasium as gym, ffsr_gym
env = gym.make("FFSR-Residual-v2", task=sys.argv[1])
obs, _ = env.reset(seed=5)  # the pool task, drawn from the seed
env.action_space.seed(5)
h = hashlib.sha256(obs.tobytes())
for _ in range(40):
    obs, r, *_ = env.step(env.action_space.sample())
    h.update(obs.tobytes()); h.update(np.float64(r).tobytes())
h.update(env.unwrapped.trajectory.q.tobytes())
print(h.hexdigest())
"""


@pytest.mark.parametrize("task", ["easy", "medium", "debris", "robust"])
def test_same_seed_bit_identical_across_processes(task):
    digests = {subprocess.run([sys.executable, "-c", SCRIPT, task], capture_output=True, text=True, check=True).stdout
               for _ in range(2)}
    assert len(digests) == 1


CYCLES = """
import gc, numpy as np, gymnasium as gym, ffsr_gym
env = gym.make("FFSR-Residual-v2", task="easy")
venv = gym.make_vec("FFSR-Residual-v2", num_envs=4, vectorization_mode="vector_entry_point", task="easy")
env.reset(seed=0); venv.reset(seed=0); env.action_space.seed(0); venv.action_space.seed(0)
def run(n):
    for _ in range(n):
        if any(env.step(env.action_space.sample())[2:4]):
            env.reset()
        venv.step(venv.action_space.sample())
run(250)  # warm-up past the first episode ends: first steps and first ends compile, load and cache
gc.collect(); gc.disable()
run(600)  # past several episode ends and autoresets
print(gc.collect())
"""


def test_steps_and_episode_ends_leave_no_cyclic_garbage():
    """Freed by reference counting alone: the cycle collector finds nothing after 600 single and
    batched steps with episode ends (experiments/bench.py times with the collector off, as timeit)."""
    out = subprocess.run([sys.executable, "-c", CYCLES], capture_output=True, text=True, check=True).stdout
    assert int(out.split()[-1]) == 0


def test_evaluate_scores_the_test_pool_from_trajectories_and_records_the_pools():
    from ffsr_gym.tasks.splits import pool

    report = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="easy", training_pool="easy/train (not trained: the fixed default)")
    entry = report.to_json()
    tasks = pool("easy", "test")
    assert entry["extra"]["evaluation_pool"] == "easy/test" and entry["extra"]["training_pool"] == "easy/train (not trained: the fixed default)"
    assert entry["extra"]["dt_s"] == 0.01  # the benchmark's own step, recorded
    assert [row["task_seed"] for row in entry["episodes"]] == [t.seed for t in tasks]
    # The default planner is the certificate of every easy task: the stored build scores, replayed.
    assert [row["score"] for row in entry["episodes"]] == pytest.approx([t.certificate_score for t in tasks], abs=1e-12)
    assert report.metrics["success_rate"] == 1.0 and 0.0 < report.metrics["score_iqm"] < 1.0
    lo, hi = report.metrics["score_iqm_ci95"]
    assert lo <= report.metrics["score_iqm"] <= hi
    with pytest.raises(InvalidInputError, match="seeds"):
        ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", seeds=[1, 2])
    with pytest.raises(InvalidInputError, match="task"):
        ffsr_gym.evaluate((0.3, 4.0), "FFSR-v0", task="easy")
    with pytest.raises(InvalidInputError, match="12 numbers in"):
        ffsr_gym.evaluate((0.3, 4.0), "FFSR-Residual-v2", task="easy")
    with pytest.raises(InvalidInputError, match="exact in float32"):
        ffsr_gym.evaluate((0.1,) * 12, "FFSR-Residual-v2", task="easy")


def test_a_constant_residual_action_is_a_fixed_policy_the_leaderboard_can_replay(tmp_path):
    """A tuple of 12 float32 values on FFSR-Residual-v2 is played every decision; the entry names it, and
    ``leaderboard verify`` re-runs it to the same rows. On hard tasks it is what their residual certificates are."""
    from ffsr_gym.bench.replay import replay_entry
    from ffsr_gym.tasks.splits import pool

    first = pool("hard", "test")[0]
    action = tuple(first.certificate.residual)
    report = ffsr_gym.evaluate(action, "FFSR-Residual-v2", task="hard", indices=[0, 1, 2])
    assert report.episodes[0]["success"] and report.episodes[0]["score"] == pytest.approx(first.certificate_score,
                                                                                          abs=1e-12)
    assert report.extra["policy"] == {"fixed": list(action)}
    path = report.save(tmp_path)
    assert replay_entry(path).text == "all 3 rows reproduce exactly (the fixed parameters)"


@pytest.mark.parametrize("env_id", IDS)
def test_dt_s_plays_the_same_task_at_another_step_with_the_same_decisions(env_id):
    """``dt_s=0.0025``: 40 physics steps per 0.1 s decision, 200 decisions; the episode is the certificate's
    replay at dt/4 (the zero residual and the default (m, T_c) are the reference planner)."""
    from ffsr_gym.tasks.certificate import Certificate, replay
    from ffsr_gym.tasks.splits import pool, task_scenario

    env = gym.make(env_id, task="easy", split="test", dt_s=0.0025)
    assert env.unwrapped.steps_per_decision == 40
    zero = np.zeros(env.action_space.shape, dtype=np.float32)
    if env_id == "FFSR-v2":
        step = lambda obs: env.unwrapped.step_with_parameters(0.3, 4.0)  # noqa: E731 - physical, no float32 rounding
    else:
        step = lambda obs: env.step(zero)  # noqa: E731
    obs, _ = env.reset(seed=0, options={"task_index": 3})
    decisions, done = 0, False
    while not done:
        obs, _, terminated, truncated, info = step(obs)
        decisions, done = decisions + 1, terminated or truncated
    task = task_scenario("easy", pool("easy", "test")[3].seed, BENCH)
    expected = replay(task.at_step(0.0025), Certificate("constant", 0.3, 4.0), BENCH)
    assert decisions == 200 and len(env.unwrapped.trajectory.t) == 8001
    assert info["score"] == pytest.approx(expected.score, abs=1e-12) and info["success"] == expected.success


def test_an_entry_scored_at_another_step_records_it_and_the_leaderboard_refuses_it():
    from ffsr_gym.bench.verify import entry_problems
    from ffsr_gym.versions.registry import spec_for_version

    spec = spec_for_version("v2")
    own = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="easy").to_json()
    fine = ffsr_gym.evaluate((0.3, 4.0), "FFSR-v2", task="easy", env_kwargs={"dt_s": 0.005}).to_json()
    assert fine["extra"]["dt_s"] == 0.005 and fine["env_kwargs"]["dt_s"] == 0.005
    assert not entry_problems(own, spec, "easy")
    assert any("dt_s 0.005" in p and "dt_s = 0.01 s" in p for p in entry_problems(fine, spec, "easy"))
