"""The ``servo`` tier of v2: the tier tasks on the servo plant, certified by v2's ensemble with a finer physics step
in place of the Pinocchio member. What every perturbed tier shares (pools full, disjoint and the first certified,
the rule re-run, batched envs, docs tables, certificates through the env and the ensemble) is tested with them
(``tests/library/tasks/test_tiers_perturbed.py``, ``tests/library/tasks/test_tasks.py``); here: what is the servo tier's own.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import assert_edited_rule_file_is_named

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.scenario import ServoSettings
from ffsr_gym.tasks import perturbation
from ffsr_gym.tasks.certificate import ensemble_members, planner_episode, replay
from ffsr_gym.tasks.generator import draw_task
from ffsr_gym.tasks.splits import load_pools, pool, task_scenario
from ffsr_gym.tasks.tiers import TIERS
from ffsr_gym.versions.registry import load_benchmark

BENCH = load_benchmark("v2")


def test_a_servo_task_is_its_base_task_on_the_servo_plant_and_nothing_else():
    rule = perturbation.load_servo_rule("v2")
    assert rule.servo == ServoSettings(physics_step_s=0.001, gain_scale=1.0, torque_limited=True)
    for split in BENCH.tasks.splits:
        for entry in pool("servo", split)[:5]:
            task, base = task_scenario("servo", entry.seed, BENCH), draw_task(entry.seed, BENCH)
            assert task.simulation.plant == "servo" and task.servo == rule.servo
            assert dataclasses.replace(task, simulation=base.simulation, servo=None, name=base.name,
                                       description=base.description) == base
            assert task.target == base.target and task.initial == base.initial  # bit for bit
            assert task.physics_substeps == 10  # 1 ms under the 10 ms planner step
            assert task.sha256() != base.sha256()  # the drives and the plant enter its hash


def test_its_last_ensemble_member_is_a_finer_physics_step_not_pinocchio():
    entry = pool("servo", "test")[0]
    task = task_scenario("servo", entry.seed, BENCH)
    with pytest.raises(InvalidInputError, match="servo plant runs on the kernel only"):
        ensemble_members(task, entry.seed, BENCH.tasks.ensemble)  # v2's ensemble asks for Pinocchio
    member = perturbation.confirmation_member(task, "v2")
    assert member.backend == "kernel" and member.name == "physics step/2"
    assert member.task.servo.physics_step_s == 0.0005 and member.task.physics_substeps == 20
    assert dataclasses.replace(member.task, servo=task.servo) == task
    result = replay(member.task, entry.certificate, BENCH)
    assert result.success and result.score != entry.certificate_score  # another physics step: another episode
    assert abs(result.score - entry.certificate_score) < 1e-3 * entry.certificate_score
    kinematic = draw_task(entry.seed, BENCH)
    assert perturbation.confirmation_member(kinematic, "v2").backend == "pinocchio"


def test_the_reference_planners_stored_verdicts_replay_on_the_servo_plant():
    """The pool file keeps, per task, how the default planner (0.3, 4 s) failed on the servo plant (None: it
    succeeded); replayed here, task by task, on a sample of every split."""
    planner = BENCH.planner
    for split in BENCH.tasks.splits:
        entries = load_pools(None, ("servo",))["splits"][split]["pools"]["servo"]
        for entry in entries[::max(1, len(entries) // 6)]:
            played = planner_episode(task_scenario("servo", entry["seed"], BENCH), BENCH, method="predefined_time",
                                     m=planner.m, T_c=planner.T_c_s)
            assert played.failure == entry["default_failure"], (split, entry["seed"])


def test_the_servo_pools_hold_every_base_tier_and_the_plant_moves_some_certificates():
    """Candidates are the easy, medium and hard tasks, so each is in the test pool; on some task the servo plant
    needs another certificate than the base task's (docs/model.md §21: few do, with the drives as shipped)."""
    test = pool("servo", "test")
    base_tier = {t.seed: name for name in TIERS for t in pool(name, "test")}
    assert {base_tier.get(t.seed) for t in test} == set(TIERS)
    differs = [t.seed for t in test if t.certificate != next(
        (b.certificate for name in TIERS for b in pool(name, "test") if b.seed == t.seed), None)]
    assert differs, "every servo test certificate equals its base task's"


@pytest.mark.parametrize("old, new, message", [
    ("physics_step_divisor = 2", "physics_step_divisor = 0.5",
     "'physics_step_divisor' = 0.5 is out of range; allowed: (1.0, 64.0]"),
    ("physics_step_s = 0.001", "physics_step_s = -1", "'servo.physics_step_s' = -1"),
    ("torque_limited = true", "torque_limited = 1", "'servo.torque_limited'"),
    ("gain_scale = 1.0", "gain_scale = 1.0\nstiffness = 3", "unknown key 'servo.stiffness'"),
])
def test_a_malformed_servo_rule_is_named(tmp_path, monkeypatch, old, new, message):
    assert_edited_rule_file_is_named(monkeypatch, tmp_path, "v2_servo.toml", "servo_rule_path",
                                     perturbation.load_servo_rule, (old, new), message)


def test_the_servo_tier_in_an_environment_logs_torques_and_saturation():
    """The zero residual of FFSR-Residual-v2 is the default planner: on a task it certifies, the env's episode has
    the stored certificate score exactly, and the trajectory carries the drives' saturation."""
    import gymnasium as gym

    import ffsr_gym  # noqa: F401  (registers the environments)

    index, entry = next((i, t) for i, t in enumerate(pool("servo", "test"))
                        if t.certificate.kind == "constant" and (t.certificate.m, t.certificate.T_c_s) == (0.3, 4.0))
    env = gym.make("FFSR-Residual-v2", task="servo", split="test")
    _, info = env.reset(seed=0, options={"task_index": index})
    assert info["task_seed"] == entry.seed
    done = False
    while not done:
        _, _, terminated, truncated, info = env.step(np.zeros(12, dtype=np.float32))
        done = terminated or truncated
    assert info["success"] and info["score"] == pytest.approx(entry.certificate_score, rel=0, abs=1e-12)
    trajectory = env.unwrapped.trajectory
    saturation = trajectory.info["torque_saturation"]
    assert saturation["physics_steps"] == 20_000 and 0.0 <= saturation["saturated_fraction"] <= 1.0
    assert trajectory.joint_torque_Nm is not None and np.abs(trajectory.joint_torque_Nm).max() > 0.0


def test_the_published_side_by_side_study_replays():
    """docs/model.md §21 shows the reference planner on both plants, from ``experiments/servo_plant.json``: the
    block is that file's tables, and the servo pool's numbers replay (200 episodes)."""
    import json
    from pathlib import Path

    from conftest import script_module

    root = Path(__file__).resolve().parents[3]
    script = script_module("servo_plant")
    result = json.loads((root / "experiments" / "servo_plant.json").read_text(encoding="utf-8"))
    text = (root / "docs" / "model.md").read_text(encoding="utf-8")
    assert text.split(script.START + "\n")[1].split(script.END)[0] == script.tables(result)
    stored = next(p for p in result["pools"] if p["tier"] == "servo")
    again = script.pool_study("v2", "servo")
    for plant in ("kinematic", "servo"):
        for key in ("success_rate", "success_by_base_tier", "mean_score"):
            assert again[plant][key] == stored[plant][key], (plant, key)
    assert again["same_verdict"] == stored["same_verdict"] and again["base_tiers"] == stored["base_tiers"]
