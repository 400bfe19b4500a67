"""An entry's action trace: the actions each episode applied, so that ``verify`` replays a policy without running it.

A score is a function of the task and of the actions the env applied (clipped to [-1, 1], as
float32), nothing else. :func:`ffsr_gym.evaluate` records those actions for every policy that is
code (a callable, a model), one text per episode row: the float32 values, little-endian, row after
row, compressed with zlib and written as base64. Replaying them through the same env gives the
same rows bit for bit, so an RL or optimiser entry is checked without loading a model or importing
a file (``ffsr-gym leaderboard verify``).

A trace costs a few bytes a number: a residual policy's entry on the easy test pool (100 tasks of
200 decisions of 12 numbers) measured 0.72 MB with its trace as text. :meth:`ffsr_gym.EvalReport.save` writes the
trace to a compressed binary file beside the entry (:mod:`ffsr_gym.bench.trace_file`); in memory, and in entries
written before, it is this text.

The env clips an action outside [-1, 1] and counts it (``info["clipped_actions"]``, the row's
``clipped_actions``). The trace keeps the applied, clipped action, and beside it, per row, the
decisions whose action was clipped (``clipped``): ``verify`` checks that each of those actions lies
on the box's boundary and that the row's count is their number.
"""

from __future__ import annotations

import base64
import binascii
import zlib
from typing import Any

import numpy as np

from ffsr_gym.exceptions import InvalidInputError

#: How the actions are written (recorded in the entry, checked on replay).
TRACE_FORMAT = "float32 little-endian, zlib, base64; one text per episode row"
#: The most decisions one episode's trace may hold (a bound on what a replay decompresses).
MAX_DECISIONS = 100_000


def encode(actions: np.ndarray) -> str:
    """One episode's applied actions, shape (decisions, action size), as trace text."""
    raw = np.ascontiguousarray(actions, dtype="<f4").tobytes()
    return base64.b64encode(zlib.compress(raw, 9)).decode("ascii")


def decode(text: Any, width: int, *, where: str) -> np.ndarray:
    """The actions of one trace text, shape (decisions, ``width``), float32.

    Raises:
        InvalidInputError: not a trace text, more than :data:`MAX_DECISIONS` decisions, a length that is
            not whole actions, or a value that is not finite or outside [-1, 1] (``where`` names it).
    """
    if not isinstance(text, str):
        raise InvalidInputError(f"{where}: a trace episode must be a text, got {type(text).__name__}")
    limit = MAX_DECISIONS * width * 4
    try:
        packed = base64.b64decode(text.encode("ascii"), validate=True)
        inflater = zlib.decompressobj()
        raw = inflater.decompress(packed, limit + 1)
    except (ValueError, UnicodeEncodeError, binascii.Error, zlib.error) as exc:
        raise InvalidInputError(f"{where}: not a trace ({TRACE_FORMAT}): {exc}") from None
    if len(raw) > limit or inflater.unconsumed_tail:
        raise InvalidInputError(f"{where}: more than {MAX_DECISIONS} decisions; allowed: at most {MAX_DECISIONS}")
    if len(raw) % (4 * width):
        raise InvalidInputError(f"{where}: {len(raw)} bytes are not whole actions of {width} float32 values")
    return check_actions(np.frombuffer(raw, dtype="<f4").reshape(-1, width).astype(np.float32), where=where)


def check_actions(actions: np.ndarray, *, where: str) -> np.ndarray:
    """``actions`` if every value is finite and in [-1, 1] (the env applies clipped actions only).

    Raises:
        InvalidInputError: naming ``where``.
    """
    if not np.all(np.isfinite(actions)) or np.any(np.abs(actions) > 1.0):
        raise InvalidInputError(f"{where}: an action value is not finite or outside [-1, 1] (the env applies "
                                "clipped actions only)")
    return actions


def trace_record(episodes: list[str], action_shape: tuple[int, ...], clipped: list[list[int]]) -> dict[str, Any]:
    """The entry's ``extra.trace``: the format, the action shape, one text per row and, per row, the decisions
    whose action the env clipped."""
    return {"format": TRACE_FORMAT, "action_shape": list(action_shape), "episodes": episodes, "clipped": clipped}


def clipped_counts(record: dict[str, Any], actions: list[np.ndarray], *, where: str) -> list[int] | None:
    """Each row's number of clipped actions, from the trace's ``clipped`` (None: a trace recorded before it).

    Raises:
        InvalidInputError: not one sorted list of distinct decision indices per row, or a listed decision whose
            action does not touch the box's boundary (a clipped action lies on it).
    """
    if "clipped" not in record:
        return None
    clipped = record["clipped"]
    if not isinstance(clipped, list) or len(clipped) != len(actions):
        raise InvalidInputError(f"{where}.clipped: allowed: one list of decision indices per row ({len(actions)})")
    counts = []
    for k, (indices, episode) in enumerate(zip(clipped, actions)):
        if (not isinstance(indices, list) or any(type(i) is not int for i in indices)
                or indices != sorted(set(indices)) or any(not 0 <= i < len(episode) for i in indices)):
            raise InvalidInputError(f"{where}.clipped[{k}]: allowed: sorted distinct decision indices in "
                                    f"[0, {len(episode)})")
        if indices and not np.all(np.max(np.abs(episode[indices]), axis=1) == 1.0):
            raise InvalidInputError(f"{where}.clipped[{k}]: a listed decision's action does not touch the box's "
                                    "boundary, where a clipped action lies")
        counts.append(len(indices))
    return counts


def trace_episodes(record: Any, rows: int, *, where: str) -> tuple[int, list[Any]]:
    """(action width, episode texts) of an entry's ``extra.trace``, checked against its number of rows.

    Raises:
        InvalidInputError: a malformed record (named).
    """
    if not isinstance(record, dict) or record.get("format") != TRACE_FORMAT:
        raise InvalidInputError(f"{where}: allowed: an object with format {TRACE_FORMAT!r}, action_shape, episodes")
    shape, episodes = record.get("action_shape"), record.get("episodes")
    if (not isinstance(shape, list) or len(shape) != 1 or isinstance(shape[0], bool) or not isinstance(shape[0], int)
            or not 1 <= shape[0] <= 64):
        raise InvalidInputError(f"{where}.action_shape = {shape!r}; allowed: [n] with 1 <= n <= 64")
    if not isinstance(episodes, list) or len(episodes) != rows:
        count = len(episodes) if isinstance(episodes, list) else type(episodes).__name__
        raise InvalidInputError(f"{where}.episodes: {count} traces for {rows} rows; allowed: one per row")
    return shape[0], episodes
