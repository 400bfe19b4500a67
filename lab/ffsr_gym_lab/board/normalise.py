"""Scores relative to each task's reference score: the leaderboard's normalised column and headroom.

An entry's normalised score is the mean over its episodes of score / the reference score of the
episode's task: the version's **frozen reference** (:mod:`ffsr_gym.tasks.reference`), the best
known scores as of the version's release, so a published normalised score never moves when the
search later improves a task. 1 means every task as good as the reference, 0 every task failed; it
can exceed 1 where an entry beats the reference. It exists for a pool entry when its evaluation
pool is in the reference.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ffsr_gym.tasks import reference
from ffsr_gym.tasks.splits import version_splits, version_tiers


def reference_scores(entry: dict[str, Any], version: str) -> np.ndarray | None:
    """The frozen reference score of every task of the entry's evaluation pool of ``version``, or None (not a
    tier pool, or a pool the reference does not cover)."""
    extra = entry.get("extra") or {}
    where = extra.get("evaluation_pool")
    if not isinstance(where, str) or extra.get("custom_task") is not None:
        return None
    tier, _, split = where.partition("/")
    if tier not in version_tiers(version) or split not in version_splits(version):
        return None
    return reference.reference_scores(tier, split, version)


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
