"""The resumable loop of the capture-v1 studies (``experiments/study_rows.py``): a stopped study resumes where it
stopped, computing only the rows its work file does not hold, in the jobs' order."""

from __future__ import annotations

import json

import pytest
from conftest import script_module


def test_a_study_resumes_where_it_stopped(tmp_path):
    rows = script_module("study_rows")
    work, calls = tmp_path / "work.json", []

    def compute(tier, seed, extra):
        calls.append((tier, seed))
        if seed == 3 and len(calls) == 3:
            raise KeyboardInterrupt  # stopped during the third row
        return {"tier": tier, "seed": seed, "value": extra * seed}

    jobs = [("sweep", 1, 10), ("sweep", 2, 10), ("nutation", 3, 10), ("nutation", 1, 10)]
    with pytest.raises(KeyboardInterrupt):
        rows.resumable_rows(work, jobs, compute, "test")
    assert [(r["tier"], r["seed"]) for r in json.loads(work.read_text())["rows"]] == [("sweep", 1), ("sweep", 2)]
    out = rows.resumable_rows(work, jobs, compute, "test")
    assert calls == [("sweep", 1), ("sweep", 2), ("nutation", 3), ("nutation", 3), ("nutation", 1)]
    assert [r["value"] for r in out] == [10, 20, 30, 10]
    assert rows.resumable_rows(work, jobs[::-1], compute, "test") == out[::-1] and len(calls) == 5


def test_publishing_writes_the_result_and_the_docs_block(tmp_path):
    rows = script_module("study_rows")
    page = tmp_path / "page.md"
    page.write_text("before\n<!-- s -->\nold\n<!-- e -->\nafter\n")
    rows.publish(tmp_path / "out.json", {"n": 2}, str(page), ("<!-- s -->", "<!-- e -->"), lambda d: f"n = {d['n']}\n")
    assert json.loads((tmp_path / "out.json").read_text()) == {"n": 2}
    assert "<!-- s -->\nn = 2\n<!-- e -->" in page.read_text() and page.read_text().startswith("before\n")
