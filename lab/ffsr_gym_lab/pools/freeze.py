"""Writing a version's frozen reference from its best-known file, once, and the records set since
(:mod:`ffsr_gym.tasks.reference` reads the reference; this module is the lab's: it reads the best-known files)."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.provenance import provenance, write_json_atomic
from ffsr_gym.tasks.reference import SPLITS, load_reference, reference_path
from ffsr_gym.tasks.splits import live_version, pool, version_splits, version_tiers
from ffsr_gym_lab.best_known import records as best_known


def freeze(version: str | None = None, *, out: str | Path | None = None, command: str = "") -> Path:
    """Write the frozen reference of ``version`` from its best-known file: every tier's test and validation pool
    whose tasks all have a best known score.

    Raises:
        InvalidInputError: the reference exists already (it is frozen: a new reference is a new version), or no
            pool has every task's best known score.
    """
    version = live_version(version)
    path = Path(out) if out is not None else reference_path(version)
    if path.exists():
        raise InvalidInputError(f"{path} exists: a version's reference is frozen; allowed: a new benchmark version "
                                "(or --out another file)")
    source = best_known.best_known_path(version)
    if not source.is_file():
        raise InvalidInputError(f"{source}: no best-known file to freeze")
    scores: dict[str, dict[str, list[float]]] = {}
    for tier in version_tiers(version):
        for split in (s for s in SPLITS if s in version_splits(version)):
            values = best_known.scores(tier, split, len(pool(tier, split, version=version)), version)
            if values is not None:
                scores.setdefault(tier, {})[split] = [float(x) for x in values]
    if not scores:
        raise InvalidInputError(f"{source}: no pool has a best known score for every task; nothing to freeze")
    data = {"version": version, "splits": list(SPLITS),
            "frozen_from": {"file": source.name, "sha256": hashlib.sha256(source.read_bytes()).hexdigest()},
            "scores": scores, "provenance": provenance(command=command)}
    write_json_atomic(path, data)
    return path


def records_since(version: str | None = None, split: str = "test") -> list[dict[str, Any]]:
    """Tasks whose best known score now beats the frozen reference: tier, index, reference, record, gain."""
    loaded = load_reference(version)
    if loaded is None:
        return []
    out = []
    for tier, splits in loaded[0]["scores"].items():
        frozen = splits.get(split)
        now = best_known.scores(tier, split, len(frozen), version) if frozen is not None else None
        if now is None:
            continue
        for index, (old, new) in enumerate(zip(frozen, now)):
            if new > old:
                out.append({"tier": tier, "index": index, "reference": old, "record": float(new),
                            "gain": float(new / old - 1.0) if old > 0 else float("inf")})
    return out
