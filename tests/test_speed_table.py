"""The speed page's tables are the one ``benchmarks/bench.py`` renders from its committed results."""

from __future__ import annotations

import json
from pathlib import Path

from conftest import benchmark_script

ROOT = Path(__file__).resolve().parents[1]


def test_the_speed_tables_are_rendered_from_the_results():
    bench = benchmark_script("bench")
    results = json.loads((ROOT / "benchmarks" / "results.json").read_text())
    text = (ROOT / "docs" / "speed.md").read_text(encoding="utf-8")
    block = text.split(bench.README_START + "\n")[1].split(bench.README_END)[0]
    assert block == bench.speed_table(results), "rerun: python benchmarks/bench.py --runs 3 --readme docs/speed.md"
    budget = text.split(bench.BUDGET_START + "\n")[1].split(bench.BUDGET_END)[0]
    assert budget == bench.budget_table(results), "rerun: python benchmarks/bench.py --runs 3 --readme docs/speed.md"
    kernel = text.split(bench.KERNEL_START + "\n")[1].split(bench.KERNEL_END)[0]
    assert kernel == bench.kernel_table(results), "rerun: python benchmarks/bench.py --runs 3 --readme docs/speed.md"
    assert results["provenance"]["git_commit"] and len(results["runs"]) == 3


def test_speed_table_ranges_and_verdicts():
    bench = benchmark_script("bench")
    row = {"key": "x", "what": "w", "unit": "ms", "reference": "r", "target": "t"}
    runs = [[row | {"value": v, "ratio": q, "met": m}] for v, q, m in ((2.0, 1.5, True), (3.0, 0.5, False))]
    table = bench.speed_table({"machine": "m", "runs": runs})
    assert "| w | 2-3 ms | r (last run) | 0.50-1.50 | t | in some runs |" in table



def test_floor_line_shares():
    """The kernel table's floor: cores x clock x operations per cycle / operations per step, and the batched share."""
    bench = benchmark_script("bench")
    results = {"operations": {"step": 10_000}, "clock_ghz": 2.5, "workers": 2,
               "runs": [[{"key": "batched", "value": 250_000.0}], [{"key": "batched", "value": 300_000.0}]]}
    line = bench.floor_line(results)
    assert "could run 1,000,000 steps/s, and 8,000,000 at the AVX2 peak" in line
    assert "250,000-300,000 steps/s: 25-30 % of the scalar floor, 3.1-3.8 % of the vector one." in line
    assert bench.floor_line(results | {"clock_ghz": None}).endswith("`operation_counts`).")
