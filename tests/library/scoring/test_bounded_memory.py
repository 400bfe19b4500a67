"""A batched copy keeps no trajectory unless asked: its episode's score comes from totals the native episode sums as it
runs, and they give the recorded trajectory's score on every tier to the last bit; the sums themselves are checked
against numpy's formulas over the trajectory (docs/kernel.md, "Memory")."""

import pickle

import numpy as np
import pytest

from ffsr_gym.environments.vector_env import FFSRVectorEnv
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.scoring.objective import objective_terms
from ffsr_gym.scoring.score import trajectory_totals

COPIES = 3
TIERS = ("easy", "medium", "hard", "debris", "robust", "servo")


def play(record: bool, task: str, residual: bool, seed: int = 11, scale: float = 0.9):
    """Whole episodes of COPIES copies with seeded random actions: (results, rewards per step, env)."""
    env = FFSRVectorEnv(COPIES, "v2", residual, record_trajectories=record, autoreset_mode="Disabled", task=task)
    env.reset(seed=seed)
    rng, rewards, done = np.random.default_rng(seed), [], np.zeros(COPIES, bool)
    while not done.all():
        actions = (scale * rng.uniform(-1, 1, (COPIES, *env.single_action_space.shape))).astype(np.float32)
        _, reward, terminated, truncated, _ = env.step(actions)
        rewards.append(reward)
        done |= terminated | truncated
    return [env.engine.results[i].as_dict() for i in range(COPIES)], np.array(rewards), env


@pytest.mark.parametrize("residual", [True, False], ids=["residual", "parameters"])
@pytest.mark.parametrize("task", TIERS)
def test_totals_give_the_recorded_trajectorys_score_on_every_tier(task, residual):
    recorded, rewards_recorded, env = play(True, task, residual)
    bounded, rewards_bounded, env_bounded = play(False, task, residual)
    assert env.engine.logs is not None and env_bounded.engine.logs is None
    assert bounded == recorded  # every field, to the last bit
    assert np.array_equal(rewards_bounded, rewards_recorded)
    # the totals against numpy's own formulas over the trajectory
    for i in range(COPIES):
        traj, scenario = env.engine.trajectory(i), env.engine.scenarios[i]
        totals = trajectory_totals(traj, scenario, env.engine.rule.benchmark)
        applied = traj.dq_joints[:-1]
        arms = applied.reshape(-1, 2, 6)
        steps = np.diff(np.vstack([np.zeros(12), applied]), axis=0).reshape(-1, 2, 6)
        assert totals.samples == len(traj.t) and totals.applied == len(applied)
        np.testing.assert_allclose(totals.square, np.einsum("kaj,kaj->a", arms, arms), rtol=1e-12)
        np.testing.assert_allclose(totals.variation, np.linalg.norm(steps, axis=2).sum(axis=0), rtol=1e-12)
        assert totals.peak == tuple(np.abs(arms).max(axis=(0, 2)))
        assert totals.min_clear == traj.clearance_m.min() and totals.min_self == traj.self_clearance_m.min()
        terms = objective_terms(traj, scenario.objective)
        assert recorded[i]["paper_B"] == (None if np.isinf(terms.objective) else terms.objective)
        assert recorded[i]["convergence_time_s"] == traj.convergence_time(
            env.engine.rule.benchmark.score.ee_position_tolerance_m)


def test_a_bounded_copy_pickles_mid_episode_with_its_totals():
    env = FFSRVectorEnv(2, "v2", True, autoreset_mode="Disabled", task="easy")
    env.reset(seed=4)
    rng = np.random.default_rng(4)
    actions = [rng.uniform(-1, 1, (2, 12)).astype(np.float32) for _ in range(env.n_steps // env.steps_per_decision)]
    for a in actions[:80]:
        env.step(a)
    clone = pickle.loads(pickle.dumps(env))
    for a in actions[80:]:
        env.step(a), clone.step(a)
    assert [r.as_dict() for r in env.engine.results] == [r.as_dict() for r in clone.engine.results]
    assert all(r is not None for r in env.engine.results)


def test_a_bounded_copy_refuses_to_give_a_trajectory_by_name():
    env = FFSRVectorEnv(2, "v2", True, task="easy")
    env.reset(seed=0)
    with pytest.raises(InvalidInputError, match="record_trajectories=True"):
        env.trajectory(0)
    with pytest.raises(InvalidInputError, match="record_trajectories"):
        FFSRVectorEnv(2, "v2", True, record_trajectories="yes")


def test_rules_that_score_the_trajectory_record_it_anyway():
    capture = FFSRVectorEnv(2, "capture-v0", True, record_trajectories=False)
    assert capture.engine.record  # capture is judged from the end-effector's recorded motion
    paper = FFSRVectorEnv(2, "v0", False, record_trajectories=False)
    assert paper.engine.record  # v0's increments are recomputed from the applied rates
