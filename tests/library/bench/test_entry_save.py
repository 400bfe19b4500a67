"""What ``EvalReport.save`` refuses in a leaderboard table: an entry of a checkout with uncommitted code changes,
unless asked for; elsewhere it takes it."""

from __future__ import annotations

import dataclasses
import json

import pytest

import ffsr_gym
from ffsr_gym.exceptions import InvalidInputError


@pytest.fixture(scope="module")
def report():
    return ffsr_gym.evaluate((0.0,) * 12, "FFSR-Residual-v2", task="easy", name="mine")


def test_a_dirty_checkouts_entry_is_refused_by_a_table_unless_asked_for(tmp_path, report, monkeypatch):
    monkeypatch.delenv("FFSR_GYM_ALLOW_DIRTY", raising=False)
    dirty = dataclasses.replace(report, provenance={**report.provenance, "git_dirty": True})
    table = tmp_path / "leaderboards" / "v2" / "easy"
    table.mkdir(parents=True)
    with pytest.raises(InvalidInputError, match="uncommitted code changes.*allow_dirty=True"):
        dirty.save(table)
    assert not list(table.iterdir())  # nothing written
    path = dirty.save(table, allow_dirty=True)
    assert json.loads(path.read_text())["provenance"]["git_dirty"] is True
    assert dirty.save(tmp_path).exists()  # not a table: the user's own folder takes it
    clean = dataclasses.replace(report, provenance={**report.provenance, "git_dirty": False})
    assert clean.save(table, overwrite=True).exists()
    monkeypatch.setenv("FFSR_GYM_ALLOW_DIRTY", "1")  # asked for once for a whole session
    assert dirty.save(table, overwrite=True).exists()


def test_the_command_line_refuses_before_any_work(tmp_path, monkeypatch, capsys):
    from ffsr_gym.cli.main import main
    from ffsr_gym.provenance import checkout_state

    monkeypatch.delenv("FFSR_GYM_ALLOW_DIRTY", raising=False)
    commit, _, source = checkout_state()
    monkeypatch.setattr("ffsr_gym.provenance.checkout_state", lambda: (commit, True, source))
    started = []
    monkeypatch.setattr("ffsr_gym.bench.evaluation.evaluate", lambda *a, **k: started.append(1))
    code = main(["evaluate", "--env-id", "FFSR-v2", "--policy", "0.3,4", "--task", "easy", "--name", "mine",
                 "--leaderboard", str(tmp_path / "board"), "--no-progress"])
    assert code == 2 and "--allow-dirty" in capsys.readouterr().err and not started
