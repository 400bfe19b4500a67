"""Which leaderboard entries a change touches: what ``ffsr-gym leaderboard verify --changed-since REF`` (the
pull-request workflow) replays.

An entry is any file the tables read (:func:`entry_files`: every ``*.json`` in a table's folder, whatever its name),
so a file named like a generated one (``aggregates.json``) in a table's folder is replayed like any other. The change
is git's: files added, copied, modified, renamed (the new name, edited or not) or changed in type since ``REF``, in
commits and in the working tree, and files not yet tracked. A changed trace file (``<name>.trace``) touches its entry.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

from ffsr_gym.bench.board_layout import folder_of, groups, table_files
from ffsr_gym.bench.trace_file import SUFFIX
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.versions.registry import all_specs

#: The longest a git query may take [s] (a hung repository is an error, not a wait).
GIT_TIMEOUT_S = 60.0


def entry_files(root: str | Path) -> list[Path]:
    """Every file a leaderboard table under ``root`` reads as an entry (:func:`~ffsr_gym.bench.board_layout.table_files`
    of each table's folder, in resolved folders, sorted)."""
    found: set[Path] = set()
    for spec in all_specs().values():
        for group in groups(spec):
            folder = folder_of(spec, root, group)
            if folder.is_dir():
                found.update(folder.resolve() / path.name for path in table_files(folder))
    return sorted(found)


def changed_entries(root: str | Path, since: str) -> list[Path]:
    """The entry files under ``root`` added, copied, modified, renamed or changed in type since the commit ``since``
    (its ancestors' files excluded), untracked ones included; paths as given under ``root``.

    Raises:
        InvalidInputError: ``root`` is not in a git repository, or ``since`` is not a commit of it (named).
    """
    root = Path(root)
    if not root.is_dir():
        raise InvalidInputError(f"--root {str(root)!r}: not a folder")
    top = Path(_git(root, "rev-parse", "--show-toplevel").strip())
    _git(root, "rev-parse", "--verify", "--quiet", f"{since}^{{commit}}", what=f"--changed-since {since!r}: not a "
         "commit of this repository (fetch it, e.g. git fetch origin main)")
    diff = _git(top, "diff", "--name-status", "-z", "-M", "-C", "--diff-filter=ACMRT", since, "--", str(root.resolve()))
    fields, touched = diff.split("\0"), set()
    k = 0
    while k < len(fields) - 1:
        status = fields[k]
        if status[:1] in "RC":  # a rename or copy lists the old then the new path
            touched.add(top / fields[k + 2])
            k += 3
        else:
            touched.add(top / fields[k + 1])
            k += 2
    untracked = _git(top, "ls-files", "-z", "--others", "--exclude-standard", "--", str(root.resolve()))
    touched.update(top / name for name in untracked.split("\0") if name)
    touched.update(path.with_suffix(".json") for path in list(touched) if path.suffix == SUFFIX)  # its entry's
    return [root / path.relative_to(root.resolve()) for path in entry_files(root) if path in touched]


def _git(where: Path, *args: str, what: str | None = None) -> str:
    try:
        done = subprocess.run(["git", "-C", str(where), *args], capture_output=True, text=True, timeout=GIT_TIMEOUT_S,
                              check=False)
    except FileNotFoundError:
        raise InvalidInputError("--changed-since needs git on the PATH") from None
    except subprocess.TimeoutExpired:
        raise InvalidInputError(f"git {args[0]} took over {GIT_TIMEOUT_S:.0f} s in {where}") from None
    if done.returncode != 0:
        raise InvalidInputError(what or f"{where}: git {args[0]} failed: {done.stderr.strip()[:300]}")
    return done.stdout
