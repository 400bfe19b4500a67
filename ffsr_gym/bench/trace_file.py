"""An entry's action trace in a binary file beside the entry (``<name>.trace``), bound to it by its sha256.

An entry of a policy that is code carries the actions the env applied (:mod:`ffsr_gym.bench.trace`). Written into
the entry's JSON as base64 text they made a residual RL entry 3.5-7.7 MB; :meth:`ffsr_gym.EvalReport.save` now
writes them beside the entry instead, and the entry's ``extra.trace`` keeps what reads them back: the file's name
(always ``<entry name>.trace``, in the entry's folder), its sha256 and size, the action shape, the number of
episodes and, per episode, the decisions whose action the env clipped. A changed, missing or swapped file fails the
sha256 and the entry is refused by name; ``ffsr-gym leaderboard verify`` replays the actions it holds.

The file (:data:`FILE_FORMAT`): the line ``ffsr-gym trace 1``, a JSON header line (action width, each episode's
number of decisions), then the actions as xz. Before compression each episode's float32 values are taken as their
32-bit patterns, each decision's minus the decision before's (modulo 2^32; consecutive actions share their high
bits), and split into byte planes (all first bytes, then all second bytes, ... of each action component): lossless,
and on the capture-v0 residual PPO entry 1.15 MB where the base64 text took 2.91 MB (raw float32: 5.18 MB).
Entries written before keep their text trace, which every reader still accepts.
"""

from __future__ import annotations

import hashlib
import json
import lzma
import re
from pathlib import Path
from typing import Any

import numpy as np

from ffsr_gym.bench.trace import MAX_DECISIONS, check_actions, decode
from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.provenance import write_bytes_atomic
from ffsr_gym.user_files import read_bytes

#: What ``extra.trace.format`` says of a trace in a file.
FILE_FORMAT = "ffsr-gym trace 1: float32 bit patterns, delta per episode, byte planes, xz; in <name>.trace"
SUFFIX = ".trace"
_MAGIC = b"ffsr-gym trace 1\n"
_SHA256 = re.compile(r"[0-9a-f]{64}")
#: The largest trace file read [bytes] (the biggest entry's, 1000 residual episodes, is about 3 MB).
MAX_FILE_BYTES = 256 * 2**20


def pack(episodes: list[np.ndarray], width: int) -> bytes:
    """The file's bytes of ``episodes`` (one float32 array of shape (decisions, ``width``) each)."""
    lengths = [int(len(a)) for a in episodes]
    patterns = []
    for actions in episodes:
        bits = np.ascontiguousarray(actions, dtype="<f4").reshape(-1, width).view("<u4")
        delta = bits.copy()
        delta[1:] -= bits[:-1]  # wraps modulo 2^32
        patterns.append(delta)
    planes = (np.concatenate(patterns) if patterns else np.zeros((0, width), "<u4")).view(np.uint8)
    planes = planes.reshape(-1, width, 4).transpose(2, 1, 0).tobytes()
    header = json.dumps({"width": width, "lengths": lengths}, separators=(",", ":")).encode() + b"\n"
    return _MAGIC + header + lzma.compress(planes, format=lzma.FORMAT_XZ, preset=9)


def unpack(data: bytes, width: int, episodes: int, *, where: str) -> list[np.ndarray]:
    """The episodes' actions of a trace file's bytes, checked as a text trace's are (:func:`trace.decode`).

    Raises:
        InvalidInputError: not a trace file, another width or number of episodes than the entry states, more than
            :data:`~ffsr_gym.bench.trace.MAX_DECISIONS` decisions an episode, or values outside [-1, 1] (named).
    """
    head, newline, rest = data[len(_MAGIC):].partition(b"\n")
    try:
        header = json.loads(head) if data.startswith(_MAGIC) and newline else None
    except ValueError:
        header = None
    lengths = header.get("lengths") if isinstance(header, dict) else None
    if (not isinstance(lengths, list) or header.get("width") != width or len(lengths) != episodes
            or not all(type(n) is int and 0 <= n <= MAX_DECISIONS for n in lengths)):
        raise InvalidInputError(f"{where}: not a trace file of {episodes} episodes of actions of width {width} "
                                f"({FILE_FORMAT})")
    size = 4 * width * sum(lengths)
    try:
        inflater = lzma.LZMADecompressor(format=lzma.FORMAT_XZ)
        planes = inflater.decompress(rest, max_length=size + 1)
    except lzma.LZMAError as exc:
        raise InvalidInputError(f"{where}: its actions do not decompress ({exc})") from None
    if len(planes) != size:
        raise InvalidInputError(f"{where}: {len(planes)} bytes of actions where its header states {size}")
    if not inflater.eof or inflater.unused_data:
        raise InvalidInputError(f"{where}: its actions do not decompress to one whole xz stream (cut short, or "
                                "followed by other bytes)")
    bits = np.frombuffer(planes, np.uint8).reshape(4, width, -1).transpose(2, 1, 0).copy().view("<u4")
    bits = bits.reshape(-1, width)
    out, start = [], 0
    for k, n in enumerate(lengths):
        actions = np.cumsum(bits[start:start + n], axis=0, dtype=np.uint32).astype("<u4").view("<f4")
        out.append(check_actions(actions.astype(np.float32), where=f"{where}: episode {k}"))
        start += n
    return out


def externalise(entry: dict[str, Any], path: Path) -> tuple[dict[str, Any], bytes | None]:
    """``entry`` to be written at ``path`` with its text trace moved to ``<name>.trace`` (the file's bytes; None
    when the entry has no text trace)."""
    record = (entry.get("extra") or {}).get("trace")
    if not isinstance(record, dict) or "episodes" not in record:
        return entry, None
    width = int(record["action_shape"][0])
    actions = [decode(text, width, where=f"{path}: extra.trace.episodes[{k}]")
               for k, text in enumerate(record["episodes"])]
    data = pack(actions, width)
    stored = {"format": FILE_FORMAT, "action_shape": [width], "file": path.stem + SUFFIX,
              "sha256": hashlib.sha256(data).hexdigest(), "bytes": len(data), "episodes_count": len(actions)}
    if "clipped" in record:
        stored["clipped"] = record["clipped"]
    return {**entry, "extra": {**entry["extra"], "trace": stored}}, data


def write_entry_files(path: Path, entry: dict[str, Any]) -> None:
    """Write ``entry`` at ``path``: its trace file first, then the JSON that names it (each atomically)."""
    _write(path, *externalise(entry, path))


def _write(path: Path, stored: dict[str, Any], data: bytes | None) -> None:
    """Write what :func:`externalise` returned: the trace file (when there is one), then the JSON."""
    from ffsr_gym.provenance import write_json_atomic

    if data is not None:
        write_bytes_atomic(path.with_name(path.stem + SUFFIX), data)
    write_json_atomic(path, stored, compact=True)


def in_file(record: Any) -> bool:
    """Whether an ``extra.trace`` names a trace file (else it holds text, or is malformed)."""
    return isinstance(record, dict) and record.get("format") == FILE_FORMAT


def file_problems(record: dict[str, Any], entry_path: Path, rows: int) -> list[str]:
    """Why the trace file an entry names is not the one it was written with (empty: it is): a name other than
    ``<entry name>.trace``, a missing or unreadable file, another size or sha256, another number of episodes."""
    return _checked_file(record, entry_path, rows)[1]


def _checked_file(record: dict[str, Any], entry_path: Path, rows: int) -> tuple[bytes | None, list[str]]:
    """(the trace file's bytes, none when it has a problem; :func:`file_problems`), the file read once."""
    name = record.get("file")
    if name != entry_path.stem + SUFFIX:
        return None, [f"extra.trace.file {str(name)[:80]!r}; allowed: {entry_path.stem + SUFFIX!r}, beside the entry"]
    if record.get("episodes_count") != rows:
        return None, [f"extra.trace.episodes_count {str(record.get('episodes_count'))[:20]!r}; allowed: {rows}, one "
                      "episode a row"]
    if not (isinstance(record.get("sha256"), str) and _SHA256.fullmatch(record["sha256"])):
        return None, ["extra.trace.sha256: allowed: the trace file's 64-digit hexadecimal sha256"]
    try:
        data = read_bytes(entry_path.with_name(name), max_bytes=MAX_FILE_BYTES)
    except FFSRError as exc:
        return None, [f"extra.trace.file: {exc}"]
    if hashlib.sha256(data).hexdigest() != record["sha256"] or len(data) != record.get("bytes"):
        return None, [f"extra.trace: {name} is not the file the entry was written with (its sha256 or size differs)"]
    return data, []


def read_actions(record: dict[str, Any], entry_path: Path, rows: int) -> list[np.ndarray]:
    """The applied actions of every row of an entry whose trace is in a file, checked against its sha256.

    Raises:
        InvalidInputError: any of :func:`file_problems`, or a file that does not decode (named).
    """
    shape = record.get("action_shape")
    if not (isinstance(shape, list) and len(shape) == 1 and type(shape[0]) is int and 1 <= shape[0] <= 64):
        raise InvalidInputError(f"{entry_path}: extra.trace.action_shape = {shape!r}; allowed: [n] with 1 <= n <= 64")
    data, problems = _checked_file(record, entry_path, rows)
    if problems:
        raise InvalidInputError(f"{entry_path}: {problems[0]}")
    return unpack(data, shape[0], rows, where=f"{entry_path.with_name(record['file'])}")


def read_entry(path: Path) -> Any:
    """An entry (or a study's evaluation) as its :meth:`EvalReport.to_json` gave it: the JSON at ``path`` with the
    actions of a trace file beside it read back (checked against its sha256) into trace text.

    Raises:
        InvalidInputError: unreadable JSON, or a trace file that is missing, changed or does not decode (named).
    """
    from ffsr_gym.bench.trace import TRACE_FORMAT, encode
    from ffsr_gym.user_files import parse_json, read_text

    entry = parse_json(read_text(path), str(path))
    record = (entry.get("extra") or {}).get("trace") if isinstance(entry, dict) else None
    if in_file(record):
        actions = read_actions(record, path, len(entry.get("episodes") or []))
        inline = {"format": TRACE_FORMAT, "action_shape": record["action_shape"],
                  "episodes": [encode(a) for a in actions]}
        if "clipped" in record:
            inline["clipped"] = record["clipped"]
        entry["extra"]["trace"] = inline
    return entry


def store_entries(paths: list[Path]) -> list[tuple[Path, int, int, bool]]:
    """Rewrite each entry not yet in the storage format (:func:`write_entry_files`): a trace written as text moves
    to a trace file beside it (the stamp dropped: the entry's content changed, ``ffsr-gym leaderboard update``
    replays and stamps it again; the actions are read back from the file and compared with the text's, bit for bit,
    before the entry is rewritten), and the JSON is written compact (its content, and so its stamp, unchanged: the
    text is parsed back and compared before it replaces the file). (entry, bytes before, bytes after: the entry and
    its trace file, whether its trace moved) of each entry rewritten.

    Raises:
        InvalidInputError: an entry that is not readable JSON, or a trace that does not decode (named).
    """
    from ffsr_gym.provenance import json_text, write_text_atomic
    from ffsr_gym.user_files import parse_json, read_text

    changed = []
    for path in paths:
        text = read_text(path)
        entry = parse_json(text, str(path))
        if not isinstance(entry, dict):
            continue
        record = (entry.get("extra") or {}).get("trace")
        if isinstance(record, dict) and "episodes" in record:
            entry["extra"].pop("verified", None)
            stored, data = externalise(entry, path)
            width = record["action_shape"][0]
            back = unpack(data, width, len(record["episodes"]), where=str(path))
            if any(a.tobytes() != decode(t, width, where=str(path)).tobytes()
                   for a, t in zip(back, record["episodes"])):
                raise InvalidInputError(f"{path}: its trace file does not read back as its text trace; nothing written")
            _write(path, stored, data)
            changed.append((path, len(text.encode("utf-8")), len(read_bytes(path)) + len(data), True))
            continue
        compact = json_text(entry, compact=True)
        if compact == text:
            continue
        if json.loads(compact) != entry:
            raise InvalidInputError(f"{path}: its compact text does not parse back to the entry; nothing written")
        write_text_atomic(path, compact)
        beside = path.with_name(path.stem + SUFFIX)
        extra = beside.stat().st_size if in_file(record) and beside.is_file() else 0
        changed.append((path, len(text.encode("utf-8")) + extra, len(compact.encode("utf-8")) + extra, False))
    return changed
