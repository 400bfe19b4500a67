"""The dt/4 study of capture v1's paired groups (``experiments/paired_groups_dt.py``): its committed rows replay, its
groups follow from its rows, and its docs block is its result rendered."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import script_module

import ffsr_gym
from ffsr_gym.bench.capture_heuristic import slowest_pass
from ffsr_gym.tasks.certificate import planner_episode
from ffsr_gym.tasks.splits import pool, task_scenario
from ffsr_gym.versions.registry import load_benchmark
from ffsr_gym_lab.board.paired import paired_groups

ROOT = Path(__file__).resolve().parents[3]
VERSION = "capture-v1"


def _result() -> dict:
    return json.loads((ROOT / "experiments" / "paired_groups_dt.json").read_text())


@pytest.mark.parametrize(("tier", "index"), [("sweep", 2), ("nutation", 5)])
def test_committed_rows_at_dt4_replay(tier, index):
    row = next(r for r in _result()["rows"] if r["tier"] == tier and r["index"] == index)
    board = json.loads((ROOT / "leaderboards" / VERSION / tier / "reference_best_constant.json").read_text())
    planner = board["extra"]["planner"]
    seed = pool(tier, "test", version=VERSION)[index].seed
    assert row["seed"] == seed
    task = task_scenario(tier, seed, load_benchmark(VERSION))
    fine = planner_episode(task.at_step(0.0025), load_benchmark(VERSION), method=planner["method"], m=planner["m"],
                           T_c=planner["T_c_s"], gain_per_s=planner["gain_per_s"], go_s=planner["go_s"])
    assert row["scores"]["reference_best_constant"] == pytest.approx(fine.score, rel=0.0, abs=1e-12)
    report = ffsr_gym.evaluate(slowest_pass, "FFSR-Capture-v1", task=tier, indices=[index],
                               env_kwargs={"dt_s": 0.0025})
    assert row["scores"]["slowest_pass"] == pytest.approx(report.episodes[0]["score"], rel=0.0, abs=1e-12)


def test_the_groups_follow_from_the_rows_and_the_docs_block_is_the_result_rendered():
    study = script_module("paired_groups_dt")
    data = _result()
    for s in data["summary"]:
        rows = sorted((r for r in data["rows"] if r["tier"] == s["tier"]), key=lambda r: r["index"])
        assert [r["index"] for r in rows] == list(range(s["tasks"])) and s["tasks"] == 100
        fine = {n: [r["scores"][n] for r in rows] for n in rows[0]["scores"]}
        assert paired_groups(study.as_entries(fine), "score_mean").groups == s["dt4"]["groups"]
        names = sorted(n for g in s["dt"]["groups"] for n in g)
        assert names == sorted(fine)  # the same entries at both steps
    page = (ROOT / "docs" / "baselines.md").read_text()
    block = page[page.index(study.START) + len(study.START):page.index(study.END)]
    assert block.strip() == study.docs_text(data).strip()
    # capture v1's files and markers are the ones it always had; another version gets its own
    assert study.markers("capture-v1") == (study.START, study.END) and study.result_name("capture-v1") == (
        "paired_groups_dt")
    other = study.markers("capture-v2")
    assert "paired-groups-dt-capture-v2:start" in other[0] and "--version capture-v2" in other[0]
    assert study.result_name("capture-v2") == "paired_groups_dt_capture-v2"
