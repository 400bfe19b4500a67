"""``ffsr-gym tasks best-known --screened``: search again where the per-task search's best candidates failed.

The per-task search (:mod:`ffsr_gym_lab.best_known.search`) ranks candidates on the score alone and checks only its
best few against the certificate test. On a task where those all fail (on the capture tiers: captures that use
most of the tolerance, which the certificate's margin refuses), it keeps a lesser schedule, often the task's
certificate, and its best known score can sit far below what a robust schedule reaches. This pass runs the
family's search again on each such (task, family) of a pool (the stored family's ``searched_best`` above its
``score``), on the screened objective (:func:`~ffsr_gym_lab.best_known.search.screened_scores`), and offers its result
to the records (:func:`~ffsr_gym_lab.best_known.build.offer`: kept only when it beats the stored score and passes
the certificate test, as an absorbed line with origin ``screened CMA-ES``). A (task, family) finished is recorded in
``<work>/screened_<tier>_<split>.done``, so an interrupted pass resumes.
"""

from __future__ import annotations

import os
from pathlib import Path

from tqdm.auto import tqdm

from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.tasks.schedule import version_families
from ffsr_gym.tasks.splits import pool
from ffsr_gym.versions.registry import spec_for_version
from ffsr_gym_lab.best_known import search
from ffsr_gym_lab.best_known.build import offer
from ffsr_gym_lab.best_known.records import records

#: The origin an improvement of this pass is stored with.
ORIGIN = "screened CMA-ES"


def candidates(tier: str, split: str, version: str = "v2") -> list[tuple[int, str]]:
    """(index, family) of the pool's stored records whose search found a better candidate than the one it kept."""
    return [(r["index"], family) for r in records(tier, split, version) for family in version_families(version)
            if r["families"][family]["searched_best"] > r["families"][family]["score"] * (1.0 + 1e-3)]


def rescreen(tier: str, split: str, work: str | Path, *, version: str = "v2", generations: int = search.GENERATIONS,
             progress: bool = True) -> int:
    """The screened search of every :func:`candidates` pair not yet done; returns how many raised their family."""
    benchmark = score_rule(spec_for_version(version)).benchmark
    tasks = pool(tier, split, version=version)
    done_path = Path(work) / f"screened_{tier}_{split}.done"
    done = set(done_path.read_text(encoding="utf-8").splitlines()) if done_path.is_file() else set()
    todo = [(index, family) for index, family in candidates(tier, split, version) if f"{index} {family}" not in done]
    populations: dict[str, search.Population] = {}
    improved = 0
    try:
        for index, family in tqdm(todo, desc=f"screened {tier}/{split}", unit="search", disable=not progress):
            if family not in populations:
                populations[family] = search.Population(family, tier, split, search.popsize(family), version)
            result = search.search_family(populations[family], tasks[index], tier, index, benchmark, generations,
                                          screened=True)
            if result.schedule is not None:
                kept = offer(result.schedule, tier, split, index, work, ORIGIN, version=version,
                             evaluations=result.evaluations)
                improved += kept is not None
            Path(work).mkdir(parents=True, exist_ok=True)
            with done_path.open("a", encoding="utf-8") as handle:
                handle.write(f"{index} {family}\n")
                handle.flush()
                os.fsync(handle.fileno())
    finally:
        for population in populations.values():
            population.close()
    return improved
