"""Benchmark v2's rules: the keep-out distance, the physics step option, the certificate ensemble and its margins."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import retired_v1_rules

from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.model.benchmark import load_rules
from ffsr_gym.model.resources import envs_dir
from ffsr_gym.model.scenario import load_scenario, to_dict
from ffsr_gym.tasks.certificate import Certificate, Margins, ensemble_members, offset_start, planner_episode, replay
from ffsr_gym.tasks.generator import draw_task
from ffsr_gym.versions.registry import load_benchmark

V2 = load_benchmark("v2")


def _with_keep_out(task, keep_out_m):
    return task.replace(objective=dataclasses.replace(task.objective, keep_out_m=keep_out_m))


def test_v2_rules_carry_the_blend_law_the_keep_out_and_the_ensemble_into_every_task(tmp_path):
    task = V2.task(load_scenario("random"))
    assert task.planner.mu_law == "distance" and task.objective.keep_out_m == 0.01
    assert V2.tasks.splits == ("train", "validation", "test") and V2.tasks.tasks_in("validation") == 50
    assert V2.tasks.ensemble.step_divisors == (2.0, 4.0) and V2.tasks.ensemble.pinocchio
    # A rule file without the keys v2 added (as v1's was) loads with v1's meaning.
    text = (envs_dir() / "benchmark" / "v2.toml").read_text()
    lines = [line for line in text.split("\n[tasks.ensemble]\n")[0].splitlines()
             if not line.startswith(("keep_out_m", "mu_law", "validation_tasks"))]
    older = tmp_path / "older.toml"
    older.write_text("\n".join(lines) + "\n\n[tasks.draw]\n" + text.split("\n[tasks.draw]\n")[1])
    v1 = load_rules(older)
    assert v1.score.keep_out_m == 0.0 and v1.planner.mu_law == "cdf" and v1.tasks.ensemble is None
    assert v1.tasks.splits == ("train", "test") and dataclasses.replace(v1, version="v1") == retired_v1_rules()


def test_a_scenario_that_leaves_keep_out_at_its_default_keeps_its_layout_and_hash():
    paper = load_scenario("paper")
    assert "keep_out_m" not in to_dict(paper)["objective"]
    moved = _with_keep_out(paper, 0.01)
    assert to_dict(moved)["objective"]["keep_out_m"] == 0.01 and moved.sha256() != paper.sha256()
    assert _with_keep_out(moved, 0.0).sha256() == paper.sha256()


@pytest.mark.parametrize("backend", ["kernel", "pinocchio"])
def test_a_clearance_below_the_keep_out_distance_is_a_collision_and_one_above_is_not(backend):
    """The episode's own smallest clearance d: a keep-out 0.1 mm above d ends it as a collision at the step
    that crosses it, 0.1 mm below leaves the verdict to the other tests (both backends stop alike)."""
    task = V2.task(draw_task(5, V2))
    free = planner_episode(_with_keep_out(task, 0.0), V2, method="predefined_time", m=0.3, T_c=4.0, backend=backend)
    d = free.min_clearance_m
    assert free.success and 0.05 < d < 0.2
    below = planner_episode(_with_keep_out(task, d - 1e-4), V2, method="predefined_time", m=0.3, T_c=4.0,
                            backend=backend)
    above = planner_episode(_with_keep_out(task, d + 1e-4), V2, method="predefined_time", m=0.3, T_c=4.0,
                            backend=backend)
    assert below.success and below.score == free.score
    assert above.failure == "collision" and above.score == 0.0
    assert d <= above.min_clearance_m < d + 1e-4  # stopped at the first step inside the keep-out distance


def test_at_step_keeps_the_decisions_and_refuses_a_step_that_does_not_divide_them():
    task = draw_task(5, V2)
    fine = task.at_step(0.0025)
    assert fine.simulation.dt_s == 0.0025 and fine.n_steps == 4 * task.n_steps
    assert fine.env.decision_interval_s == task.env.decision_interval_s
    assert fine.replace(simulation=task.simulation).sha256() == task.sha256()  # nothing else moved
    for bad, words in ((0.003, "does not divide env.decision_interval_s"), (0.2, "allowed: [1e-05, 0.1]"),
                       (math.nan, "dt_s"), ("0.01", "must be a number"), (True, "must be a number")):
        with pytest.raises(InvalidInputError, match="dt_s") as info:
            task.at_step(bad)
        assert words in str(info.value)


def test_the_ensemble_members_are_the_smaller_steps_two_starts_a_hair_off_and_pinocchio():
    task = draw_task(5, V2)
    members = ensemble_members(task, 5, V2.tasks.ensemble)
    assert [m.name for m in members] == ["dt/2", "dt/4", "start 1", "start 2", "pinocchio"]
    assert [m.task.simulation.dt_s for m in members[:2]] == [0.005, 0.0025]
    assert members[-1].backend == "pinocchio" and members[-1].task is task
    offsets = []
    for member in members[2:4]:
        moved = np.r_[member.task.initial.mission_joints_deg, member.task.initial.balance_joints_deg]
        start = np.r_[task.initial.mission_joints_deg, task.initial.balance_joints_deg]
        np.testing.assert_allclose(np.abs(moved - start), 1e-6, rtol=1e-6)  # every joint, 1e-6 deg
        offsets.append(np.sign(moved - start))
        assert member.task.replace(initial=task.initial).sha256() == task.sha256()
    assert not np.array_equal(offsets[0], offsets[1])  # two draws
    again = ensemble_members(task, 5, V2.tasks.ensemble, pinocchio=False)
    assert [m.name for m in again] == ["dt/2", "dt/4", "start 1", "start 2"]
    assert again[2].task.initial == members[2].task.initial  # drawn from the seed: the same every time


def test_an_offset_start_moves_the_joint_angles_by_the_offsets():
    task = draw_task(5, V2)
    offsets = np.arange(12) * 1e-3
    moved = offset_start(task, offsets)
    np.testing.assert_allclose(np.array(moved.initial.mission_joints_deg) - task.initial.mission_joints_deg,
                               offsets[:6], atol=1e-12)
    np.testing.assert_allclose(np.array(moved.initial.balance_joints_deg) - task.initial.balance_joints_deg,
                               offsets[6:], atol=1e-12)


def _margins(**kw):
    base = {"min_clearance_m": 0.1, "min_self_clearance_m": 0.05, "peak_rate_deg_s": 100.0,
            "final_ee_position_error_m": 1e-6, "final_ee_attitude_error": 1e-6, "episodes": 1}
    return Margins(**{**base, **kw})


def test_a_margin_inside_the_hair_band_names_what_is_short():
    """v2: peak <= 0.98 x 200 deg/s, clearance >= 10 mm + 2 mm (self: 2 mm), final errors <= 0.5 x tolerance."""
    assert _margins().short(V2) is None
    assert _margins(peak_rate_deg_s=196.0).short(V2) is None
    assert _margins(peak_rate_deg_s=196.01).short(V2) == "rate margin"
    assert _margins(min_clearance_m=0.012).short(V2) is None
    assert _margins(min_clearance_m=0.0119).short(V2) == "clearance margin"
    assert _margins(min_self_clearance_m=0.0019).short(V2) == "clearance margin"
    assert _margins(final_ee_position_error_m=5.1e-4).short(V2) == "final error margin"
    assert _margins(final_ee_attitude_error=5.1e-4).short(V2) == "final error margin"
    assert _margins(peak_rate_deg_s=199.0).short(retired_v1_rules()) is None  # without an ensemble: no margins


def test_worst_margins_are_the_worst_of_each_quantity_over_the_episodes():
    task = V2.task(draw_task(5, V2))
    results = [planner_episode(task.at_step(0.01 / d), V2, method="predefined_time", m=0.3, T_c=4.0) for d in (1, 2, 4)]
    worst = Margins.worst(results)
    assert worst.episodes == 3
    assert worst.min_clearance_m == min(r.min_clearance_m for r in results)
    assert worst.peak_rate_deg_s == max(max(r.peak_rate_deg_s) for r in results)
    assert worst.final_ee_position_error_m == max(r.final_ee_position_error_m for r in results)
    merged = Margins.worst(results[:1]).merge(Margins.worst(results[1:]))
    assert merged == worst
    assert Margins.from_dict(worst.as_dict()) == worst
    no_obstacle = dataclasses.replace(worst, min_clearance_m=math.inf)
    assert no_obstacle.as_dict()["min_clearance_m"] is None and Margins.from_dict(no_obstacle.as_dict()) == no_obstacle


def test_a_certificate_replays_alike_at_dt_over_four_and_on_its_own_step():
    """Under v2's law the verdict and the score of the reference default hardly move with the step."""
    task = V2.task(draw_task(5, V2))
    certificate = Certificate("constant", 0.3, 4.0)
    coarse, fine = replay(task, certificate, V2), replay(task.at_step(0.0025), certificate, V2)
    assert coarse.success and fine.success
    assert abs(coarse.score - fine.score) < 0.01


def test_the_paper_task_is_out_of_v2_reach_because_its_obstacle_sits_inside_the_targets_danger_radius():
    """Reported in docs/model.md: under the distance law the avoidance never releases on `paper`."""
    task = V2.task(load_scenario("paper"))
    results = [planner_episode(task, V2, method="predefined_time", m=m, T_c=T_c) for m, T_c in ((0.3, 4.0), (0.1, 3.0))]
    assert all(r.failure == "final_error" and r.final_ee_position_error_m > 0.1 for r in results)


def test_a_keep_out_distance_out_of_range_is_refused_by_name():
    with pytest.raises(FFSRError, match="keep_out_m"):
        _with_keep_out(load_scenario("paper"), -0.01)
