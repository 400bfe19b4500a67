"""The speed page's tables are the one ``experiments/bench.py`` renders from its committed results."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import script_module

ROOT = Path(__file__).resolve().parents[2]


def test_the_speed_tables_are_rendered_from_the_results():
    bench = script_module("bench")
    results = json.loads((ROOT / "experiments" / "results.json").read_text())
    text = (ROOT / "docs" / "speed.md").read_text(encoding="utf-8")
    block = text.split(bench.README_START + "\n")[1].split(bench.README_END)[0]
    assert block == bench.speed_table(results), "rerun: python experiments/bench.py --runs 3 --readme docs/speed.md"
    budget = text.split(bench.BUDGET_START + "\n")[1].split(bench.BUDGET_END)[0]
    assert budget == bench.budget_table(results), "rerun: python experiments/bench.py --runs 3 --readme docs/speed.md"
    guard = script_module("speed_guard")
    block = text.split(guard.START + "\n")[1].split(guard.END)[0]
    assert block == guard.guard_block(results), "rerun: python experiments/bench.py --runs 3 --readme docs/speed.md"
    assert results["provenance"]["git_commit"] and len(results["runs"]) == 3


def test_speed_table_ranges_and_verdicts():
    bench = script_module("bench")
    row = {"key": "x", "what": "w", "unit": "ms", "reference": "r", "target": "t"}
    runs = [[row | {"value": v, "ratio": q, "met": m}] for v, q, m in ((2.0, 1.5, True), (3.0, 0.5, False))]
    table = bench.speed_table({"machine": "m", "runs": runs})
    assert "| w | 2-3 ms | r (last run) | 0.50-1.50 | t | in some runs |" in table



def test_a_slower_row_is_flagged_against_the_committed_results():
    """Rates and times, raw and yardstick-scaled: a 6x slower batched rate is flagged, a machine twice as slow is
    not a regression once scaled, and a row within the tolerance is not flagged."""
    guard = script_module("speed_guard")

    def results(rate: float, time_us: float, yardstick: float | None) -> dict:
        rows = [{"key": "batched", "what": "batched", "value": rate, "unit": "physics steps/s"},
                {"key": "step", "what": "one step", "value": time_us, "unit": "us"}]
        return {"runs": [rows], "yardstick_s": yardstick, "provenance": {"git_commit": "abcdef0123"}}

    committed = results(410_000.0, 50.0, 0.1)
    flagged = guard.regressions(results(69_000.0, 52.0, 0.1), committed)
    assert len(flagged) == 1 and flagged[0].startswith("SLOWER 5.94x: batched") and "abcdef0" in flagged[0]
    assert guard.regressions(results(205_000.0, 100.0, 0.2), committed) == []  # the same code, a machine half as fast
    assert len(guard.regressions(results(205_000.0, 100.0, 0.1), committed)) == 2
    assert guard.regressions(results(330_000.0, 60.0, None), committed | {"yardstick_s": None}) == []  # raw: < 1.3x
    rollout = {"key": "rollout", "what": "rollout", "value": 7.0, "unit": "ms", "ratio": 280.0}  # Pinocchio 1.96 s
    old, slow_machine = committed | {"yardstick_s": None}, results(205_000.0, 100.0, None)
    old["runs"][0].append(rollout)
    slow_machine["runs"][0].append(rollout | {"value": 14.0})  # the machine twice as slow: Pinocchio 3.92 s
    assert guard.machine_scale(slow_machine, old) == (2.0, "Pinocchio rollout")
    assert guard.regressions(slow_machine, old) == []
    assert guard.yardstick_s(repeats=1) > 0.0


def test_the_speed_page_was_measured_on_the_newest_kernel():
    """The results the speed page is rendered from were measured at a commit that holds the newest change to
    ``ffsr_gym/kernel/``, ``src/native/`` or the build's flags (rerun ``python experiments/bench.py --runs 3 --readme
    docs/speed.md`` after a kernel change)."""
    import subprocess

    def git(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)

    newest = git("log", "-1", "--format=%H", "--", "ffsr_gym/kernel", "src/native", "CMakeLists.txt").stdout.strip()
    if not newest or git("rev-parse", "--is-shallow-repository").stdout.strip() == "true":
        pytest.skip("not a full git checkout: the history of ffsr_gym/kernel is not here")
    measured = json.loads((ROOT / "experiments" / "results.json").read_text())["provenance"]["git_commit"]
    assert git("merge-base", "--is-ancestor", newest, measured).returncode == 0, (
        f"docs/speed.md was measured at {measured[:7]}, before the kernel change {newest[:7]}: rerun "
        "python experiments/bench.py --runs 3 --readme docs/speed.md")
