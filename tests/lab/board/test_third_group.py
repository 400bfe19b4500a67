"""The capture-v1 third-group study (experiments/capture_v1_third_group.py): its committed result describes today's
board, its cases are what they say, and the docs block is the one it generates."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import script_module

from ffsr_gym.versions.registry import spec_for_version
from ffsr_gym_lab.board.leaderboard import load_entries, verified

ROOT = Path(__file__).resolve().parents[3]
STUDY = script_module("capture_v1_third_group")
RESULT = json.loads((ROOT / "experiments" / "capture_v1_third_group.json").read_text(encoding="utf-8"))
BEST = json.loads((ROOT / "envs" / "benchmark" / "capture-v1_reference.json").read_text(encoding="utf-8"))["scores"]


@pytest.mark.parametrize("row", RESULT["tiers"], ids=lambda row: row["tier"])
def test_the_bars_are_todays_board(row):
    spec = spec_for_version("capture-v1")
    entries = {e["name"]: e for e in verified(load_entries(ROOT / "leaderboards", spec))[row["tier"]]}
    ci = spec.leaderboard.ci
    capturing = [e for name, e in entries.items() if not name.startswith("random")]
    # the top group: every entry whose CI is chained to the best entry's; its highest upper end is the bar
    top = sorted(capturing, key=lambda e: -e["metrics"][ci][1])
    group, reach = [top[0]], top[0]["metrics"][ci][0]
    for e in top[1:]:
        if e["metrics"][ci][1] >= reach:
            group.append(e)
            reach = min(reach, e["metrics"][ci][0])
    assert row["new_group"]["bar"] == max(e["metrics"][ci][1] for e in group), "rerun the study: the board changed"
    assert row["above_default"]["bar"] == entries["reference_capture-v1_default"]["metrics"][ci][1]


@pytest.mark.parametrize("row", RESULT["tiers"], ids=lambda row: row["tier"])
@pytest.mark.parametrize("bar", ["new_group", "above_default"])
def test_each_case_clears_its_bar_and_one_step_less_does_not(row, bar):
    best = np.asarray(BEST[row["tier"]]["test"] if isinstance(BEST[row["tier"]], dict) else BEST[row["tier"]])
    case, level = row[bar]["favourable"], row[bar]["bar"]
    k = case["tasks"]
    order = np.sort(best)[::-1]
    assert case["normalised"] == k / len(best)
    assert case["mean"] == pytest.approx(order[:k].sum() / len(best), abs=1e-12)
    assert case["ci"][0] > level
    fewer = np.concatenate([order[:k - 1], np.zeros(len(best) - k + 1)])
    assert not STUDY.clears(fewer, level)[0]
    uniform = row[bar]["uniform"]
    assert uniform["mean"] == pytest.approx(uniform["normalised"] * best.mean(), abs=1e-12)
    assert uniform["ci"][0] > level
    assert not STUDY.clears((uniform["normalised"] - 0.01) * best, level)[0]


def test_the_docs_block_is_the_generated_one():
    page = (ROOT / "docs" / "baselines.md").read_text(encoding="utf-8")
    assert f"{STUDY.START}\n{STUDY.docs_text(RESULT)}{STUDY.END}" in page
