"""The verification stamp: what ``ffsr-gym leaderboard verify --stamp`` writes into an entry it reproduced, and the
check that a stamp still describes the entry it sits in.

A stamp (``extra.verified``) names the verifier (the package version and the commit it ran from), the pool file and
frozen reference the entry was replayed against, the sha256 of the rows it reproduced, of the whole entry it
replayed (:func:`entry_digest`: every field but the stamp, its name included) and of the code the replay ran
(:func:`code_digest`, with its own version's data; ``leaderboard update`` replays an entry whose code changed since).
It proves nothing by itself (anyone can type one); what it states is checked: a stamp whose entry, rows, pool or
reference differ from the entry's and the shipped files' (a stamp copied with the rows under another name, or typed
by hand) gets the entry refused, as does a commit that is not one of this repository's when the check runs in a
checkout; and the pull-request workflow replays every added, changed or renamed entry itself. Only versions that
rank by the rules carry a stamp (v0 does not: a stamp on a v0 entry is refused). The tables show a valid stamp
beside the entry's commit.
"""

from __future__ import annotations

import fnmatch
import hashlib
import json
import re
from datetime import datetime, timezone
from functools import lru_cache
from importlib import metadata
from typing import Any

from ffsr_gym.provenance import LAB_DATA

KEYS = ("status", "verifier", "commit", "pool_file_sha256", "reference_sha256", "rows_sha256", "entry_sha256",
        "code_sha256", "created_utc")
#: A stamp written before stamps recorded the replayed code's digest: still valid, its code cannot be compared.
KEYS_WITHOUT_CODE = tuple(key for key in KEYS if key != "code_sha256")
#: The package's modules a replay runs (the physics, the planner, the scoring, the tasks, the envs and the replay
#: itself), relative to the package; with every file of the robot, scenario, rule and pool data (``envs``, but for
#: the lab's best-known files, which no replay reads and the wheel does not carry, and the benchmark files of the
#: other versions) they make :func:`code_digest`. A change elsewhere (the CLI, the tables, the docs, a best-known
#: search, another version's rule, spec, pool or reference file) leaves a stamp's code standing.
REPLAYED_CODE = ("kernel", "model", "planning", "sim", "scoring", "versions", "tasks", "environments",
                 "bench/replay.py", "bench/replay_tolerance.py", "bench/policies.py", "bench/episodes.py",
                 "bench/evaluation.py")
_HEX = re.compile(r"[0-9a-f]{40}|[0-9a-f]{64}")
_VERIFIER = re.compile(r"ffsr-gym [0-9A-Za-z.+-]{1,40}")
_CREATED = re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00")


def rows_digest(rows: list[dict[str, Any]]) -> str:
    """sha256 of an entry's episode rows, as JSON with sorted keys."""
    return hashlib.sha256(json.dumps(rows, sort_keys=True, allow_nan=False).encode()).hexdigest()


def entry_digest(entry: dict[str, Any]) -> str:
    """sha256 of an entry as JSON with sorted keys, without its stamp and the loader's ``_`` keys: what a stamp
    binds."""
    extra = {key: value for key, value in (entry.get("extra") or {}).items() if key != "verified"}
    body = {key: value for key, value in entry.items() if not key.startswith("_")} | {"extra": extra}
    return hashlib.sha256(json.dumps(body, sort_keys=True, allow_nan=False).encode()).hexdigest()


def version_of_file(name: str, versions: Any) -> str | None:
    """The version among ``versions`` a file of ``envs/benchmark`` named ``name`` belongs to (``<v>.toml``,
    ``spec_<v>.toml``, ``<v>_*``; the longest such name), or None: a file of no version's own."""
    owners = [v for v in versions if name in (f"{v}.toml", f"spec_{v}.toml") or name.startswith(f"{v}_")]
    return max(owners, key=len, default=None)


@lru_cache(maxsize=16)
def code_digest(version: str | None = None) -> str:
    """sha256 over the path and bytes of every file a replay of an entry of ``version`` runs (:data:`REPLAYED_CODE`,
    the ``envs`` data but the other versions' benchmark files; None: every version's), caches aside, and the native
    kernel's source digest compiled into it: the same for a checkout and a wheel of the same code."""
    from pathlib import Path

    from ffsr_gym import _native
    from ffsr_gym.model.resources import envs_dir
    from ffsr_gym.versions.registry import all_specs

    package = Path(__file__).resolve().parents[1]
    files = [(f"ffsr_gym/{path.relative_to(package).as_posix()}", path) for part in REPLAYED_CODE
             for path in ([package / part] if (package / part).is_file() else (package / part).rglob("*"))]
    versions, benchmark = tuple(all_specs()), envs_dir() / "benchmark"
    files += [(f"envs/{path.relative_to(envs_dir()).as_posix()}", path) for path in envs_dir().rglob("*")
              if not fnmatch.fnmatch(path.name, LAB_DATA)
              and (version is None or path.parent != benchmark
                   or version_of_file(path.name, versions) in (None, version))]
    digest = hashlib.sha256(b"src/native\0" + _native.SOURCE_SHA256.encode())
    for name, path in sorted(files):
        if path.is_file() and "__pycache__" not in path.parts:
            digest.update(name.encode() + b"\0" + hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


@lru_cache(maxsize=256)
def _known_commit(commit: str) -> bool | None:
    """:func:`ffsr_gym.provenance.is_checkout_commit`, once per commit in a process (the tables check every stamp)."""
    from ffsr_gym.provenance import is_checkout_commit

    return is_checkout_commit(commit)


def _reference_sha(entry: dict[str, Any], version: str) -> str | None:
    """The frozen reference the entry's pool is normalised by now (None when the reference does not cover it)."""
    from ffsr_gym.tasks.reference import reference_record

    tier, _, split = str((entry.get("extra") or {}).get("evaluation_pool", "")).partition("/")
    try:
        return reference_record(tier, split, version).get("reference_sha256")
    except (KeyError, ValueError):
        return None


def make_stamp(entry: dict[str, Any], version: str) -> dict[str, Any]:
    """The stamp of an entry that ``verify`` has just reproduced. Its commit is the ffsr-gym checkout's when the
    verifier ran from a clean one (generated results aside), else null: an installed package, or uncommitted code."""
    from ffsr_gym.provenance import checkout_state, is_source_checkout

    commit, dirty, _ = checkout_state()
    clean = is_source_checkout() and dirty is False
    return {"status": "reproduced", "verifier": f"ffsr-gym {metadata.version('ffsr-gym')}",
            "commit": commit if clean else None,
            "pool_file_sha256": entry["extra"].get("pool_file_sha256"),
            "reference_sha256": _reference_sha(entry, version),
            "rows_sha256": rows_digest(entry["episodes"]), "entry_sha256": entry_digest(entry),
            "code_sha256": code_digest(version),
            "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds")}


def stamp_problems(entry: dict[str, Any], version: str | None) -> list[str]:
    """Why an entry's stamp does not describe it (empty: no stamp, or a stamp that does). ``version`` None: a version
    that carries no stamp (v0)."""
    stamp = (entry.get("extra") or {}).get("verified")
    if stamp is None:
        return []
    if version is None:
        return ["extra.verified: this version's entries carry no stamp (only versions ranked by the rules do)"]
    if not isinstance(stamp, dict) or set(stamp) not in (set(KEYS), set(KEYS_WITHOUT_CODE)):
        return [f"extra.verified: allowed a stamp with exactly the keys {list(KEYS)} (written by ffsr-gym leaderboard "
                "verify --stamp)"]
    problems = []
    if "code_sha256" in stamp and not (isinstance(stamp["code_sha256"], str) and len(stamp["code_sha256"]) == 64
                                       and _HEX.fullmatch(stamp["code_sha256"])):
        problems.append("extra.verified.code_sha256: allowed a 64-digit hexadecimal sha256")
    if stamp["status"] != "reproduced":
        problems.append(f"extra.verified.status {str(stamp['status'])[:20]!r}; allowed: 'reproduced'")
    if not (isinstance(stamp["verifier"], str) and _VERIFIER.fullmatch(stamp["verifier"])):
        problems.append("extra.verified.verifier: allowed 'ffsr-gym <version>' (at most 40 characters)")
    if not (isinstance(stamp["created_utc"], str) and _CREATED.fullmatch(stamp["created_utc"])):
        problems.append("extra.verified.created_utc: allowed a UTC time YYYY-MM-DDTHH:MM:SS+00:00")
    if stamp["commit"] is not None and not (isinstance(stamp["commit"], str) and len(stamp["commit"]) == 40
                                            and _HEX.fullmatch(stamp["commit"])):
        problems.append("extra.verified.commit: allowed a 40-digit hexadecimal commit or null")
    elif stamp["commit"] is not None and _known_commit(stamp["commit"]) is False:
        problems.append(f"extra.verified.commit {stamp['commit'][:12]}...: not a commit of this repository")
    if stamp["entry_sha256"] != entry_digest(entry):
        problems.append("extra.verified: the entry changed after it was verified, or the stamp is another entry's "
                        "(entry_sha256 differs)")
    if stamp["rows_sha256"] != rows_digest(entry["episodes"]):
        problems.append("extra.verified: the rows changed after they were verified (rows_sha256 differs)")
    if stamp["pool_file_sha256"] != entry["extra"].get("pool_file_sha256"):
        problems.append("extra.verified: stamped against another pool file than the entry's")
    if stamp["reference_sha256"] != _reference_sha(entry, version):
        problems.append("extra.verified: stamped against another reference than the frozen one")
    return problems


def stamp_text(entry: dict[str, Any]) -> str:
    """The table's words for an entry's stamp: ``verified at <commit>`` (or the verifier's version), or empty."""
    stamp = (entry.get("extra") or {}).get("verified")
    if not isinstance(stamp, dict):
        return ""
    return f"verified at {stamp['commit'][:8]}" if stamp.get("commit") else f"verified by {stamp.get('verifier')}"
