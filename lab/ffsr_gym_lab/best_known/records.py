"""The best known score of every pool task, stored with the pools.

The test and validation pools' records are in ``envs/benchmark/<version>_best_known.json`` (the
leaderboards' normalised column reads it); the training pools', which only the offline datasets
use (:mod:`ffsr_gym_lab.publish.dataset`), are in ``<version>_best_known_train.json``, so that loading
the first never parses the second. Each stored task has the schedule
(:class:`~ffsr_gym.tasks.schedule.Schedule`) that reached its
best known score, the env whose actions it is, that score and its worst margins over the
ensemble; ``ffsr-gym tasks best-known`` writes the file (:mod:`ffsr_gym_lab.best_known.search`).
Leaderboards divide an entry's task scores by these (the normalised column).
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
from ffsr_gym.tasks.schedule import Schedule
from ffsr_gym.tasks.splits import live_version, pool_path

#: The splits whose records are stored in a file of their own, and its name's suffix.
OWN_FILE = {"train": "_train"}


def best_known_path(version: str | None = None, split: str | None = None) -> Path:
    """The best-known file of ``version`` that holds ``split``'s records (may not exist); without ``split``,
    the test and validation file."""
    return envs_dir() / "benchmark" / f"{live_version(version)}_best_known{OWN_FILE.get(split, '')}.json"


@lru_cache(maxsize=8)
def _load(path: str, stamp: int) -> dict[str, Any]:
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InvalidInputError(f"{path}: not a readable best-known file ({type(exc).__name__}: {exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("tasks"), dict):
        raise InvalidInputError(f"{path}: allowed: a JSON object with 'tasks': {{tier: {{split: [records]}}}}")
    return data


def load_best_known(version: str | None = None, path: str | Path | None = None) -> dict[str, Any] | None:
    """The best-known file's content, or None when the version has none."""
    path = Path(path) if path is not None else best_known_path(version)
    if not path.is_file():
        return None
    return _load(str(path), path.stat().st_mtime_ns)


def records(tier: str, split: str, version: str | None = None, path: str | Path | None = None) -> list[dict[str, Any]]:
    """The stored records of ``tier``'s ``split`` pool, in pool order ([] when none are stored); ``path``
    overrides the split's shipped file."""
    data = load_best_known(version, path if path is not None else best_known_path(version, split))
    if data is None:
        return []
    return sorted(data["tasks"].get(tier, {}).get(split, []), key=lambda r: r["index"])


def scores(tier: str, split: str, size: int, version: str | None = None) -> np.ndarray | None:
    """The best known score of each of the ``size`` tasks of a pool, or None unless every one is stored
    and the pool file is the one they were searched on."""
    data = load_best_known(version, best_known_path(version, split))
    stored = records(tier, split, version)
    if data is None or len(stored) != size or [r["index"] for r in stored] != list(range(size)):
        return None
    pools = hashlib.sha256(pool_path(tier, live_version(version)).read_bytes()).hexdigest()
    if data.get("pool_files_sha256", {}).get(tier) != pools:
        return None
    return np.array([r["best"]["score"] for r in stored])


def best_schedule(record: dict[str, Any]) -> Schedule | None:
    """The schedule of a record's best family (None when the best is the task's certificate)."""
    family = record["best"]["family"]
    return None if family == "certificate" else Schedule.from_dict(record["families"][family]["schedule"])
