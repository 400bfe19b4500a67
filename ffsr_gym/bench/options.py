"""Checks of command-line options and output places, made before any work starts.

The ``argparse`` types (:func:`positive_int`, :func:`natural`, :func:`positive_float`,
:func:`scheduler`) make a bad number or address an ``ffsr-gym: error: argument --x: ...`` line naming
the option and the allowed range; :func:`writable_folder` and :func:`free_entry` refuse an output
place that would lose the run's result at its end (a file where a folder is needed, a folder without write
permission, an entry that a previous run saved).
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

from ffsr_gym.exceptions import InvalidInputError


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None


def positive_int(text: str) -> int:
    """An integer >= 1 (chunks, workers, steps, intervals)."""
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value}; allowed: an integer >= 1")
    return value


def natural(text: str) -> int:
    """An integer >= 0 (a seed)."""
    value = _integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value}; allowed: an integer >= 0")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (a speed)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value) or value <= 0.0:
        raise argparse.ArgumentTypeError(f"{value}; allowed: a finite number > 0")
    return value


def scheduler(text: str) -> str:
    """``--scheduler``: ``local:N`` or a Dask scheduler's address, checked by :func:`ffsr_gym.cluster.parse_scheduler`."""
    from ffsr_gym.cluster import parse_scheduler

    try:
        parse_scheduler(text)
    except InvalidInputError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix(f"--scheduler {text!r}; ")) from None
    return text


def add_scheduler_option(parser: argparse.ArgumentParser, pieces: str) -> None:
    """The ``--scheduler`` option of every long command, whose ``pieces`` run on the cluster it names."""
    parser.add_argument("--scheduler", type=scheduler, default=None, metavar="ADDRESS",
                        help=f"run the {pieces} on a Dask cluster: a scheduler's address (tcp://host:8786) or local:N "
                             "(N single-threaded worker processes here); the same results as a local run "
                             "(docs/cluster.md) (default: none)")


def writable_folder(path: str | Path, option: str) -> Path:
    """``path`` as a folder this process can write into (created if missing).

    Raises:
        InvalidInputError: it is a file, or it (or its nearest existing parent) cannot be written.
    """
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InvalidInputError(f"{option} {str(path)!r} is a file; allowed: a folder")
    existing = path
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise InvalidInputError(f"{option} {str(path)!r}: {str(existing)!r} is a file; allowed: a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InvalidInputError(f"{option} {str(path)!r}: {str(existing)!r} is not writable")
    return path


def free_entry(folder: str | Path, name: str, *, force: bool, option: str = "--leaderboard",
               allow_dirty: bool | None = True) -> Path:
    """The path an entry named ``name`` would take in ``folder``, checked before any work.

    Raises:
        InvalidInputError: an entry of that name exists (and ``force`` is off), the folder cannot be written, or
            (``allow_dirty`` off) the folder is a leaderboard table and the code runs from a checkout with
            uncommitted changes, which :meth:`ffsr_gym.EvalReport.save` would refuse after the run.
    """
    from ffsr_gym.bench.board_layout import leaderboard_table
    from ffsr_gym.provenance import checkout_state, dirty_allowed

    table = leaderboard_table(Path(folder)) is not None
    if table and not dirty_allowed(allow_dirty) and checkout_state()[1]:
        raise InvalidInputError(f"{folder} is a leaderboard table and this checkout has uncommitted code changes "
                                "(git status): commit them first, or pass --allow-dirty (the table marks the entry "
                                "+dirty)")
    folder = writable_folder(folder, option)
    path = folder / f"{name}.json"
    if path.exists() and not force:
        raise InvalidInputError(f"{str(path)!r} exists: a previous result would be replaced; choose another --name, "
                                "or pass --force to replace it")
    return path


def unique_seeds(seeds: list[int]) -> list[int]:
    """Training seeds, each once.

    Raises:
        InvalidInputError: a seed given twice (one agent would count twice in the entry).
    """
    repeated = sorted({s for s in seeds if seeds.count(s) > 1})
    if repeated:
        raise InvalidInputError(f"--seeds {seeds}: {repeated} given more than once; allowed: distinct seeds >= 0")
    return seeds
