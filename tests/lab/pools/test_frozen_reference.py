"""The normalised column divides by a frozen reference: a better best known score later is a record, shown apart,
and moves no published number; an entry scored against another reference is refused by name."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.tasks import reference
from ffsr_gym.tasks.splits import pool
from ffsr_gym.versions.registry import spec_for_version
from ffsr_gym_lab.best_known import records as best_known
from ffsr_gym_lab.board import leaderboard, tables
from ffsr_gym_lab.board.normalise import normalised_mean
from ffsr_gym_lab.pools import freeze

ROOT = Path(__file__).resolve().parents[3]


def _normalised_column(root: Path) -> dict[str, str]:
    """The easy table's normalised cell of every ranked entry, read from the rendered Markdown."""
    text = leaderboard.render_readme(root)
    block = text.split("### easy (test pool)")[1].split("\n### ")[0]
    cells = {}
    for line in block.splitlines():
        parts = [p.strip() for p in line.split("|")]
        if len(parts) > 6 and parts[2].startswith("`"):
            cells[parts[2].split("`")[1]] = parts[5]
    return cells


def test_a_better_best_known_score_is_a_record_and_moves_no_normalised_score(tmp_path, monkeypatch):
    root = tmp_path / "leaderboards"
    shutil.copytree(ROOT / "leaderboards", root, ignore=shutil.ignore_patterns("*.png"))
    before = _normalised_column(root)
    entry = json.loads((root / "v2" / "easy" / "cmaes_v2.json").read_text())
    mean_before = normalised_mean(entry, "v2")
    assert before and before["cmaes_v2"] == f"{mean_before:.3f}" and entry["episodes"][0]["task_index"] == 0
    assert "ref. " + reference.reference_sha256("v2")[:8] in leaderboard.render_readme(root)

    earlier = {(r["tier"], r["index"]): r["gain"] for r in freeze.records_since("v2")}  # records shipped so far
    improved = json.loads(best_known.best_known_path("v2").read_text())  # the search finds a better score on task 0
    task = next(r for r in improved["tasks"]["easy"]["test"] if r["index"] == 0)
    task["best"]["score"] *= 1.5
    copy = tmp_path / "v2_best_known.json"
    copy.write_text(json.dumps(improved))
    monkeypatch.setattr(best_known, "best_known_path", lambda version=None, split=None: copy)
    assert best_known.scores("easy", "test", 100, "v2")[0] == task["best"]["score"]  # the live file moved

    assert _normalised_column(root) == before  # ... and no published normalised score did
    assert f"{normalised_mean(entry, 'v2'):.17g}" == f"{mean_before:.17g}"
    found = {(r["tier"], r["index"]): r["gain"] for r in freeze.records_since("v2")}
    frozen = reference.reference_scores("easy", "test", "v2")[0]
    assert set(found) == set(earlier) | {("easy", 0)}
    assert found[("easy", 0)] == pytest.approx(task["best"]["score"] / frozen - 1.0)  # against the frozen score
    assert all(found[key] == gain for key, gain in earlier.items() if key != ("easy", 0))
    assert "Records since the reference was frozen" in tables.records_text("v2") and \
        f"by up to {max(found.values()):.1%}" in tables.records_text("v2")


def test_an_entry_scored_against_another_reference_is_refused_by_name(tmp_path):
    root = tmp_path / "leaderboards"
    shutil.copytree(ROOT / "leaderboards" / "v2" / "easy", root / "v2" / "easy")
    path = root / "v2" / "easy" / "cmaes_v2.json"
    entry = json.loads(path.read_text())
    entry["extra"]["reference_sha256"] = "0" * 64
    path.write_text(json.dumps(entry))
    problems = {e["_file"]: e["_problems"] for e in leaderboard.load_entries(root, spec_for_version("v2"))["easy"]}
    assert any("another reference" in p and reference.reference_sha256("v2")[:12] in p
               for p in problems["cmaes_v2.json"])


def test_the_reference_covers_every_scored_pool_and_is_written_once(tmp_path):
    data, _ = reference.load_reference("v2")
    for tier, splits in data["scores"].items():
        for split, values in splits.items():
            assert len(values) == len(pool(tier, split, version="v2")) and min(values) > 0.0, (tier, split)
    assert set(data["scores"]) == {"easy", "medium", "hard", "debris", "robust", "servo"}
    with pytest.raises(InvalidInputError, match="frozen"):
        freeze.freeze("v2")
    out = freeze.freeze("v2", out=tmp_path / "again.json")
    assert json.loads(out.read_text())["frozen_from"]["file"] == "v2_best_known.json"
