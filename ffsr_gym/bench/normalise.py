"""Scores relative to each task's best known score: the leaderboard's normalised column and headroom.

An entry's normalised score is the mean over its episodes of score / best known score of the
episode's task (:mod:`ffsr_gym.tasks.best_known`): 1 means every task as good as the best found,
0 every task failed. It can exceed 1 on a task where an entry beats the search. It exists for a
pool entry when every task of its evaluation pool has a stored best known score.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym.tasks import best_known
from ffsr_gym.tasks.splits import pool, version_splits
from ffsr_gym.tasks.tiers import ALL_TIERS


def reference_scores(entry: dict[str, Any], version: str) -> np.ndarray | None:
    """The best known score of every task of the entry's evaluation pool of ``version``, or None (not a tier
    pool, or not every task stored)."""
    extra = entry.get("extra") or {}
    where = extra.get("evaluation_pool")
    if not isinstance(where, str) or extra.get("custom_task") is not None:
        return None
    tier, _, split = where.partition("/")
    if tier not in ALL_TIERS or split not in version_splits(version):
        return None
    return best_known.scores(tier, split, len(pool(tier, split, version=version)), version)


def normalised_scores(entry: dict[str, Any], version: str) -> np.ndarray | None:
    """score / best known score of each of the entry's episodes (rows order), or None."""
    reference = reference_scores(entry, version)
    if reference is None:
        return None
    rows = entry["episodes"]
    if any(not isinstance(row.get("task_index"), int) or not 0 <= row["task_index"] < len(reference) for row in rows):
        return None
    return np.array([(row["score"] or 0.0) / reference[row["task_index"]] for row in rows])


def normalised_mean(entry: dict[str, Any], version: str) -> float | None:
    """The mean of :func:`normalised_scores` (the table's normalised column), or None."""
    values = normalised_scores(entry, version)
    return None if values is None else float(values.mean())
