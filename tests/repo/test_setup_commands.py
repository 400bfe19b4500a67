"""The README's two set-up commands: CI runs the second verbatim, and their times are generated."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import script_module

ROOT = Path(__file__).resolve().parents[2]


def test_ci_runs_the_readme_test_command_verbatim():
    _, tests = script_module("setup_time").setup_commands((ROOT / "README.md").read_text(encoding="utf-8"))
    lines = [line for line in (ROOT / ".ci" / "run").read_text().splitlines() if line and not line.startswith("#")]
    assert lines[-1].endswith(tests), f".ci/run must end with the README's test command: {tests}"
    assert "pip install" in tests and "pytest" in tests


def test_readme_setup_times_are_rendered_from_the_measurement():
    module = script_module("setup_time")
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    results = json.loads((ROOT / "experiments" / "setup_time.json").read_text())
    block = text.split(module.START + "\n")[1].split(module.END)[0]
    assert block == module.setup_text(results), "rerun: python experiments/setup_time.py --readme README.md"
    assert results["commands"]["tests"]["parts"][-1]["command"].endswith("pytest -q")
    assert results["provenance"]["git_commit"]


def test_setup_commands_need_the_section_and_two_one_line_blocks():
    module = script_module("setup_time")
    with pytest.raises(SystemExit, match="Set-up"):
        module.setup_commands("# no set-up here\n")
    with pytest.raises(SystemExit, match="two one-line bash blocks"):
        module.setup_commands("## Set-up: two commands\n```bash\na && b\n```\n## Next\n```bash\nc\n```\n")
    assert module.setup_commands("## Set-up: two commands\n```bash\na\n```\ntext\n```bash\nb && c\n```\n") == ("a", "b && c")


def test_durations_read_as_minutes_and_seconds():
    module = script_module("setup_time")
    assert module._duration(42.4) == "42 s"
    assert module._duration(141.0) == "2 min 21 s"
