"""Reading files a user or a pull request brings (entries, scenarios, robot files): bounded, regular, named errors.

Every reader here refuses, by name and before parsing, a path that is not a regular file (a FIFO
would hang the reader, a link to ``/dev/zero`` would fill memory), a file larger than its bound,
and a document nested deeper than :data:`MAX_DEPTH` (Python's parsers recurse: 100,000 nested
arrays end in a ``RecursionError``, or worse).
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any

import numpy as np

from ffsr_gym.exceptions import UserFileError

#: The largest entry, scenario or robot file read [bytes]: a 100-task residual entry with its trace is about 2 MB,
#: the best-known files about 5 MB.
MAX_FILE_BYTES = 64 * 2**20
#: The deepest nesting of a JSON or TOML document (the project's own files nest at most 6 deep).
MAX_DEPTH = 32


def check_regular(path: str | Path, *, max_bytes: int = MAX_FILE_BYTES) -> Path:
    """``path`` if it is a regular file (after links) of at most ``max_bytes``.

    Raises:
        UserFileError: missing, not a regular file, unreadable or larger than ``max_bytes`` (named).
    """
    path = Path(path)
    try:
        info = os.stat(path)
    except OSError as exc:
        raise UserFileError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(info.st_mode):
        raise UserFileError(f"{path}: not a regular file (a FIFO, device, socket or folder); allowed: a regular file")
    if info.st_size > max_bytes:
        raise UserFileError(f"{path}: {info.st_size:,} bytes; allowed: at most {max_bytes:,}")
    return path


def read_bytes(path: str | Path, *, max_bytes: int = MAX_FILE_BYTES) -> bytes:
    """The bytes of a regular file of at most ``max_bytes``.

    Raises:
        UserFileError: as :func:`check_regular`.
    """
    path = check_regular(path, max_bytes=max_bytes)
    try:
        with open(path, "rb") as handle:
            data = handle.read(max_bytes + 1)
    except OSError as exc:
        raise UserFileError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    if len(data) > max_bytes:  # grew since the check
        raise UserFileError(f"{path}: more than {max_bytes:,} bytes; allowed: at most {max_bytes:,}")
    return data


def read_text(path: str | Path, *, max_bytes: int = MAX_FILE_BYTES) -> str:
    """The UTF-8 text of a regular file of at most ``max_bytes``.

    Raises:
        UserFileError: as :func:`check_regular`, or not UTF-8 text.
    """
    data = read_bytes(path, max_bytes=max_bytes)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise UserFileError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None


def nesting_depth(text: str) -> int:
    """An upper bound of how deep ``text`` nests brackets (strings included: a bound, never an underestimate).

    The depth after each character, never below 0 (an extra closing bracket is ignored), is the running sum of
    +1 / -1 minus the lowest the sum has been below 0; computed on the UTF-8 bytes, where ASCII brackets keep
    their places.
    """
    data = np.frombuffer(text.encode("utf-8", "surrogatepass"), dtype=np.uint8)
    step = np.zeros(len(data), dtype=np.int32)
    for chars, sign in (("[{", 1), ("]}", -1)):  # ASCII: one byte each in UTF-8
        for char in chars:
            step[data == ord(char)] = sign
    running = np.cumsum(step, dtype=np.int64)
    return int(np.max(running - np.minimum(np.minimum.accumulate(running), 0), initial=0))


def check_depth(text: str, where: str, *, max_depth: int = MAX_DEPTH) -> None:
    """Refuse a document whose brackets nest deeper than ``max_depth`` before a recursive parser sees it.

    Raises:
        UserFileError: naming ``where`` and the bound.
    """
    if nesting_depth(text) > max_depth and _parsed_depth(text) > max_depth:
        raise UserFileError(f"{where}: nested deeper than {max_depth} levels; allowed: at most {max_depth}")


def _parsed_depth(text: str) -> int:
    """The brackets' nesting outside quoted strings (the exact bound, when the cheap one is exceeded)."""
    depth = deepest = 0
    quote, escaped = "", False
    for char in text:
        if quote:
            escaped, quote = (not escaped and char == "\\"), ("" if char == quote and not escaped else quote)
        elif char in "\"'":
            quote = char
        elif char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth = max(0, depth - 1)
    return deepest


def parse_json(text: str, where: str) -> Any:
    """The JSON document ``text`` (read from ``where``), its depth bounded before the parser sees it.

    Strict where Python's parser is lenient: a key given twice in one object (which of the two would count is a
    matter of parser, so a forged value can hide before a genuine one) and ``NaN`` / ``Infinity`` (not JSON) are
    refused.

    Raises:
        UserFileError: as :func:`check_depth`, not JSON (named with the position), a repeated key or a non-finite
            constant (named).
    """
    check_depth(text, where)
    try:
        return json.loads(text, object_pairs_hook=_unique_keys, parse_constant=_no_constant)
    except _StrictJSONError as exc:
        raise UserFileError(f"{where}: {exc}") from None
    except (ValueError, RecursionError) as exc:
        raise UserFileError(f"{where}: not JSON ({exc})") from None


class _StrictJSONError(Exception):
    """A document JSON's grammar allows and this package refuses (raised inside the parser's hooks)."""


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out = dict(pairs)
    if len(out) != len(pairs):
        seen: set[str] = set()
        twice = next(key for key, _ in pairs if key in seen or seen.add(key))
        raise _StrictJSONError(f"key {twice[:60]!r} appears twice in one object; allowed: each key once")
    return out


def _no_constant(name: str) -> Any:
    raise _StrictJSONError(f"{name} is not a JSON number; allowed: finite numbers (or null)")


def load_json(path: str | Path, *, max_bytes: int = MAX_FILE_BYTES) -> Any:
    """A JSON document from a regular file, bounded in size and depth.

    Raises:
        UserFileError: as :func:`read_text` and :func:`parse_json`.
    """
    return parse_json(read_text(path, max_bytes=max_bytes), str(path))


#: The most a robot folder's files may hold together [bytes] (the scenario hash reads every one).
MAX_FOLDER_BYTES = 256 * 2**20


def hash_files(digest: Any, paths: list[Path], *, names: bool = True, max_bytes: int = MAX_FOLDER_BYTES) -> None:
    """Feed each path's name (unless not ``names``) and bytes into ``digest``, streamed, refusing non-regular files
    and more than ``max_bytes`` in all.

    Raises:
        UserFileError: a file that is not regular or unreadable, or too many bytes in all (named).
    """
    total = 0
    for path in paths:
        total += check_regular(path, max_bytes=max_bytes).stat().st_size
        if total > max_bytes:
            raise UserFileError(f"{path.parent}: its files hold more than {max_bytes:,} bytes; allowed: at most "
                                f"{max_bytes:,} (every file of a robot folder enters the scenario hash)")
        if names:
            digest.update(path.name.encode())
        try:
            with open(path, "rb") as handle:
                for block in iter(lambda: handle.read(2**20), b""):
                    digest.update(block)
        except OSError as exc:
            raise UserFileError(f"{path}: cannot be read ({exc.strerror or exc})") from None
