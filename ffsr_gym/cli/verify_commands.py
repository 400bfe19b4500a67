"""The ``leaderboard`` group of sub-commands and its ``verify``: replay an entry and compare its rows (what a submitter
runs); the board's maintenance sub-commands join the group when the lab's commands are installed."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import InvalidInputError


def add_verify_commands(sub: Any) -> dict[str, Any]:
    """Sub-command leaderboard verify; returns the groups other commands may join (``{"leaderboard": ...}``)."""
    board = sub.add_parser("leaderboard", help="leaderboard entries: verify (and, with the lab's commands, tables and "
                                               "figures)")
    board_sub = board.add_subparsers(dest="action", required=True)
    verify = board_sub.add_parser("verify", help="replay an entry's trace (or planner, fixed parameters) and compare "
                                                 "its rows exactly (exit 0: reproduced, 1: differ, 3: skipped code; "
                                                 "over several: 1 if any differs)")
    verify.add_argument("entry", nargs="*", help="the entries' JSON files")
    verify.add_argument("--changed-since", default=None, metavar="REF",
                        help="replay every entry the tables read that was added, changed, renamed or copied since the "
                             "git commit REF (what the pull-request workflow replays), whatever its name")
    verify.add_argument("--root", default="leaderboards",
                        help="leaderboard root, for --changed-since (default: leaderboards)")
    verify.add_argument("--run-code", default=None, metavar="TEXT",
                        help="consent to run the code the entry names: exactly its extra.policy callable or SB3 .zip "
                             "(importing a file or unpickling a model runs code of its maker's choosing)")
    verify.add_argument("--stamp", action="store_true",
                        help="when reproduced, write the verification stamp (verifier, commit, pool, reference and "
                             "rows hashes) into the entry; the tables show it")
    verify.set_defaults(func=_verify)
    return {"leaderboard": board_sub}


def _verify(args: argparse.Namespace) -> int:
    from ffsr_gym.bench.changes import changed_entries
    from ffsr_gym.bench.replay import replay_entry

    if args.changed_since is not None:
        if args.entry:
            raise InvalidInputError("verify: give entry files or --changed-since, not both")
        paths = [str(path) for path in changed_entries(args.root, args.changed_since)]
        print(f"{len(paths)} entries added, changed or renamed since {args.changed_since}", file=sys.stderr)
    elif not args.entry:
        raise InvalidInputError("verify: no entry; allowed: one or more entry files, or --changed-since REF")
    else:
        paths = args.entry
    codes = {0}
    for path in paths:
        verdict = replay_entry(path, run_code=args.run_code)
        print(f"{path}: {verdict.status}: {verdict.text}", file=sys.stdout if verdict.exit_code == 0 else sys.stderr)
        if args.stamp and verdict.status == "reproduced":
            write_stamp(path, verdict.entry_text)
        codes.add(verdict.exit_code)
    return 1 if 1 in codes else max(codes)  # one that differs outweighs one skipped


def write_stamp(path: str, replayed: str) -> None:
    """Write the verification stamp into the entry just reproduced: into the text that was replayed, and only if the
    file still holds exactly that text (atomically; the rest of the file as it was)."""
    from ffsr_gym.bench.board_layout import spec_of_entry
    from ffsr_gym.bench.stamp import make_stamp
    from ffsr_gym.provenance import write_json_atomic
    from ffsr_gym.user_files import parse_json, read_text

    if Path(path).is_symlink():
        raise InvalidInputError(f"{path}: a symbolic link; allowed: stamp the entry file itself (nothing stamped)")
    if read_text(path) != replayed:
        raise InvalidInputError(f"{path}: the file changed while it was replayed; nothing stamped (verify it again)")
    entry = parse_json(replayed, path)
    spec = spec_of_entry(entry)
    if spec.rules is None:
        print(f"{path}: {spec.version} entries carry no stamp", file=sys.stderr)
        return
    entry["extra"]["verified"] = make_stamp(entry, spec.rules.version)
    write_json_atomic(path, entry, compact=True)
    print(f"{path}: stamped ({entry['extra']['verified']['verifier']})")
