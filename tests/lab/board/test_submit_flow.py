"""The Submit section of leaderboards/README.md, followed word for word on a copy of the leaderboards: its commands
run as written, and the check it names passes; a figure left stale fails it. With the published 2,000 bootstrap
resamples (``-m slow``) the aggregates of the new method, and the replays of every entry whose code changed since its
stamp; the figure check also has a test of its own (below)."""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import pytest

from ffsr_gym.cli.main import main

ROOT = Path(__file__).resolve().parents[3]

pytest.importorskip("rliable")


def _section_commands() -> list[list[str]]:
    text = (ROOT / "leaderboards" / "README.md").read_text(encoding="utf-8")
    section = text.split("## Submit a result")[1].split("\n## ")[0]
    blocks = re.findall(r"```bash\n(.*?)```", section, flags=re.S)
    commands = [shlex.split(line.strip()) for block in blocks for line in block.splitlines() if line.strip()]
    check = re.search(r"\*\*Check\*\*[^`]*`(ffsr-gym [^`]+)`", section).group(1)
    return commands + [shlex.split(check)]


def _shipped_code_digests() -> dict[str, str]:
    """The code digest each version's shipped stamps record (one per version: the board is stamped in one run)."""
    import json

    out = {}
    for folder in (ROOT / "leaderboards").iterdir():
        extras = [json.loads(path.read_text()).get("extra", {}) for path in folder.glob("*/*.json")]
        digests = {extra["verified"].get("code_sha256") for extra in extras if "verified" in extra}
        if digests:
            assert len(digests) == 1, (folder.name, digests)
            out[folder.name] = digests.pop()
    return out


def _commit_all(folder: Path) -> None:
    """``folder`` as a git checkout whose last commit holds everything in it."""
    import subprocess

    for args in (["init", "-q"], ["add", "-A"], ["-c", "user.name=submitter", "-c", "user.email=s@example.org",
                                                 "commit", "-qm", "the board"]):
        subprocess.run(["git", "-C", str(folder), *args], check=True, capture_output=True)


@pytest.mark.parametrize("reps", [100, pytest.param(None, marks=pytest.mark.slow)])
def test_the_submit_section_passes_as_written(tmp_path, monkeypatch, reps):
    """In CI with 100 bootstrap resamples for the aggregates instead of the published 2,000 (the rest as written):
    rliable's performance profiles take two minutes at 2,000."""
    if reps is not None:
        from ffsr_gym_lab.board import aggregates, update_plan

        monkeypatch.setattr(aggregates, "REPS", reps)
        # the board as stamped for this code: update replays the new entry (and the unstamped ones), not the
        # stamped board (test_update_plan checks that a change of code replays it)
        digests = _shipped_code_digests()  # read once: the board's entries are megabytes of JSON
        monkeypatch.setattr(update_plan, "code_digest", lambda version=None: digests[version])
    shutil.copytree(ROOT / "leaderboards", tmp_path / "leaderboards")
    shutil.copy(ROOT / "README.md", tmp_path / "README.md")
    (tmp_path / "docs").mkdir()
    shutil.copy(ROOT / "docs" / "baselines.md", tmp_path / "docs" / "baselines.md")
    (tmp_path / "my_policy.py").write_text("import numpy as np\n\ndef act(obs):\n    return np.array([0.1, -0.2], "
                                           "'float32')\n")
    _commit_all(tmp_path)  # a submitter works in a checkout: update replays what git reports new there
    monkeypatch.chdir(tmp_path)
    commands = _section_commands()
    assert [c[:3] for c in commands] == [["ffsr-gym", "evaluate", "--env-id"],
                                         ["ffsr-gym", "leaderboard", "update"], ["ffsr-gym", "leaderboard", "render"]]
    for command in commands:
        assert main([*command[1:], *(["--no-progress"] if command[1] == "evaluate" else [])]) == 0, command
    entry = tmp_path / "leaderboards" / "v2" / "easy" / "my_method_easy.json"
    assert entry.is_file() and "my_method" in (tmp_path / "docs" / "baselines.md").read_text()
    from ffsr_gym_lab.board.plots import stale_figures

    (tmp_path / "leaderboards" / "v2" / "iqm.png").write_bytes(b"stale")  # a figure left out of date
    assert stale_figures(tmp_path / "leaderboards")[0].endswith("iqm.png: not the one drawn")


def test_a_stale_figure_or_changed_inputs_fail_the_figure_check(tmp_path):
    from ffsr_gym_lab.board.plots import stale_figures

    board = tmp_path / "leaderboards"
    shutil.copytree(ROOT / "leaderboards" / "v2", board / "v2")
    assert stale_figures(board) == []
    (board / "v2" / "profiles.png").write_bytes(b"edited by hand")
    assert stale_figures(board) == [f"{board / 'v2' / 'profiles.png'}: not the one drawn"]
    shutil.copy(ROOT / "leaderboards" / "v2" / "profiles.png", board / "v2" / "profiles.png")
    entry = board / "v2" / "easy" / "cmaes_v2.json"
    entry.write_text(entry.read_text().replace('"score_mean": ', '"score_mean":  ', 1))  # same numbers: same inputs
    assert stale_figures(board) == []
    (board / "v2" / "easy" / "cmaes_v2.json").unlink()
    assert "inputs (entries, pareto, aggregates) changed" in stale_figures(board)[0]
