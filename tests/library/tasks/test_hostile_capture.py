"""The fourth hostile pass on capture inputs: a body no mass distribution can be, a capture id without a body to
capture, rule files with reversed ranges or fractional counts, an episode too long to hold. Each named at load."""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import gymnasium as gym
import pytest

import ffsr_gym  # noqa: F401 - registers the ids
from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.model.benchmark import CaptureDraw
from ffsr_gym.model.scenario_sections import tumbling_problems
from ffsr_gym.model.schema import MAX_EPISODE_STEPS, build_table
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.tasks.capture_family import box_inertia
from ffsr_gym.tasks.splits import pool, task_scenario
from ffsr_gym.versions.registry import spec_for_version

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def capture_task():
    benchmark = score_rule(spec_for_version("capture-v0")).benchmark
    return task_scenario("slow", pool("slow", "test", version="capture-v0")[0].seed, benchmark)


def test_moments_beyond_what_the_mass_can_have_inside_the_box_are_refused(capture_task):
    body = capture_task.tumbling_target
    assert tumbling_problems(body, capture_task.target) == []  # a drawn (uniform) body passes
    a, b, c = body.size_m
    most = body.mass_kg * (b * b + c * c) / 4.0  # all the mass in the corners
    assert box_inertia(body.mass_kg, body.size_m)[0] == pytest.approx(most / 3.0)  # a uniform box: a third of it
    heavy = dataclasses.replace(body, inertia_kg_m2=(1.01 * most, *body.inertia_kg_m2[1:]))
    assert any("the most" in p and "moment 1" in p for p in tumbling_problems(heavy, capture_task.target))
    absurd = dataclasses.replace(body, mass_kg=1.0, size_m=(0.3, 0.3, 0.3), inertia_kg_m2=(1e6, 1e6, 1e6))
    assert any("0.045 kg m²" in p for p in tumbling_problems(absurd, capture_task.target))


def test_a_capture_id_refuses_a_scenario_with_no_body_to_capture():
    with pytest.raises(InvalidInputError, match=r"no \[tumbling_target\] to capture"):
        gym.make("FFSR-Capture-v0", task="paper")


def _draw_table() -> dict:
    rules = tomllib.loads((ROOT / "envs" / "benchmark" / "capture-v0.toml").read_text(encoding="utf-8"))
    return dict(rules["tasks"]["capture_draw"])


@pytest.mark.parametrize("key, value, words", [
    ("size_m", [0.8, 0.4], "reversed"),
    ("slow_spin_deg_s", [10.0, 2.0], "reversed"),
    ("max_attempts", 2.5, "an integer in"),
    ("max_attempts", 0, "an integer in"),
])
def test_a_rule_file_with_a_reversed_range_or_a_fractional_count_is_refused(key, value, words):
    table = _draw_table()
    assert isinstance(build_table(CaptureDraw, table, prefix="tasks.capture_draw."), CaptureDraw)  # the shipped one loads
    with pytest.raises(ScenarioError, match=f"{key}.*{words}"):
        build_table(CaptureDraw, table | {key: value}, prefix="tasks.capture_draw.")


def test_an_episode_too_long_to_hold_is_refused_up_front(capture_task):
    tiny = 1e-5  # divides the decision interval and the duration, into more steps than an episode may hold
    assert capture_task.simulation.duration_s / tiny > MAX_EPISODE_STEPS
    with pytest.raises(InvalidInputError, match="allowed: at most 200,000 steps"):
        capture_task.at_step(tiny)
    with pytest.raises(ScenarioError, match="allowed: at most 200,000 steps"):
        capture_task.replace(simulation=dataclasses.replace(capture_task.simulation, duration_s=3600.0, dt_s=1e-4))
