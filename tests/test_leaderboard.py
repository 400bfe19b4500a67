"""Leaderboards: entries valid, aggregates recompute from rows, tables up to date, staleness, ranking."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import jsonschema
import pytest

import ffsr_gym
from ffsr_gym.bench import leaderboard

ROOT = Path(__file__).resolve().parent.parent / "leaderboards"
ENTRIES = sorted(ROOT.glob("*/*.json")) + []


def _close(a, b):
    if a is None or b is None or (isinstance(b, float) and math.isinf(b)):
        return (a is None or math.isinf(a)) and (b is None or math.isinf(b))
    return math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-15)


@pytest.mark.parametrize("path", [p for p in ENTRIES if p.name != "schema.json"], ids=lambda p: p.name)
def test_committed_entries_are_valid_and_recompute(path):
    entry = json.loads(path.read_text())
    jsonschema.validate(entry, json.loads((ROOT / "schema.json").read_text()))
    recomputed = leaderboard.recompute(entry)
    for key in ("score_mean", "score_iqm", "feasible_rate", "episodes"):
        assert _close(entry["metrics"][key], recomputed[key]), key
    for got, want in zip(entry["metrics"]["score_ci95"], recomputed["score_ci95"]):
        assert _close(got, want)
    assert entry["protocol"]["seeds"] == [row["seed"] for row in entry["episodes"]]


def test_committed_tables_are_up_to_date():
    assert leaderboard.render_readme(ROOT) == (ROOT / "README.md").read_text(), "run: ffsr-gym leaderboard render"


@pytest.fixture()
def board(tmp_path):
    root = tmp_path / "leaderboards"
    root.mkdir()
    shutil.copy(ROOT / "README.md", root / "README.md")
    good = ffsr_gym.evaluate((0.2167, 2.19), "FFSR-v0", seeds=[1, 2], name="good")
    bad = ffsr_gym.evaluate((0.1, 2.19), "FFSR-v0", seeds=[1], name="bad")
    for report in (good, bad):
        report.save(root / "FFSR-v0")
    return root


def test_ranking_stale_and_out_of_date_detection(board):
    assert leaderboard.write_readme(board)
    text = (board / "README.md").read_text()
    assert text.index("`good`") < text.index("`bad`")  # feasible rate first
    assert "| 1 | `good`" in text and "(single run)" in text
    assert not leaderboard.write_readme(board)  # idempotent
    entry_path = board / "FFSR-v0" / "good.json"
    entry = json.loads(entry_path.read_text())
    entry["provenance"]["scenario_sha256"]["family"] = "0" * 64
    entry_path.write_text(json.dumps(entry))
    assert leaderboard.render_readme(board) != text  # the table is now out of date
    assert "| stale | `good`" in leaderboard.render_readme(board)


def test_tampered_aggregate_is_caught(board):
    entry = json.loads((board / "FFSR-v0" / "good.json").read_text())
    entry["metrics"]["score_iqm"] = 0.0
    assert not _close(entry["metrics"]["score_iqm"], leaderboard.recompute(entry)["score_iqm"])
