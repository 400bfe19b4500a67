"""The frozen reference of a benchmark version: the scores the leaderboard's normalised column divides by.

The best-known search goes on after a version is released, and its file
(:mod:`ffsr_gym_lab.best_known.records`) keeps improving. If the normalised column read that file, a
published entry's normalised score would fall every time the search improved a task. So each
version has one **frozen reference** (``envs/benchmark/<version>_reference.json``): the best
known score of every task of its test and validation pools as of the version's release, with the
hash of the best-known file it was taken from. ``ffsr-gym tasks freeze-reference`` writes it once
and refuses to write it again; every entry records its sha256, the table header names it, and an
entry scored against another reference is refused by name. Later improvements are *records*,
listed apart (:func:`ffsr_gym_lab.pools.freeze.records_since`), never folded into the reference. Writing the
reference and finding the records read the best-known files: the lab's (:mod:`ffsr_gym_lab.pools.freeze`).
"""

from __future__ import annotations

import hashlib
import json
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.model.resources import envs_dir
from ffsr_gym.tasks.splits import live_version

#: The pools a reference covers (the training pools are never scored by an entry).
SPLITS = ("test", "validation")


def reference_path(version: str | None = None) -> Path:
    """The frozen reference file of ``version`` (may not exist)."""
    return envs_dir() / "benchmark" / f"{live_version(version)}_reference.json"


@lru_cache(maxsize=4)
def _load(path: str, stamp: int) -> tuple[dict[str, Any], str]:
    raw = Path(path).read_bytes()
    try:
        data = json.loads(raw)
    except ValueError as exc:
        raise InvalidInputError(f"{path}: not a readable reference file ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("scores"), dict):
        raise InvalidInputError(f"{path}: allowed: a JSON object with 'scores': {{tier: {{split: [score, ...]}}}}")
    return data, hashlib.sha256(raw).hexdigest()


def load_reference(version: str | None = None) -> tuple[dict[str, Any], str] | None:
    """(content, sha256) of the version's frozen reference, or None when it has none."""
    path = reference_path(version)
    if not path.is_file():
        return None
    return _load(str(path), path.stat().st_mtime_ns)


def reference_sha256(version: str | None = None) -> str | None:
    """The sha256 of the version's frozen reference file, or None."""
    loaded = load_reference(version)
    return None if loaded is None else loaded[1]


def reference_scores(tier: str, split: str, version: str | None = None) -> np.ndarray | None:
    """The frozen reference score of each task of a pool (pool order), or None (no reference, or the pool is not
    in it)."""
    loaded = load_reference(version)
    if loaded is None:
        return None
    values = loaded[0]["scores"].get(tier, {}).get(split)
    return None if values is None else np.asarray(values, dtype=float)


def reference_record(tier: str, split: str, version: str | None = None) -> dict[str, str]:
    """What an entry of ``tier``'s ``split`` pool records of the reference it is normalised by: its sha256 (empty
    when the version's reference does not cover that pool)."""
    sha = reference_sha256(version)
    return {} if sha is None or reference_scores(tier, split, version) is None else {"reference_sha256": sha}
