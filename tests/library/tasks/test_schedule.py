"""Action schedules (the best-known search's actions): interpolation by hand, and replays that agree with the
registered environments bit for bit, decision after decision and in the batched population."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ffsr_gym  # noqa: F401
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.tasks.certificate import replay
from ffsr_gym.tasks.schedule import Schedule, replay_schedule
from ffsr_gym.tasks.splits import pool, task_scenario
from ffsr_gym.versions.registry import spec_for_version

BENCHMARK = score_rule(spec_for_version("v2")).benchmark


def _task(tier="easy", index=0, split="test"):
    entry = pool(tier, split, version="v2")[index]
    return entry, task_scenario(tier, entry.seed, BENCHMARK)


def test_actions_interpolate_linearly_between_knots_and_hold_after_the_last():
    _, task = _task()
    knots = [[-1.0, 0.5], [0.0, 0.25], [1.0, -0.5]]
    actions = Schedule("parameters", tuple(map(tuple, knots))).actions(task)
    assert actions.shape == (200, 2) and actions.dtype == np.float32
    # three knots over decisions 0..199: at 0, 99.5 and 199
    assert actions[0].tolist() == [-1.0, 0.5] and actions[199].tolist() == [1.0, -0.5]
    assert actions[50, 0] == np.float32(-1.0 + 50 / 99.5)
    residual = Schedule.constant("residual", np.linspace(-1, 1, 12), 2).actions(task)
    # the residual knots spread over the decisions that start before the motion ends (10 s: 100 of them)
    assert Schedule.constant("residual", np.zeros(12), 2).span(task) == 100
    assert np.array_equal(residual[0], np.linspace(-1, 1, 12).astype(np.float32))
    assert np.array_equal(residual[150], residual[0])


def test_vector_round_trip_and_bad_knots_are_refused_by_name():
    schedule = Schedule.from_vector("residual", np.linspace(-2, 2, 48))  # clipped to [-1, 1]
    assert np.abs(schedule.vector()).max() == 1.0
    assert Schedule.from_dict(schedule.as_dict()) == schedule
    assert Schedule.from_vector("residual", schedule.vector()) == schedule
    with pytest.raises(InvalidInputError, match="family"):
        Schedule("torque", ((0.0,),))
    with pytest.raises(InvalidInputError, match="shape"):
        Schedule("parameters", ((0.0, 0.0, 0.0),))
    with pytest.raises(InvalidInputError, match="float32"):
        Schedule("parameters", ((0.1, 0.0),))
    with pytest.raises(InvalidInputError, match="keys"):
        Schedule.from_dict({"family": "residual"})


@pytest.mark.parametrize(("family", "env_id", "tier"), [("residual", "FFSR-Residual-v2", "hard"),
                                                        ("parameters", "FFSR-v2", "medium"),
                                                        ("residual", "FFSR-Residual-v2", "debris")])
def test_a_schedule_replays_as_the_env_plays_its_actions(family, env_id, tier):
    _, task = _task(tier, 2)
    rng = np.random.default_rng(5)
    schedule = Schedule.from_vector(family, rng.uniform(-0.4, 0.4, 3 * (12 if family == "residual" else 2)))
    result = replay_schedule(task, schedule, BENCHMARK)
    env = gym.make(env_id, task=tier, split="test")
    env.reset(seed=0, options={"task_index": 2})
    for action in schedule.actions(task):
        _, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    assert info["score"] == result.score and info["success"] == result.success


def test_constant_residual_schedules_reproduce_the_certificates():
    """A (m, T_c) certificate is physical, not a float32 action, so only residual ones compare exactly."""
    for index in range(3):
        entry, task = _task("hard", index)
        schedule = Schedule.constant("residual", entry.certificate.residual, 3)
        assert replay_schedule(task, schedule, BENCHMARK).score == pytest.approx(entry.certificate_score, abs=1e-12)
        assert replay(task, entry.certificate, BENCHMARK).score == pytest.approx(entry.certificate_score, abs=1e-12)


def test_the_batched_population_scores_as_the_replay():
    pytest.importorskip("cma")
    from ffsr_gym_lab.best_known.search import Population

    entry, task = _task("hard", 1)
    rng = np.random.default_rng(2)
    around = np.tile(entry.certificate.residual, 4)  # the hard certificate plus noise: some succeed, some not
    schedules = [Schedule.from_vector("residual", around + rng.uniform(-s, s, 48)) for s in (0.0, 0.05, 0.1, 0.6)]
    population = Population("residual", "hard", "test", 5)
    scores = population.scores(1, schedules)
    population.close()
    assert scores.tolist() == [replay_schedule(task, s, BENCHMARK).score for s in schedules]
    assert len(set(scores.tolist())) > 1  # the draws differ: the check compares something
