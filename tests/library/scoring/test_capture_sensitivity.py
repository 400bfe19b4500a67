"""What the capture verdicts depend on. The tolerance and danger-radius study (experiments/capture_sensitivity.py):
rescoring a row with every tolerance scaled is exact (checked against capture() run again on the episode's relative
motion with the scaled rule). The dt study on the capture tiers (experiments/dt_sensitivity.py --version capture-v0):
its sampled episodes replay, and at least four planners per tier meet the bar. docs/model.md holds both tables."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest
from conftest import script_module

from ffsr_gym.bench.replay_tolerance import tolerance_for
from ffsr_gym.scoring.capture import QUANTITIES, capture, episode_relative_motion
from ffsr_gym.sim.setup import prepare
from ffsr_gym.tasks.capture_family import draw_capture_task
from ffsr_gym.tasks.certificate import planner_episode, planner_run, planner_task
from ffsr_gym.versions.registry import load_benchmark

ROOT = Path(__file__).resolve().parents[3]
RULES = load_benchmark("capture-v0")
study = script_module("capture_sensitivity")
dt_study = script_module("dt_sensitivity")
DT_STUDY = json.loads((ROOT / "experiments" / "dt_sensitivity_capture.json").read_text())


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
    data = json.loads((ROOT / "experiments" / "capture_sensitivity.json").read_text())
    text = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    block = text[text.index(study.START) + len(study.START):text.index(study.END)]
    assert block.strip() == study.docs_text(data).strip()


@pytest.mark.parametrize("index", [0, 35])  # slow at dt, fast at dt/4
def test_sampled_dt_study_episodes_replay(index):
    entry = DT_STUDY["sample"][index]
    kwargs = dt_study.planners(entry["tier"], ROOT / "leaderboards", "capture-v0")[entry["planner"]]
    piece = dt_study.run_piece((entry["law"], entry["tier"], entry["planner"], kwargs, entry["divisor"],
                                entry["seeds"][:1], "capture-v0"))
    tolerance = tolerance_for("capture-v0")  # the study's rows were made before the set-up was portable
    assert [row["score"] for row in piece["rows"]] == pytest.approx(entry["scores"][:1], rel=tolerance.score_rel_tol,
                                                                     abs=0.0)
    assert [row["score"] > 0.0 for row in piece["rows"]] == [s > 0.0 for s in entry["scores"][:1]]


def test_at_least_four_planners_per_capture_tier_meet_the_dt_bar():
    """The issue's bar, from the study's rows: verdicts equal at dt and dt/4 on >= 98 % of the tasks, Spearman
    >= 0.95, |IQM(dt) - IQM(dt/4)| <= 0.01, recomputed here from the row's numbers."""
    for tier in ("slow", "fast"):
        rows = [r for r in DT_STUDY["summary"] if r["tier"] == tier]
        meeting = [r["planner"] for r in rows if r["agreement"] >= 0.98 and r["spearman"] is not None
                   and r["spearman"] >= 0.95 and abs(r["iqm"][0] - r["iqm"][-1]) <= 0.01]
        assert len(meeting) >= 4, (tier, meeting)
        assert sorted(meeting) == sorted(r["planner"] for r in rows if r["meets_bar"])


def test_the_docs_hold_the_dt_study():
    text = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    assert dt_study.docs_block(text, "capture-v0").strip() == \
        dt_study.stored_docs_text(DT_STUDY, "experiments/dt_sensitivity_capture.json").strip()
