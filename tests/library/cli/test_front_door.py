"""The ``ffsr-gym`` front door with the library alone, with the lab, and with a lab left over from another version.

The lab's commands arrive through the ``ffsr_gym.commands`` entry point group (docs/layout.md); these tests replace
what :func:`importlib.metadata.entry_points` returns for that group, so they need no second install.
"""

from __future__ import annotations

import argparse
import importlib.metadata

import pytest

from ffsr_gym.cli.main import COMMANDS, build_parser, main

USER_COMMANDS = {"list", "info", "reproduce", "ga", "evaluate", "render", "train", "leaderboard"}


def _commands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _only(monkeypatch, points):
    real = importlib.metadata.entry_points

    def entry_points(**select):
        return points if select.get("group") == COMMANDS else real(**select)

    monkeypatch.setattr(importlib.metadata, "entry_points", entry_points)


def test_the_library_alone_has_a_users_commands_only(monkeypatch):
    _only(monkeypatch, [])
    commands = _commands(build_parser())
    assert set(commands) == USER_COMMANDS
    assert set(_commands(commands["leaderboard"])) == {"verify"}


def test_the_lab_adds_its_commands():
    commands = _commands(build_parser())
    assert USER_COMMANDS | {"tasks", "dataset", "docs"} <= set(commands)
    assert {"verify", "render", "update", "store", "plot", "aggregates", "pareto"} <= set(
        _commands(commands["leaderboard"]))


@pytest.mark.parametrize("value", ["ffsr_gym_no_such_module:add", "ffsr_gym.cli.main:no_such_function"])
def test_a_lab_that_does_not_load_is_named_and_the_users_commands_still_work(monkeypatch, capsys, value):
    _only(monkeypatch, [importlib.metadata.EntryPoint(name="lab", value=value, group=COMMANDS)])
    commands = _commands(build_parser())
    assert set(commands) == USER_COMMANDS
    err = capsys.readouterr().err
    assert "warning" in err and value in err and "reinstall" in err


@pytest.mark.parametrize("argv, named", [(["tasks", "build", "--version", "v2"], "tasks"),
                                         (["leaderboard", "render", "--root", "my_board"], "leaderboard render"),
                                         (["study", "missing", "studies/rl-v2"], "study")])
def test_a_lab_command_without_the_lab_says_where_it_lives(monkeypatch, capsys, argv, named):
    _only(monkeypatch, [])
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"'{named}' is a command of the lab" in err and "pip install -e ./lab" in err


def test_a_users_command_and_a_typo_are_not_sent_to_the_lab(monkeypatch, capsys):
    _only(monkeypatch, [])
    assert main(["leaderboard", "rendr"]) == 2
    assert "invalid choice" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["leaderboard", "verify", "--help"])
    assert "lab" not in capsys.readouterr().err
