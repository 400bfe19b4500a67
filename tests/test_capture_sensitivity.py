"""The capture verdicts' sensitivity study (benchmarks/capture_sensitivity.py): rescoring a row with every tolerance
scaled is exact (checked against capture() run again on the episode's relative motion with the scaled rule), and
docs/model.md holds the study's generated tables."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from ffsr_gym.model.benchmark import load_benchmark
from ffsr_gym.scoring.capture import QUANTITIES, capture, episode_relative_motion
from ffsr_gym.sim.setup import prepare
from ffsr_gym.tasks.capture_family import draw_capture_task
from ffsr_gym.tasks.certificate import planner_episode, planner_run, planner_task
from tests.conftest import benchmark_script

ROOT = Path(__file__).resolve().parents[1]
RULES = load_benchmark("capture-v0")
study = benchmark_script("capture_sensitivity")


@pytest.mark.parametrize(("tier", "seed", "m", "T_c"), [("slow", 5, 0.3, 4.0), ("slow", 10, 0.3, 4.0),
                                                         ("fast", 6, 0.5, 2.5)])
def test_a_row_rescored_at_scaled_tolerances_is_the_capture_judged_again(tier, seed, m, T_c):
    task = draw_capture_task(tier, seed, RULES)
    result = planner_episode(task, RULES, method="predefined_time", m=m, T_c=T_c)
    row = result.as_dict()
    played = planner_task(task, "predefined_time", None)
    trajectory = planner_run(played, method="predefined_time", m=m, T_c=T_c)
    relative = episode_relative_motion(prepare(played), trajectory)
    for scale in (0.25, 0.5, 1.0, 2.0, 4.0):
        rule = dataclasses.replace(RULES.capture, **{q: scale * getattr(RULES.capture, q) for q in QUANTITIES})
        again = capture(trajectory.t, relative, rule)
        (expected,) = study.rescored([row], scale)
        assert expected["success"] == (again.captured and row["failure"] in (None, "no_capture")), scale
        if expected["success"]:
            assert expected["score"] == pytest.approx(1.0 / (1.0 + result.smoothness_cost), abs=1e-15)


def test_the_docs_hold_the_generated_tables():
    data = json.loads((ROOT / "benchmarks" / "capture_sensitivity.json").read_text())
    text = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    block = text[text.index(study.START) + len(study.START):text.index(study.END)]
    assert block.strip() == study.docs_text(data).strip()
