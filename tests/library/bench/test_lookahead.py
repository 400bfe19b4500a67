"""The look-ahead timing (``ffsr_gym.bench.lookahead``) and planner entries with one go moment per task: what it
simulates is what ``FFSR-Capture-v1`` plays when stepped, and its choice is the middle of the best window."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import timed_episode

import ffsr_gym  # noqa: F401  (registers the ids)
from ffsr_gym.bench.lookahead import Lookahead
from ffsr_gym.bench.planner_scores import evaluate_planner
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.tasks.splits import pool, task_scenario
from ffsr_gym.versions.registry import load_benchmark

VERSION = "capture-v1"


def stepped(tier: str, index: int, m: float, T_c: float, go_s: float) -> dict:
    """Test task ``index`` stepped through the env (:func:`conftest.timed_episode`); the last step's info."""
    return timed_episode(tier, "test", index, m, T_c, go_s)


@pytest.mark.parametrize(("scores", "chosen"), [
    ([0.0, 0.4, 0.0, 0.3, 0.3, 0.3, 0.0], 4),  # the middle of a window beats a higher lone moment
    ([0.0, 0.2, 0.0, 0.1, 0.0], 1),            # no window: the best lone moment
    ([0.0, 0.0, 0.0], 0),                      # nothing captures: straight in
    ([0.5, 0.5, 0.0, 0.6, 0.6], 4),            # the grid's ends have one neighbour
    ([0.0, 0.3, 0.3, 0.3, 0.0, 0.3, 0.3, 0.3], 2),  # the earliest of equals
    ([0.2, 0.3, 0.4, 0.4, 0.4, 0.2], 3),
])
def test_it_plays_the_middle_of_the_best_window(scores, chosen):
    assert Lookahead.choose(np.array(scores)) == chosen


def test_what_it_simulates_is_what_the_env_plays():
    lookahead, tier, index = Lookahead(step_s=4.0), "sweep", 3
    benchmark = load_benchmark(VERSION)
    task = task_scenario(tier, pool(tier, "test", version=VERSION)[index].seed, benchmark)
    grid = lookahead.grid(60.0)
    assert grid.tolist() == [4.0 * k for k in range(15)]
    scores = lookahead.scores(task, benchmark, 60.0)
    captured, missed = int(np.argmax(scores)), int(np.argmin(scores))
    assert scores[captured] > 0.1 and scores[missed] == 0.0
    for k in (captured, missed):
        info = stepped(tier, index, 0.3, 4.0, float(grid[k]))
        assert info["success"] == (scores[k] > 0.0)
        assert info["score"] == pytest.approx(scores[k], rel=1e-12, abs=0.0)


def test_a_planner_entry_with_a_moment_per_task_records_and_plays_each():
    tasks = len(pool("nutation", "test", version=VERSION))
    moments = [0.0] * tasks
    moments[5] = 12.3
    report = evaluate_planner("predefined_time", task="nutation", m=0.3, T_c=4.0, go_s=moments, version=VERSION)
    rows = report.episodes
    assert [row["go_s"] for row in rows] == moments and report.extra["planner"]["go_s"] == moments
    info = stepped("nutation", 5, 0.3, 4.0, 12.3)
    assert rows[5]["score"] == pytest.approx(info["score"], rel=1e-12, abs=0.0)
    assert rows[5]["success"] == info["success"]


@pytest.mark.parametrize(("go_s", "message"), [
    ([0.0] * 3, "a list of 100"),
    ([0.0] * 99 + [60.0], r"go_s\[99\].*\[0, 60\) s"),
    ([0.0] * 99 + [float("nan")], r"go_s\[99\]"),
    ("0.0", "one number, or a list"),
])
def test_bad_moments_are_refused_by_name(go_s, message):
    with pytest.raises(InvalidInputError, match=message):
        evaluate_planner("predefined_time", task="sweep", m=0.3, T_c=4.0, go_s=go_s, version=VERSION)


def test_a_grid_step_outside_its_range_is_refused_by_name():
    for step in (0.0, 11.0, True, "0.5"):
        with pytest.raises(InvalidInputError, match=r"step_s.*\[0.01, 10\]"):
            Lookahead(step_s=step)
