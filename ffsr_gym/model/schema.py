"""The validation language of the data files (scenarios, robots' sections, benchmark specs and rules).

A file's table is loaded into a frozen dataclass whose fields declare, in their ``metadata``,
what they accept: :func:`number`, :func:`vector`, :func:`rows`, :func:`natural`,
:func:`choice`, :func:`section` (a nested table), :data:`BOOL`, :data:`TEXT` or :data:`TEXTS`.
:func:`build_table` checks every key against its declaration and raises
:class:`~ffsr_gym.exceptions.ScenarioError` naming the key, the value and what is allowed.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import FFSRError, ScenarioError
from ffsr_gym.user_files import check_depth, read_text

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

Vec = tuple[float, ...]
BOOL = {"kind": "bool"}
TEXT = {"kind": "text"}
TEXTS = {"kind": "texts"}
#: The most draws a randomised family or a capture draw may try (a draw costs 0.1-0.3 ms: at most a few seconds
#: before a family whose ranges admit nothing is refused by name).
MAX_DRAW_ATTEMPTS = 10_000


#: The most steps an episode may take: its logs (and a tumbling target's motion) are held in memory for the whole
#: episode, so a longer one is refused at load, not by a MemoryError at reset.
MAX_EPISODE_STEPS = 200_000


def episode_steps_problem(duration_s: float, dt_s: float) -> str | None:
    """Why an episode of ``duration_s`` at steps of ``dt_s`` is too long to hold (None: it is not)."""
    steps = duration_s / dt_s
    if steps <= MAX_EPISODE_STEPS + 0.5:
        return None
    return (f"{duration_s} s / {dt_s} s = {round(steps):,} steps; allowed: at most {MAX_EPISODE_STEPS:,} steps in an "
            "episode (a longer step, or a shorter episode)")


def number(lo: float, hi: float, *, lo_open: bool = False, hi_open: bool = False) -> dict:
    """A real number in [lo, hi] (an open end excludes its bound)."""
    return {"kind": "number", "lo": lo, "hi": hi, "lo_open": lo_open, "hi_open": hi_open}


def vector(size: int, lo: float = -math.inf, hi: float = math.inf) -> dict:
    """A list of ``size`` numbers, each within [lo, hi]."""
    return {"kind": "vector", "size": size, "lo": lo, "hi": hi}


def interval(lo: float = -math.inf, hi: float = math.inf) -> dict:
    """A range ``[low, high]`` drawn from: two numbers within [lo, hi], low <= high."""
    return {"kind": "interval", "size": 2, "lo": lo, "hi": hi}


def count(lo: int, hi: int) -> dict:
    """A whole number in [lo, hi] (attempts), written as an integer; kept as a float, as the numbers it replaced
    were (the hashes of the files that hold one do not change)."""
    return {"kind": "count", "lo": lo, "hi": hi}


def rows(size: int, lo: float, hi: float, max_rows: int) -> dict:
    """A list of up to ``max_rows`` entries: numbers (``size`` 0) or ``size``-vectors, each within [lo, hi]."""
    return {"kind": "rows", "size": size, "lo": lo, "hi": hi, "max_rows": max_rows}


def natural(hi: int) -> dict:
    """An integer in [0, hi] (a seed)."""
    return {"kind": "natural", "hi": hi}


def integer(*options: int) -> dict:
    """One of the listed integers (a schema version)."""
    return {"kind": "integer", "options": options}


def choice(*options: str) -> dict:
    """One of the listed strings."""
    return {"kind": "choice", "options": options}


def section(cls: type, *, key: str | None = None) -> dict:
    """A nested table, validated as the frozen dataclass ``cls``; ``key``: its name in the file, when the
    attribute's name differs."""
    return {"kind": "section", "cls": cls, **({"key": key} if key else {})}


def file_key(f: dataclasses.Field) -> str:
    """A field's key in the data file (its ``key`` metadata, else its name)."""
    return f.metadata.get("key", f.name)


def build_table(cls: type, table: Any, *, prefix: str = "") -> Any:
    """A validated frozen dataclass ``cls`` from a TOML table (fields declare their allowed values).

    A field named ``source`` is never read from the table (it records where the data came from).

    Raises:
        ScenarioError: unknown, missing, mistyped or out-of-range key (named with ``prefix``).
    """
    if not isinstance(table, dict):
        raise ScenarioError(f"key {prefix.rstrip('.') or '<root>'!r} must be a table, got {table!r}")
    fields = {file_key(f): f for f in dataclasses.fields(cls) if f.name != "source"}
    unknown = sorted(set(table) - set(fields))
    if unknown:
        raise ScenarioError(f"unknown key {prefix + unknown[0]!r}; allowed keys here: {sorted(fields)}")
    values = {}
    for name, spec in fields.items():
        key = prefix + name
        if name not in table:
            if spec.default is dataclasses.MISSING:
                raise ScenarioError(f"missing key {key!r} (required)")
            continue
        if spec.metadata.get("kind") == "section":
            values[spec.name] = build_table(spec.metadata["cls"], table[name], prefix=key + ".")
        else:
            values[spec.name] = convert(key, table[name], spec.metadata)
    return cls(**values)


def load_table(cls: type, path: str | Path) -> Any:
    """A validated frozen dataclass ``cls`` from a TOML file; every error names the file.

    Raises:
        ScenarioError: unreadable file, or an invalid key (named, with the file).
    """
    path = Path(path)
    try:
        text = read_text(path)
        check_depth(text, str(path))
        data: dict[str, Any] = tomllib.loads(text)
    except (FFSRError, tomllib.TOMLDecodeError) as exc:
        raise ScenarioError(f"{path}: not a readable TOML file ({exc})") from None
    try:
        return build_table(cls, data)
    except ScenarioError as exc:
        raise ScenarioError(f"{path}: {exc}") from None


def convert(key: str, value: Any, meta: Any) -> Any:
    """``value`` of ``key`` checked against its declaration ``meta`` (tuples for lists).

    Raises:
        ScenarioError: naming the key, the value and what is allowed.
    """
    kind = meta["kind"]
    if kind == "text":
        if not isinstance(value, str):
            raise ScenarioError(f"key {key!r} must be a string, got {value!r}")
        return value
    if kind == "texts":
        if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
            raise ScenarioError(f"key {key!r} must be a list of strings, got {value!r}")
        return tuple(value)
    if kind == "bool":
        if not isinstance(value, bool):
            raise ScenarioError(f"key {key!r} must be true or false, got {value!r}")
        return value
    if kind in ("choice", "integer"):
        if isinstance(value, bool) or value not in meta["options"]:
            raise ScenarioError(f"key {key!r} is {value!r}; allowed: {list(meta['options'])}")
        return int(value) if kind == "integer" else value
    if kind == "number":
        return check_number(key, value, meta)
    if kind == "rows":
        return _convert_rows(key, value, meta)
    if kind == "count":
        whole = isinstance(value, int) or (isinstance(value, float) and value.is_integer())
        if isinstance(value, bool) or not whole or not meta["lo"] <= value <= meta["hi"]:
            raise ScenarioError(f"key {key!r} is {value!r}; allowed: an integer in [{meta['lo']}, {meta['hi']}]")
        return float(value)
    if kind == "interval":
        low, high = convert(key, value, {**meta, "kind": "vector"})
        if low > high:
            raise ScenarioError(f"key {key!r} = {[low, high]}; allowed: [low, high] with low <= high (this range is "
                                f"reversed), each in [{meta['lo']}, {meta['hi']}]")
        return low, high
    if kind == "natural":
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= meta["hi"]:
            raise ScenarioError(f"key {key!r} is {value!r}; allowed: an integer in [0, {meta['hi']}]")
        return int(value)
    size = meta["size"]
    if not isinstance(value, (list, tuple)) or len(value) != size:
        raise ScenarioError(f"key {key!r} must be a list of {size} numbers, got {value!r}")
    return tuple(check_number(f"{key}[{i}]", v, meta) for i, v in enumerate(value))


def _convert_rows(key: str, value: Any, meta: dict) -> tuple:
    size, most = meta["size"], meta["max_rows"]
    shape = "numbers" if size == 0 else f"lists of {size} numbers"
    if not isinstance(value, (list, tuple)) or len(value) > most:
        raise ScenarioError(f"key {key!r} must be a list of at most {most} {shape}, got {value!r}")
    if size == 0:
        return tuple(check_number(f"{key}[{i}]", v, meta) for i, v in enumerate(value))
    row_meta = {**meta, "kind": "vector"}
    return tuple(convert(f"{key}[{i}]", row, row_meta) for i, row in enumerate(value))


def check_number(key: str, value: Any, meta: dict) -> float:
    """``value`` as a float inside the declared range of ``key``.

    Raises:
        ScenarioError: not a real number, not finite, or out of range.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ScenarioError(f"key {key!r} must be a number, got {value!r} ({type(value).__name__})")
    lo, hi = meta["lo"], meta["hi"]
    below = value <= lo if meta.get("lo_open") else value < lo
    above = value >= hi if meta.get("hi_open") else value > hi
    if not math.isfinite(value) or below or above:
        left = "(" if meta.get("lo_open") else "["
        right = ")" if meta.get("hi_open") else "]"
        raise ScenarioError(f"key {key!r} = {value!r} is out of range; allowed: {left}{lo}, {hi}{right}")
    return float(value)


def check_action_bounds(m_bounds: Vec, T_c_bounds_s: Vec, *, section: str, where: str = "") -> None:
    """Raise :class:`ScenarioError` unless both are [low, high] with low < high, and m's inside (0, 1)."""
    for key, (lo, hi) in ((f"{section}.m_bounds", m_bounds), (f"{section}.T_c_bounds_s", T_c_bounds_s)):
        is_m = key.endswith("m_bounds")
        if not lo < hi or (is_m and (lo <= 0.0 or hi >= 1.0)):
            raise ScenarioError(f"{where}key {key!r} = {[lo, hi]} is invalid; allowed: [low, high] with low < high"
                                + (" inside (0, 1)" if is_m else ""))
