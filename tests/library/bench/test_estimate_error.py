"""The estimate-error study of the look-ahead (``experiments/capture_estimate_error.py``): its model of a task moves the
body's spin and drift by exactly the drawn error and nothing else, its robust rule takes the moment best on average
over the hypotheses, and a row plays each chosen moment on the task itself."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import script_module

from ffsr_gym.bench.lookahead import Lookahead
from ffsr_gym.tasks.certificate import planner_episode
from ffsr_gym.tasks.splits import pool, task_scenario
from ffsr_gym.versions.registry import load_benchmark

VERSION = "capture-v1"


def test_the_model_moves_the_spin_and_the_drift_and_nothing_else():
    study = script_module("capture_estimate_error")
    benchmark = load_benchmark(VERSION)
    task = task_scenario("nutation", pool("nutation", "test", version=VERSION)[0].seed, benchmark)
    spin, drift = np.array([0.1, -0.2, 0.3]), np.array([0.001, 0.0, -0.002])
    model = study.moved(task, spin, drift)
    body, moved_body = task.tumbling_target, model.tumbling_target
    assert np.array(moved_body.omega_body_deg_s) - np.array(body.omega_body_deg_s) == pytest.approx(spin, abs=1e-15)
    assert np.array(moved_body.velocity_m_s) - np.array(body.velocity_m_s) == pytest.approx(drift, abs=1e-15)
    assert dataclasses.replace(moved_body, omega_body_deg_s=body.omega_body_deg_s,
                               velocity_m_s=body.velocity_m_s) == body
    assert model.replace(tumbling_target=body) == task
    assert study.moved(task, np.zeros(3), np.zeros(3)) == task


@pytest.mark.parametrize(("hypotheses", "chosen"), [
    ([[0.0, 0.5, 0.3], [0.0, 0.0, 0.3]], 2),  # good under both beats best under one
    ([[0.2, 0.2], [0.2, 0.2]], 0),            # the earliest of equals
    ([[0.0, 0.0], [0.0, 0.0]], 0),            # nothing captures: straight in
])
def test_the_robust_rule_takes_the_best_mean_over_the_hypotheses(hypotheses, chosen):
    assert script_module("capture_estimate_error").robust_choice(np.array(hypotheses)) == chosen


def test_a_row_plays_each_chosen_moment_on_the_task_itself():
    study = script_module("capture_estimate_error")
    benchmark = load_benchmark(VERSION)
    seed = pool("sweep", "test", version=VERSION)[3].seed
    row = study.task_row("sweep", seed, 3, Lookahead(step_s=10.0))
    task = task_scenario("sweep", seed, benchmark)
    assert len(row["levels"]) == len(study.LEVELS) and row["exact"] <= row["exact_grid_best"]
    for level in row["levels"]:
        for rule in ("naive", "robust"):
            assert level[f"{rule}_go_s"] in [10.0 * k for k in range(6)]
            episode = planner_episode(task, benchmark, method="predefined_time", m=0.3, T_c=4.0,
                                      go_s=level[f"{rule}_go_s"])
            assert level[rule] == pytest.approx(episode.score, rel=0.0, abs=1e-15)


def test_the_docs_block_is_the_committed_result_rendered():
    study = script_module("capture_estimate_error")
    root = Path(__file__).resolve().parents[3]
    data = json.loads((root / "experiments" / "capture_estimate_error.json").read_text())
    page = (root / "docs" / "baselines.md").read_text()
    block = page[page.index(study.START) + len(study.START):page.index(study.END)]
    assert block.strip() == study.docs_text(data).strip()
    for s in data["summary"]:  # the exact model is the look-ahead of the study it extends: it captures every task
        assert s["cells"][0]["model"] == "exact" and s["cells"][0]["captures"] == s["tasks"] == 40
