"""The summary's generated parts (docs/baselines.md): method names, headroom, compute per RL entry."""

from __future__ import annotations

import numpy as np
import pytest

from ffsr_gym.versions.registry import spec_for_version
from ffsr_gym_lab.board import normalise, tables

SPEC = spec_for_version("v2")


def _entry(name, tier, scores, **extra):
    rows = [{"seed": i, "task_index": i, "score": s} for i, s in enumerate(scores)]
    return {"name": name, "episodes": rows, "extra": {"evaluation_pool": f"{tier}/test", **extra}}


def test_method_names_drop_the_tier_before_the_checkpoint_suffix():
    assert tables.method_name({"name": "ppo_residual_easy"}, "easy") == "ppo_residual"
    assert tables.method_name({"name": "ppo_residual_easy_valbest"}, "easy") == "ppo_residual_valbest"
    assert tables.method_name({"name": "reference_v2_default"}, "easy") == "reference_v2_default"


def test_headroom_is_one_minus_the_best_normalised_score(monkeypatch):
    monkeypatch.setattr(normalise.reference, "reference_scores",
                        lambda tier, split, version=None: np.full(100, 0.5) if tier == "easy" else None)
    monkeypatch.setattr(tables.best_known, "load_best_known", lambda version=None, path=None: None)
    entries = {"easy": [_entry("a", "easy", [0.25] * 100), _entry("b", "easy", [0.4] * 100)],
               "hard": [_entry("c", "hard", [0.1] * 100)]}
    text = tables.headroom(SPEC, entries)
    assert "easy 0.200 (best: `b`, 0.800; no entry beats the reference score on any test task)" in text  # 1 - 0.4/0.5
    assert "hard - (no reference scores)" in text
    entries["easy"].append(_entry("c", "easy", [0.6, 0.55] + [0.0] * 98))  # beats it on tasks 0 and 1
    assert "entries beat the reference score on 2 test tasks, by up to 20.0%" in tables.headroom(SPEC, entries)


def test_best_known_cost_sums_each_file_and_skips_a_missing_one(monkeypatch):
    files = {"test": {"counts": {"easy": {"test": 100, "validation": 50}, "hard": {"test": 100}},
                      "compute": {"objective_evaluations": 12_345, "wall_time_s": 5400.0, "cores": 1}},
             "train": None}
    monkeypatch.setattr(tables.best_known, "load_best_known",
                        lambda version=None, path=None: files["train" if "_train" in str(path) else "test"])
    assert tables.best_known_cost("v2").endswith(": 250 tasks of the test and validation pools, 12,345 episodes, "
                                                 "1.5 core-hours.")
    files["train"] = {"counts": {"easy": {"train": 200}},
                      "compute": {"objective_evaluations": 1_000, "wall_time_s": 3600.0, "cores": 2}}
    assert tables.best_known_cost("v2").endswith("12,345 episodes, 1.5 core-hours; 200 tasks of the training pools "
                                                 "(offline datasets), 1,000 episodes, 2.0 core-hours.")
    files["test"] = files["train"] = None
    assert tables.best_known_cost("v2") == ""


def test_compute_per_rl_entry_counts_each_training_once():
    common = {"compute": {"env_steps": 5_000_000, "wall_time_s": 7200.0, "hardware": "1 CPU core per training seed"},
              "runs": [{}] * 5, "timesteps_per_seed": 1_000_000}
    entries = {"easy": [_entry("ppo_easy", "easy", [0.1], checkpoint="last", **common),
                        _entry("ppo_easy_valbest", "easy", [0.1], checkpoint="best_on_validation", **common),
                        _entry("reference_v2_default", "easy", [0.1])]}
    lines = tables.rl_compute_table(entries)
    assert lines[2:] == ["| `ppo` | 5 x 1,000,000 steps, 2.0 h, `1 CPU core per training seed` |"]  # typed: inert
    rl = [e for e in entries["easy"] if e["extra"].get("checkpoint") == "last"]
    assert tables._rl_compute(rl).startswith("RL entries: 5 trained agents, 5,000,000 environment steps, 2.0 h")


@pytest.mark.parametrize("tier", ["easy", "debris"])
def test_normalised_column_is_absent_without_reference_scores(tier, monkeypatch):
    monkeypatch.setattr(normalise.reference, "reference_scores", lambda *a, **k: None)
    assert normalise.normalised_mean(_entry("a", tier, [0.3] * 100), "v2") is None


def test_the_aggregates_file_goes_stale_when_an_entry_changes():
    from ffsr_gym_lab.board.aggregates import inputs

    entries = {"easy": [_entry("a", "easy", [0.25] * 10)]}
    before = inputs(entries)
    entries["easy"][0]["episodes"][3]["score"] = 0.26
    assert inputs(entries) != before and list(before) == ["easy/a"]
    changed = inputs(entries)
    entries["easy"][0]["_problems"] = []  # what the loader adds is not content
    assert inputs(entries) == changed


def _ranked(name, env_id, iqm, lo, hi, rate, checkpoint=None):
    extra = {} if checkpoint is None else {"training_seeds": [0, 1, 2, 3, 4], "checkpoint": checkpoint}
    return {"name": name, "env_id": env_id, "extra": extra,
            "metrics": {"score_iqm": iqm, "score_iqm_ci95": [lo, hi], "success_rate": rate}}


def test_the_rl_study_table_compares_the_selected_rl_entry_with_the_classical_ones():
    from ffsr_gym_lab.board import rl_comparison

    easy = [_ranked("reference_best_constant", "planner", 0.25, 0.23, 0.27, 0.98),
            _ranked("ga_v2", "planner", 0.24, 0.22, 0.26, 0.97),
            _ranked("cmaes_residual", "FFSR-Residual-v2", 0.33, 0.32, 0.35, 0.99),
            _ranked("sac_residual_easy_valbest", "FFSR-Residual-v2", 0.30, 0.29, 0.31, 0.97, "best_on_validation"),
            _ranked("sac_residual_easy", "FFSR-Residual-v2", 0.20, 0.19, 0.21, 0.87, "last"),
            _ranked("ppo_easy_valbest", "FFSR-v2", 0.26, 0.25, 0.27, 0.9, "best_on_validation"),
            _ranked("ppo_easy", "FFSR-v2", 0.05, 0.04, 0.06, 0.3, "last")]
    debris = [_ranked("reference_best_constant", "planner", 0.19, 0.15, 0.23, 0.7),
              _ranked("ppo_debris_valbest", "FFSR-v2", 0.192, 0.17, 0.21, 0.7, "best_on_validation"),
              _ranked("ppo_debris", "FFSR-v2", 0.13, 0.12, 0.15, 0.69, "last")]
    text = rl_comparison.table(SPEC, {"easy": easy, "medium": easy[:3], "debris": debris})
    rows = {line.split(" | ")[0][2:]: line.split(" | ") for line in text.splitlines()[2:]}
    assert set(rows) == {"easy", "debris"}  # medium has no RL entry
    easy_row = rows["easy"]
    assert easy_row[1] == "`sac_residual_valbest` 0.300 [0.290, 0.310], 97%"  # 0.30 beats PPO's 0.26
    assert easy_row[2] == "`sac_residual` 0.200 [0.190, 0.210], 87%"
    assert easy_row[3].startswith("`reference_best_constant` 0.250") and easy_row[4] == "above"  # 0.29 > 0.27
    assert easy_row[5].startswith("`cmaes_residual` 0.330") and easy_row[6] == "below"  # 0.31 < 0.32
    assert easy_row[7] == "`ppo` +0.210"  # PPO falls 0.26 - 0.05, SAC only 0.10
    assert easy_row[8] == "2 of 4 |"
    brax = [_ranked("brax_ppo_easy_valbest", "FFSR-Residual-v2", 0.29, 0.28, 0.30, 0.95, "best_on_validation"),
            _ranked("brax_ppo_easy", "FFSR-Residual-v2", 0.27, 0.26, 0.28, 0.96, "last")]
    with_brax = rl_comparison.table(SPEC, {"easy": easy + brax}).splitlines()[2]
    assert with_brax.endswith("| 2 of 4 (+1 other) |")  # another library's pair is not one of the study's four
    assert rows["debris"][4] == rows["debris"][6] == "CIs overlap"  # [0.17, 0.21] against [0.15, 0.23]
    assert rl_comparison.table(SPEC, {"easy": easy[:3]}) == "No RL entries yet.\n"
