"""The RL study's plan: seeds done and left, and core-hours left from finished seeds' wall times."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym_lab.studies import plan as study_plan


def _seed(work: Path, algo: str, env_id: str, tier: str, seed: int, wall_time_s: float, *, scored: bool = True) -> None:
    folder = work / f"{algo}_{env_id}_{tier}_seed{seed}"
    folder.mkdir(parents=True)
    (folder / "train_record.json").write_text(json.dumps(
        {"algo": algo, "env_id": env_id, "task": tier, "seed": seed, "wall_time_s": wall_time_s}))
    if scored:
        for name in ("evaluation.json", "evaluation_best_on_validation.json"):
            (folder / name).write_text("{}")


def _entry(root: Path, name: str, env_id: str, tier: str, checkpoint: str, wall_times: list[float]) -> None:
    path = root / "v2" / tier / f"{name}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    runs = [{"seed": s, "wall_time_s": w} for s, w in enumerate(wall_times)]
    path.write_text(json.dumps({"env_id": env_id, "env_kwargs": {"task": tier, "split": "test"},
                                "extra": {"checkpoint": checkpoint, "runs": runs}}))


def test_plan_counts_seeds_and_estimates_from_the_tier_then_other_tiers(tmp_path):
    work, root = tmp_path / "work", tmp_path / "lb"
    _seed(work, "ppo", "FFSR-v2", "easy", 0, 100.0)
    _seed(work, "ppo", "FFSR-v2", "easy", 1, 300.0)
    _seed(work, "ppo", "FFSR-v2", "easy", 2, 500.0, scored=False)  # trained, not scored: not done, but timed
    _seed(work, "ppo", "FFSR-Residual-v2", "easy", 0, 50.0)  # another env id: never mixed in
    for suffix, wall in (("", [1000.0, 2000.0]), ("_valbest", [7.0, 7.0])):  # only the last entry's runs count
        _entry(root, f"ppo_medium{suffix}", "FFSR-v2", "medium", "last" if not suffix else "best_on_validation", wall)
    groups = [("ppo", "FFSR-v2", "easy"), ("ppo", "FFSR-v2", "hard"), ("ppo", "FFSR-v2", "medium"),
              ("sac", "FFSR-v2", "easy")]
    plans = {p.tier + p.algo: p for p in study_plan.plan(groups, [0, 1, 2, 3, 4], work, root)}
    assert "mediumppo" not in plans  # both entries written: nothing left
    easy = plans["easyppo"]
    assert easy.done == (0, 1) and easy.left == (2, 3, 4) and easy.measured_on == "this tier"
    assert easy.hours_per_seed * 3600.0 == pytest.approx(300.0)  # median of 100, 300, 500
    hard = plans["hardppo"]
    # other tiers: easy's records (100, 300, 500) and medium's last entry (1000, 2000): median 500
    assert hard.done == () and hard.measured_on == "other tiers" and hard.hours_per_seed * 3600.0 == pytest.approx(500.0)
    sac = plans["easysac"]
    assert sac.hours_per_seed is None and sac.measured_on == "none"
    text = study_plan.render(list(plans.values()))
    assert f"{3 + 5 + 5} seeds left, about {(3 * 300.0 + 5 * 500.0) / 3600.0:.1f} h" in text
    assert "1 groups with no finished seed" in text
    assert study_plan.render(study_plan.plan([("ppo", "FFSR-v2", "medium")], [0, 1, 2, 3, 4], work, root)).startswith(
        "nothing left")


def test_only_a_run_covering_the_study_seeds_writes_entries():
    assert study_plan.writes_entries([0, 1, 2, 3, 4]) and study_plan.writes_entries([4, 3, 2, 1, 0, 5])
    assert not study_plan.writes_entries([0]) and not study_plan.writes_entries([0, 1, 2, 3])


def test_an_entry_from_fewer_seeds_than_asked_is_refused_by_name(tmp_path):
    root = tmp_path / "lb"
    groups = [("ppo", "FFSR-v2", "debris")]
    for suffix, checkpoint in (("", "last"), ("_valbest", "best_on_validation")):
        _entry(root, f"ppo_debris{suffix}", "FFSR-v2", "debris", checkpoint, [1.0])
    for path in (root / "v2" / "debris").glob("*.json"):  # as a `--seeds 0` run would have written them
        entry = json.loads(path.read_text())
        entry["extra"]["training_seeds"] = [0]
        path.write_text(json.dumps(entry))
    study_plan.check_entry_seeds(root, "v2", groups, [0])  # what it was written from: kept
    study_plan.check_entry_seeds(root, "v2", [("sac", "FFSR-v2", "debris")], [0, 1, 2, 3, 4])  # no entry yet
    with pytest.raises(InvalidInputError, match=r"ppo_debris(_valbest)?\.json: extra\.training_seeds is \[0\]"):
        study_plan.check_entry_seeds(root, "v2", groups, [0, 1, 2, 3, 4])
