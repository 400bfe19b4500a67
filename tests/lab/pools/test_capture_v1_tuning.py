"""Capture v1's tuned baselines: a timed policy's go time read as the environments read it (the first decision at
or after it), the black-box loss refusing a go time by name, and the GA's third gene (resumable, spanning its box,
finding a closed-form bowl's minimum)."""

from __future__ import annotations

import numpy as np
import pytest

from ffsr_gym.bench.evaluation import evaluate
from ffsr_gym.bench.planner_scores import training_loss
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.optim import ga
from ffsr_gym.tasks.capture_timed import draw_timed_task
from ffsr_gym.tasks.certificate import planner_episode, timed_run
from ffsr_gym.versions.registry import load_benchmark

BENCH = load_benchmark("capture-v1")
SEED = 41  # a sweep candidate the default planner captures going in at 32 s (tests/library/tasks/test_capture_v1.py)


@pytest.fixture(scope="module")
def task():
    return draw_timed_task("sweep", SEED, BENCH)


def test_a_go_time_between_decisions_goes_at_the_next_decision_as_in_the_env(task):
    late, on_grid, early = (timed_run(task, 0.3, 4.0, go) for go in (31.95, 32.0, 31.9))
    assert np.array_equal(late.q, on_grid.q)  # 31.95 s: the decision at 32.0 s
    assert not np.array_equal(late.q, early.q)  # not the one at 31.9 s
    report = evaluate((0.3, 4.0, 31.95), "FFSR-Capture-v1", task=task)
    expected = planner_episode(task, BENCH, method="predefined_time", m=0.3, T_c=4.0, go_s=31.95)
    assert expected.success and report.episodes[0]["score"] == expected.score


def test_the_proportional_planner_takes_a_go_time(task):
    went = planner_episode(task, BENCH, method="proportional", gain_per_s=1.0, go_s=32.0)
    held = planner_episode(task, BENCH, method="proportional", gain_per_s=1.0, go_s=59.9)
    assert went.capture_time_s is not None and went.capture_time_s > 32.0
    assert held.capture_time_s is None and held.score == 0.0  # 0.1 s left: no capture


@pytest.mark.parametrize(("go", "version", "match"), [
    (None, "capture-v1", r"go_s = None; allowed on version 'capture-v1': a number in \[0, 60\) s"),
    (60.0, "capture-v1", r"go_s = 60.0; allowed on version 'capture-v1': a number in \[0, 60\) s"),
    (True, "capture-v1", r"go_s = True; allowed"),
    (10.0, "v2", r"go_s = 10.0; allowed: None on version 'v2'"),
])
def test_the_training_loss_refuses_a_go_time_by_name(go, version, match):
    with pytest.raises(InvalidInputError, match=match):
        training_loss(0.3, 4.0, go, tier="sweep" if version == "capture-v1" else "hard", tasks=1, version=version)


def _bowl(m: float, T_c: float, go_s: float) -> float:
    """A closed-form loss with its minimum at (0.3, 4 s, 20 s)."""
    return (m - 0.3) ** 2 + ((T_c - 4.0) / 10.0) ** 2 + ((go_s - 20.0) / 44.0) ** 2


def _config() -> ga.GAConfig:
    return ga.GAConfig(population=20, generations=25, m_bounds=(0.05, 0.6), T_c_bounds_s=(1.0, 10.0),
                       go_bounds_s=(0.0, 44.0), seed=5)


def test_the_third_gene_spans_its_box():
    config = _config()
    assert ga.decode(np.zeros(3 * ga.BITS, dtype=np.int8), config) == (0.05, 1.0, 0.0)
    assert ga.decode(np.ones(3 * ga.BITS, dtype=np.int8), config) == pytest.approx((0.6, 10.0, 44.0), abs=1e-12)


def test_a_timed_ga_resumes_exactly_and_finds_the_bowls_minimum(tmp_path):
    whole = ga.run(_config(), fitness=_bowl, progress=False)
    path = tmp_path / "ga.json"
    ga.run(_config(), fitness=_bowl, checkpoint=path, progress=False, stop_after=7)
    resumed = ga.run(None, fitness=_bowl, checkpoint=path, progress=False)
    assert resumed.history == whole.history and resumed.cache == whole.cache
    m, T_c, loss = ga.best(whole)
    assert ga.best_go_s(whole) == pytest.approx(20.0, abs=4.0) and m == pytest.approx(0.3, abs=0.1)
    assert loss == _bowl(m, T_c, ga.best_go_s(whole)) and loss < _bowl(0.3, 4.0, 0.0)


def test_capture_v1_ranks_on_the_mean_and_v2_on_the_iqm():
    from ffsr_gym.scoring.rules import score_rule
    from ffsr_gym.versions.registry import spec_for_version
    from ffsr_gym_lab.board.tables import header

    scores = [0.0] * 80 + [0.3] * 20  # captures on 20 % of the tasks: the IQM (middle half, all zeros) is 0
    rows = [{"score": s, "success": s > 0} for s in scores]
    v1, v2 = spec_for_version("capture-v1"), spec_for_version("v2")
    mean = score_rule(v1).aggregate(rows)
    assert mean["score_mean"] == pytest.approx(0.06) and mean["success_rate"] == pytest.approx(0.2)
    low, high = mean["score_mean_ci95"]
    assert 0.0 < low < 0.06 < high < 0.3  # a bootstrap CI of the mean, away from the IQM's 0
    assert score_rule(v2).aggregate(rows)["score_iqm"] == mean["score_iqm"] == 0.0  # reported, not ranked on
    assert "score mean [95% CI]" in header(v1, "sweep")[2] and "score IQM [95% CI]" in header(v2, "hard")[2]


def test_a_timed_schedule_plays_alike_in_the_env_batched_and_as_its_timed_run(task):
    import gymnasium as gym

    from ffsr_gym.environments.vector_env import FFSRVectorEnv
    from ffsr_gym.model.benchmark import action_to_parameters
    from ffsr_gym.tasks.schedule import Schedule, go_value, replay_schedule

    m_a, T_c_a = float(np.float32(2 * 0.25 / 0.55 - 1)), float(np.float32(2 * 3 / 9 - 1))  # ~ (0.3, 4 s)
    schedules = [Schedule("timed", ((m_a, T_c_a, go_value(k, 600)),)) for k in (0, 320, 200)]
    m, T_c = action_to_parameters([m_a, T_c_a], task)
    timed = planner_episode(task, BENCH, method="predefined_time", m=m, T_c=T_c, go_s=32.0)
    assert replay_schedule(task, schedules[1], BENCH).score == timed.score and timed.success
    env = gym.make("FFSR-Capture-v1", task=task)
    env.reset(seed=0)
    for action in schedules[1].actions(task):
        _, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    assert info["score"] == timed.score and info["capture_time_s"] == timed.capture_time_s
    venv = FFSRVectorEnv(3, "capture-v1", False, threads=1, autoreset_mode="Disabled", task=task)
    venv.reset(seed=[0, 1, 2])
    actions = np.stack([s.actions(task) for s in schedules], axis=1)
    for row in actions:
        if all(venv.engine.finished(i) for i in range(3)):
            break
        venv.step(np.ascontiguousarray(row))
    assert [venv.engine.results[i].score for i in range(3)] == [replay_schedule(task, s, BENCH).score
                                                               for s in schedules]
    venv.close()


def test_timed_schedules_name_every_decision_and_hold_one_knot():
    from ffsr_gym.tasks.schedule import Schedule, go_decision, go_value, version_families

    assert all(go_decision(go_value(k, 600), 600) == k for k in range(600))
    with pytest.raises(InvalidInputError, match="a timed schedule has one knot"):
        Schedule("timed", ((0.0, 0.0, 0.0), (0.0, 0.0, 0.5)))
    assert version_families("capture-v1") == ("timed",) and version_families("v2") == ("residual", "parameters")


def test_a_timed_schedule_is_judged_on_its_whole_runs_capture_ratio_as_a_timed_certificate(task):
    from ffsr_gym.model.benchmark import action_to_parameters
    from ffsr_gym.tasks.certificate import Certificate, replay_with_margins
    from ffsr_gym.tasks.schedule import Schedule, go_value, replay_schedule
    from ffsr_gym_lab.best_known.search import replayed

    m_a, T_c_a = float(np.float32(2 * 0.25 / 0.55 - 1)), float(np.float32(2 * 3 / 9 - 1))
    schedule = Schedule("timed", ((m_a, T_c_a, go_value(320, 600)),))
    m, T_c = action_to_parameters([m_a, T_c_a], task)
    episode, margins = replay_with_margins(task, Certificate("timed", m, T_c, go_s=32.0), BENCH)
    judged = replayed(task, schedule, BENCH)
    assert judged.score == episode.score == replay_schedule(task, schedule, BENCH).score
    assert judged.capture_ratio == margins.capture_ratio < 0.5 < episode.capture_ratio  # the episode's own: ~1


def test_the_go_decision_is_the_environments_for_every_go_time_on_a_fine_grid():
    from ffsr_gym.tasks.certificate import go_decision_of

    for go in np.round(np.arange(0.0, 60.0, 0.005), 3):  # the env's test (bench.entry.stepper): K dt >= go - 1e-9
        env = next(k for k in range(601) if (10 * k) * 0.01 >= go - 1e-9)  # K physics steps of 0.01 s
        assert go_decision_of(float(go), 0.1) == env, go
