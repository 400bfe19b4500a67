"""Sub-commands of a study's archive: ``study archive``, ``study restore`` and ``study missing``
(:mod:`ffsr_gym_lab.studies.archive`)."""

from __future__ import annotations

import argparse
from typing import Any


def add_archive_commands(sub: Any, groups: dict[str, Any]) -> None:
    """The ``study`` group (``groups``: the library's groups; none is joined)."""
    study = sub.add_parser("study", help="a study folder's bulky outputs out of the tree and back")
    study_sub = study.add_subparsers(dest="action", required=True)
    pack = study_sub.add_parser("archive", help="move the files of a study folder that match --pattern into one "
                                                "tar.xz archive out of the tree, recorded by sha256 in the folder's "
                                                "archive.json")
    pack.add_argument("folder", help="the study folder (e.g. studies/rl-capture-v0)")
    pack.add_argument("--pattern", action="append", required=True,
                      help="glob relative to the folder, e.g. '*/evaluation*.trace'; repeat for more")
    pack.add_argument("--out", required=True, help="the archive to write (outside the folder), e.g. "
                                                   "release/rl-capture-v0-traces.tar.xz")
    pack.add_argument("--url", default=None, help="where the archive is published, recorded in the manifest "
                                                  "(default: none)")
    pack.set_defaults(func=_archive)
    back = study_sub.add_parser("restore", help="bring an archive's files back into the study folder, each checked "
                                                "against its recorded sha256")
    back.add_argument("folder", help="the study folder")
    back.add_argument("--from", dest="source", required=True,
                      help="the archive: a local path, an http(s) URL, or git:<commit> (git: alone: the commit the "
                           "manifest records) to read the files from the repository's history")
    back.add_argument("--archive", default=None, help="which recorded archive (default: the only one)")
    back.set_defaults(func=_restore)
    gone = study_sub.add_parser("missing", help="list the archived files not in the folder now")
    gone.add_argument("folder", help="the study folder")
    gone.set_defaults(func=_missing)


def _archive(args: argparse.Namespace) -> None:
    from ffsr_gym_lab.studies.archive import MANIFEST, pack

    record = pack(args.folder, args.pattern, args.out, url=args.url)
    total = sum(f["bytes"] for f in record["files"].values())
    print(f"archived {len(record['files'])} files ({total / 1e6:.2f} MB) into {args.out} ({record['bytes'] / 1e6:.2f} "
          f"MB, sha256 {record['sha256']}); recorded in {args.folder}/{MANIFEST}")


def _restore(args: argparse.Namespace) -> None:
    from ffsr_gym_lab.studies.archive import restore

    written = restore(args.folder, args.source, archive=args.archive)
    print(f"restored {len(written)} files into {args.folder}")


def _missing(args: argparse.Namespace) -> int:
    from ffsr_gym_lab.studies.archive import missing

    names = missing(args.folder)
    print("\n".join(names) if names else "every archived file is in the folder")
    return 0
