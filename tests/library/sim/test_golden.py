"""Golden numbers of the reference runs on `paper`, stored with the hash of the files they came from.

A change that moves them must be deliberate: regenerate with tests/library/sim/golden/regenerate.py, bump the
env version (docs/envs.md) and add a CHANGELOG line.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent / "golden"))
from regenerate import compute  # noqa: E402

GOLDEN = json.loads((Path(__file__).parent / "golden" / "paper.json").read_text())


@pytest.fixture(scope="module")
def current():
    return compute()


def test_scenario_and_robot_files_unchanged(current):
    assert current["scenario_sha256"] == GOLDEN["scenario_sha256"], (
        "paper.toml or the robot files changed: regenerate the golden numbers and bump the env version")


def _close(a, b):
    if isinstance(a, dict):
        return all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return all(_close(x, y) for x, y in zip(a, b))
    if a is None or b is None or isinstance(a, bool):
        return a == b
    return math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-9)


@pytest.mark.parametrize("name", sorted(GOLDEN["runs"]))
def test_reference_run_metrics_unchanged(current, name):
    got, want = current["runs"][name], GOLDEN["runs"][name]
    for key in want:
        assert _close(want[key], got[key]), f"{name}.{key}: {got[key]} != golden {want[key]}"
