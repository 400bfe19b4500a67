"""The capture v2 preview (``experiments/capture_v2_preview.py``): its subsets are the robust study's certified
tasks and, of those, the ones where the board's default entry fails going straight in at dt and its dt/4 replay
fails too; its docs block is its result rendered."""

from __future__ import annotations

import json
from pathlib import Path

from conftest import script_module

from ffsr_gym.tasks.splits import pool

ROOT = Path(__file__).resolve().parents[3]


def _json(name: str) -> dict:
    return json.loads((ROOT / "experiments" / name).read_text())


def test_the_subsets_follow_the_robust_study_and_the_default_entry():
    data, robust = _json("capture_v2_preview.json"), _json("capture_v1_robust.json")
    fine = _json("paired_groups_dt.json")
    study = script_module("capture_v2_preview")
    for s in data["summary"]:
        tier = s["tier"]
        certified = next(r for r in robust["summary"] if r["tier"] == tier)["certified"]
        assert s["tasks"][study.SUBSETS[1]] == certified
        board = json.loads((ROOT / "leaderboards" / "capture-v1" / tier / f"{study.DEFAULT}.json").read_text())
        failed = {row["task_index"] for row in board["episodes"] if not row["success"]}
        fails_fine = {r["index"] for r in fine["rows"] if r["tier"] == tier and r["scores"][study.DEFAULT] == 0.0}
        seeds = [t.seed for t in pool(tier, "test", version="capture-v1")]
        kept = {r["seed"] for r in robust["rows"] if r["tier"] == tier and r["certificate"] is not None}
        both = [i for i, seed in enumerate(seeds) if seed in kept and i in failed and i in fails_fine]
        assert s["tasks"][study.SUBSETS[2]] == len(both) > 0
        default = next(e for e in s["entries"] if e["entry"] == study.DEFAULT)
        assert default[study.SUBSETS[2]]["mean"] == 0.0 < default[study.SUBSETS[1]]["mean"]


def test_the_docs_block_is_the_result_rendered():
    study = script_module("capture_v2_preview")
    page = (ROOT / "docs" / "model.md").read_text()
    block = page[page.index(study.START) + len(study.START):page.index(study.END)]
    assert block.strip() == study.docs_text(_json("capture_v2_preview.json")).strip()
