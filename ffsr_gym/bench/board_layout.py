"""Where a leaderboard's tables live and which version an entry belongs to: what saving or replaying one entry needs
to know of the board (the board's rendering, storage and maintenance are :mod:`ffsr_gym_lab.board.leaderboard`'s)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.spec import BenchmarkSpec
from ffsr_gym.versions.registry import all_specs, spec_for_env_id


def groups(spec: BenchmarkSpec) -> list[str]:
    """The tables of a version: one per env id (``{env_id}`` folders) or per tier (``{task}`` folders)."""
    return list(spec.tasks.tiers) if "{task}" in spec.leaderboard.folder else sorted(spec.env_ids)


def folder_of(spec: BenchmarkSpec, root: str | Path, group: str) -> Path:
    """The folder of one table's entries."""
    if "{task}" in spec.leaderboard.folder:
        return Path(root) / spec.folder(spec.ids.parameters, group)
    return Path(root) / spec.folder(group, "")


def table_files(folder: Path) -> list[Path]:
    """The files a table reads as its entries: every ``*.json`` in its folder, whatever its name (sorted)."""
    return sorted(folder.glob("*.json"))


def leaderboard_table(directory: str | Path) -> tuple[BenchmarkSpec, str] | None:
    """(spec, table) when ``directory`` is a leaderboard table folder by its path (it ends in the folder
    :func:`folder_of` gives that table under any root), else None."""
    parts = Path(directory).absolute().parts
    for spec in all_specs().values():
        for group in groups(spec):
            tail = folder_of(spec, "", group).parts
            if parts[-len(tail):] == tail:
                return spec, group
    return None


def spec_of_entry(entry: dict[str, Any]) -> BenchmarkSpec:
    """The version an entry belongs to: by its env id, else by the score rule its protocol names.

    Raises:
        InvalidInputError: neither names a known version.
    """
    spec = spec_for_env_id(str(entry.get("env_id", "")))
    if spec is not None:
        return spec
    protocol = entry.get("protocol")
    text = protocol.get("score") if isinstance(protocol, dict) else None
    for candidate in all_specs().values():
        if candidate.score.text == text:
            return candidate
    raise InvalidInputError(f"entry {entry.get('name')!r}: env_id {entry.get('env_id')!r} and score rule {text!r} "
                            "name no known benchmark version")
