"""The certificate-stability study (benchmarks/certificate_stability.py): its replays and its docs table."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ffsr_gym.model.benchmark import load_benchmark
from ffsr_gym.tasks.splits import pool, task_scenario

from conftest import benchmark_script

ROOT = Path(__file__).resolve().parents[1]


def test_nudged_start_moves_every_joint_angle_by_one_ulp_and_nothing_else():
    study = benchmark_script("certificate_stability")
    task = task_scenario("easy", pool("easy", "test")[0].seed, load_benchmark("v1"))
    for direction in (np.inf, -np.inf):
        moved = study.nudged(task, direction)
        for field in ("mission_joints_deg", "balance_joints_deg"):
            before, after = np.array(getattr(task.initial, field)), np.array(getattr(moved.initial, field))
            assert np.all(np.sign(after - before) == np.sign(direction))  # moved, the right way,
            assert np.all(np.abs(after - before) <= np.spacing(np.abs(before)))  # by at most an ulp
        assert moved.replace(initial=task.initial).sha256() == task.sha256()


def test_a_case_the_study_found_fragile_replays_as_recorded():
    """A medium task whose certificate failed from a start one ulp up: its kernel replays again."""
    study = benchmark_script("certificate_stability")
    data = json.loads((ROOT / "benchmarks" / "certificate_stability.json").read_text())
    stored = next(r for r in data["cases"] if r["tier"] == "medium" and not r["ulp_up"]["success"])
    row = study.run_case((stored["tier"], stored["split"], stored["index"]))
    for variant in ("kernel", "ulp_up", "ulp_down"):  # the kernel's numbers are machine independent (§17)
        assert row[variant] == stored[variant]
    assert row["kernel"]["success"] and not row["ulp_up"]["success"]
    # not compared: the Pinocchio replay, whose matrix products may differ in the last bit between
    # machines (§17), which on a task this fragile can decide the outcome


def test_docs_table_is_rendered_from_the_full_study():
    study = benchmark_script("certificate_stability")
    data = json.loads((ROOT / "benchmarks" / "certificate_stability.json").read_text())
    assert [(r["tier"], r["split"], r["index"]) for r in data["cases"]] == study.cases()
    for row in data["cases"]:  # the study's kernel replays are the certified outcomes
        assert row["kernel"]["success"]
        assert row["kernel"]["score"] == pytest.approx(row["certificate_score"], rel=0, abs=1e-12)
        assert row["certificate_score"] == pool(row["tier"], row["split"])[row["index"]].certificate_score
    text = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    block = text.split(study.START + "\n")[1].split(study.END)[0]
    assert block == study.docs_text(data), "rerun: python benchmarks/certificate_stability.py --docs docs/model.md"


def test_a_malformed_results_file_is_refused_by_name(tmp_path):
    study = benchmark_script("certificate_stability")
    out = tmp_path / "results.json"
    for text in ("not json", '{"cases": [{"x": 1}]}', "[]"):
        out.write_text(text)
        with pytest.raises(SystemExit, match="results.json: not results of this study"):
            study.run(out, workers=1)
        assert out.read_text() == text  # left as it was


def test_fixed_parameter_entries_replay_their_board_metrics_and_stay_in_their_ci():
    """The study's kernel replay of each fixed-parameter leaderboard entry gives the board's IQM and
    success rate; from starts one ulp off the IQM stays in the board's CI (docs/model.md §18 says so)."""
    study = benchmark_script("certificate_stability")
    data = json.loads((ROOT / "benchmarks" / "certificate_stability.json").read_text())
    rows = {(r["tier"], r["entry"], r["variant"]): r for r in data["entries"]["rows"]}
    assert {(tier, name) for tier, name, _ in study.planner_entries()} == {(t, e) for t, e, _ in rows}
    for tier, name, _ in study.planner_entries():
        board = json.loads((study.LEADERBOARDS / tier / f"{name}.json").read_text())["metrics"]
        assert rows[(tier, name, "kernel")]["score_iqm"] == pytest.approx(board["score_iqm"], rel=0, abs=1e-12)
        assert rows[(tier, name, "kernel")]["success_rate"] == board["success_rate"]
        low, high = board["score_iqm_ci95"]
        assert all(low <= rows[(tier, name, v)]["score_iqm"] <= high for v in ("ulp_up", "ulp_down"))
    text = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    block = text.split(study.ENTRIES_START + "\n")[1].split(study.ENTRIES_END)[0]
    assert block == study.entries_text(data), "rerun: python benchmarks/certificate_stability.py --docs docs/model.md"
