"""How a replayed row must agree with the stored one: exactly for v0 and v2, within capture-v0's stated
``[replay]`` tolerances there (docs/model.md §17), with the verdict always exact and no one-way drift of the scores
over an entry's rows."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from ffsr_gym.bench.replay import replay_entry
from ffsr_gym.bench.replay_tolerance import bias_problem, differing_keys, numbers_agree, score_bias, tolerance_for
from ffsr_gym.model.spec import ReplaySpec

ROOT = Path(__file__).resolve().parents[3]
ROW = {"seed": 0, "task_index": 3, "task_seed": 1000006, "score": 0.4, "success": True, "failure": None,
       "smoothness_cost": 1.5, "rate_variation": [4.0, 2.5], "min_clearance_m": 0.03, "capture_time_s": 14.9,
       "capture_ratio": 0.001}


def test_v0_and_v2_replay_exactly_and_capture_states_its_tolerance():
    assert tolerance_for("v2") == ReplaySpec(0.0, 0.0) and tolerance_for("v0") == ReplaySpec(0.0, 0.0)
    capture = tolerance_for("capture-v0")
    assert 0.0 < capture.score_rel_tol <= 0.05 and capture.margin_rel_tol > 0.0 and capture.margin_abs_tol <= 1e-6


def test_a_row_agrees_within_the_tolerance_and_never_with_another_verdict():
    tolerance = ReplaySpec(score_rel_tol=0.01, margin_rel_tol=1.0)
    moved = ROW | {"score": 0.4 * 1.009, "smoothness_cost": 1.5 * 0.995, "rate_variation": [4.03, 2.49],
                   "capture_ratio": 0.0019, "min_clearance_m": 0.05}
    assert differing_keys(ROW, moved, tolerance) == []
    assert differing_keys(ROW, moved, ReplaySpec()) == ["capture_ratio", "min_clearance_m", "rate_variation",
                                                        "score", "smoothness_cost"]
    assert differing_keys(ROW, ROW | {"score": 0.4 * 1.011}, tolerance) == ["score"]
    assert differing_keys(ROW, ROW | {"success": False, "failure": "no_capture"}, tolerance) == ["failure", "success"]
    assert differing_keys(ROW, ROW | {"task_seed": 1000007}, tolerance) == ["task_seed"]
    assert differing_keys(ROW, {k: v for k, v in ROW.items() if k != "capture_time_s"}, tolerance) == ["capture_time_s"]
    assert differing_keys(ROW, ROW | {"capture_ratio": 0.0021}, tolerance) == ["capture_ratio"]


def test_the_score_and_c_keep_the_score_bound_their_terms_and_near_zero_numbers_the_margins():
    """The four capture-v0 residual RL rows that replayed outside the old bound (docs/model.md §17): one arm's rate
    variation 6 % off with C 1.1 % off, and final attitude errors of a few 1e-9 rad, twice or half the stored."""
    tolerance = ReplaySpec(score_rel_tol=0.05, margin_rel_tol=1.0, margin_abs_tol=1e-6)
    row = ROW | {"rate_variation": [2.2330, 2.5806], "smoothness_cost": 1.1756, "final_ee_attitude_error": 4.6e-9}
    replayed = row | {"rate_variation": [2.2968, 2.7359], "smoothness_cost": 1.1879, "final_ee_attitude_error": 9.7e-9}
    assert differing_keys(row, replayed, tolerance) == []
    assert differing_keys(row, replayed, ReplaySpec(0.05, 1.0)) == ["final_ee_attitude_error"]
    assert differing_keys(row, replayed | {"smoothness_cost": 1.1756 * 1.06}, tolerance) == ["smoothness_cost"]
    assert differing_keys(row, replayed | {"final_ee_attitude_error": 2e-6}, tolerance) == ["final_ee_attitude_error"]
    assert numbers_agree(0.0, 5e-7, 0.0, 1e-6) and not numbers_agree(0.0, 5e-7, 0.0)


@pytest.mark.parametrize(("stored", "replayed", "agree"), [
    (1.0, 1.0, True), (True, 1, False), (1, 1.0, True), (float("inf"), float("inf"), True),
    (float("inf"), 1e308, False), (float("nan"), float("nan"), False), (None, 0.0, False), ([1.0], [1.0, 1.0], False),
])
def test_numbers_agree_on_edge_values(stored, replayed, agree):
    assert numbers_agree(stored, replayed, 0.5) is agree


def test_rows_inflated_one_way_within_the_row_tolerance_are_refused():
    tolerance = ReplaySpec(score_rel_tol=0.01, margin_rel_tol=1.0)
    stored = [ROW | {"score": 0.2 + 0.01 * k} for k in range(40)]
    honest = [r | {"score": r["score"] * (1.0 + (0.004 if k % 2 else -0.004))} for k, r in enumerate(stored)]
    assert abs(score_bias(stored, honest)) < 1e-4 and bias_problem(stored, honest, tolerance) is None
    forged = [r | {"score": r["score"] * 1.005} for r in honest]  # every stored row 0.5 % above its replay
    assert score_bias(forged, honest) == pytest.approx(-0.005 / 1.005, rel=1e-9)
    assert "above their replays" in bias_problem(forged, honest, tolerance)
    assert bias_problem(forged, honest, ReplaySpec()) is None  # exact versions compare row by row instead


@pytest.mark.slow
def test_a_capture_entry_verifies_within_its_tolerance_and_an_inflated_copy_does_not(tmp_path):
    """A capture-v0 planner entry replays with its verdicts and within the tolerance on any x86-64 machine with FMA;
    the same rows with every positive score raised 1 % (inside the per-row tolerance, beyond the 0.5 % an entry's
    rows may drift one way) are refused."""
    path = ROOT / "leaderboards" / "capture-v0" / "fast" / "reference_capture-v0_default.json"
    verdict = replay_entry(path)
    assert verdict.status == "reproduced", verdict.text
    entry = json.loads(path.read_text())
    forged = copy.deepcopy(entry)
    for row in forged["episodes"]:
        row["score"] = row["score"] * 1.01 if row["score"] > 0.0 else row["score"]
    copy_path = tmp_path / path.name
    copy_path.write_text(json.dumps(forged))
    assert replay_entry(copy_path).status == "differs"


def test_the_tolerance_covers_the_measured_replays_and_the_docs_hold_them():
    """Every capture-v0 certificate replayed by experiments/certificate_replay.py kept its verdict and stayed inside
    the stated per-row tolerance, their mean signed difference inside the entry-level one; docs/model.md holds the
    study's generated table."""
    from conftest import script_module

    study = script_module("certificate_replay")
    data = json.loads(study.OUT.read_text())
    tolerance = tolerance_for("capture-v0")
    rows = [r for r in data["rows"] if r["version"] == "capture-v0"]
    assert len({(r["tier"], r["split"], r["index"]) for r in rows}) == 700 and all(r["success"] for r in rows)
    assert max(r["rel_difference"] for r in rows) <= tolerance.score_rel_tol / 1.5  # a margin over the largest move
    host = [r for r in rows if r["condition"] == "host"]
    assert bias_problem([{"score": r["stored_score"]} for r in host], [{"score": r["score"]} for r in host],
                        tolerance) is None
    text = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    block = text[text.index(study.START) + len(study.START):text.index(study.END)]
    assert block.strip() == study.docs_text(data).strip()
