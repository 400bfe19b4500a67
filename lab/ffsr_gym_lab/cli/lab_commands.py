"""The lab's sub-commands, which the ``ffsr-gym`` command line loads from the ``ffsr_gym.commands`` entry point:
the leaderboard's maintenance (render, update, store, plot, aggregates, pareto), the task pools and best-known
searches (``tasks``), a study's archive (``study``), the datasets and the docs site's generated pages. A user's
install of the library alone has the rest: list, info, reproduce, ga, evaluate, render, train and leaderboard
verify."""

from __future__ import annotations

from typing import Any

from ffsr_gym_lab.cli.archive_commands import add_archive_commands
from ffsr_gym_lab.cli.board_commands import add_board_commands
from ffsr_gym_lab.cli.docs_commands import add_docs_commands
from ffsr_gym_lab.cli.study_commands import add_study_commands


def add_lab_commands(sub: Any, groups: dict[str, Any]) -> None:
    """Add the lab's sub-commands to ``sub``, and to the library's groups (``groups["leaderboard"]``)."""
    for add in (add_study_commands, add_archive_commands, add_board_commands, add_docs_commands):
        add(sub, groups)
