"""Which entries ``ffsr-gym leaderboard update`` replays: those that changed since the board's last verified state.

An entry's last verified state is its stamp (:mod:`ffsr_gym.bench.stamp`): the hashes of the entry, its rows, its
pool file, the frozen reference and the code the replay ran. An entry is replayed when

* it has no stamp and git reports it added, changed or renamed since the last commit, or git cannot tell (a board
  outside a repository); an unstamped entry the last commit holds as it is was replayed by the pull-request
  workflow when it changed (or predates it: ``verify`` or ``--full`` replays it), and a frozen v0 entry never
  carries a stamp,
* its stamp no longer describes it (:func:`~ffsr_gym.bench.stamp.stamp_problems`: the entry, its rows, its pool or
  the reference changed), or its trace file is not the one it names (:mod:`~ffsr_gym.bench.trace_file`),
* the code a replay runs changed since (:func:`~ffsr_gym.bench.stamp.code_digest` of the entry's version: another
  version's rule, pool or reference file does not count), or the stamp predates the code's digest.

Every other entry is skipped, with the reason. ``--full`` replays them all.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ffsr_gym.bench.changes import changed_entries, entry_files
from ffsr_gym.bench.stamp import code_digest, stamp_problems
from ffsr_gym.bench.trace_file import file_problems, in_file
from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.user_files import parse_json, read_text
from ffsr_gym_lab.board.leaderboard import spec_of_entry


@dataclass(frozen=True)
class Step:
    """One entry file and what ``update`` does with it."""

    path: Path
    replay: bool
    reason: str


def plan(root: str | Path, *, full: bool = False) -> list[Step]:
    """Every entry file under ``root`` (:func:`~ffsr_gym.bench.changes.entry_files`), replayed or skipped."""
    root = Path(root)
    paths = [root / resolved.relative_to(root.resolve()) for resolved in entry_files(root)]
    if full:
        return [Step(path, True, "--full") for path in paths]
    try:
        changed: set[Path] | None = {path.resolve() for path in changed_entries(root, "HEAD")}
    except InvalidInputError:
        changed = None  # not in a git repository, or no commit yet
    return [_step(path, changed) for path in paths]


def _unstamped(path: Path, changed: set[Path] | None, why: str) -> Step:
    if changed is None:
        return Step(path, True, f"{why}; git cannot tell whether it changed")
    if path.resolve() in changed:
        return Step(path, True, f"{why}; added or changed since the last commit")
    return Step(path, False, f"{why}; unchanged since the last commit (verify or --full replays it)")


def _step(path: Path, changed: set[Path] | None) -> Step:
    try:
        entry = parse_json(read_text(path), str(path))
        if not isinstance(entry, dict):
            return Step(path, True, "not a JSON object")
        spec = spec_of_entry(entry)
    except FFSRError as exc:
        return Step(path, True, f"not an entry this version reads ({str(exc)[:80]})")
    extra = entry.get("extra")
    stamp = extra.get("verified") if isinstance(extra, dict) else None
    if spec.rules is None:
        return _unstamped(path, changed, f"{spec.version} is frozen and its entries carry no stamp")
    if stamp is None:
        return _unstamped(path, changed, "no stamp")
    problems = stamp_problems(entry, spec.rules.version)
    record = extra.get("trace")
    if not problems and in_file(record) and isinstance(entry.get("episodes"), list):
        problems = file_problems(record, path, len(entry["episodes"]))  # the trace file can change alone
    if problems:
        return Step(path, True, f"its stamp no longer describes it ({problems[0]})")
    if "code_sha256" not in stamp:
        return Step(path, True, "its stamp predates the code's digest: the code it ran cannot be compared")
    if stamp["code_sha256"] != code_digest(spec.rules.version):  # once per version: it hashes megabytes
        return Step(path, True, "the code a replay runs changed since it was verified (code_sha256 differs)")
    return Step(path, False, "stamped; entry, pool, reference and the code a replay runs unchanged since")
