"""What a best-known record must be before ``tasks best-known`` assembles it: a record of a task of the pool its
work file is named after, with scores a score can be, whose best score is what its schedule scores when replayed.

A work folder is a folder of text files anyone can edit, and the assembled file normalises every leaderboard entry,
so nothing in it is taken on trust: :func:`record_problem` checks a search record's form and its task, and
:func:`absorbed_problem` an absorbed line's; :func:`replay_problem` replays the best schedule the record names
(:func:`~ffsr_gym.tasks.schedule.replay_schedule`, about 0.03 s a task) and compares its score exactly, or, when the
best is the task's certificate, compares it with the pool's certified score.
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path
from typing import Any

from tqdm.auto import tqdm

from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.scoring.score import Benchmark
from ffsr_gym.tasks.schedule import FAMILIES, Schedule, replay_schedule
from ffsr_gym.tasks.splits import SPLITS, PoolTask, pool, task_scenario
from ffsr_gym.versions.registry import spec_for_version

#: A record's best may be a searched family's schedule or the task's own certificate.
BEST_FAMILIES = (*FAMILIES, "certificate")


@lru_cache(maxsize=64)
def _pool(tier: str, split: str, version: str) -> tuple[PoolTask, ...]:
    """A pool's tasks, read once per assembly's many records (``pool`` rebuilds them from the file's data)."""
    return pool(tier, split, version=version)


def _score_problem(value: Any, where: str) -> str | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or not 0.0 <= value <= 1.0:
        return f"{where} {str(value)[:30]}; allowed: a score in [0, 1]"
    return None


def _task(tier: Any, split: Any, index: Any, version: str, file_tier: str, file_split: str) -> tuple[PoolTask | None,
                                                                                                   str | None]:
    """The pool task a record names, or why it names none."""
    if (tier, split) != (file_tier, file_split):
        return None, (f"a {str(tier)[:20]}/{str(split)[:20]} record in the {file_tier}/{file_split} work file; "
                      "allowed: records of the file's own pool")
    if tier not in spec_for_version(version).tasks.tiers or split not in SPLITS:
        return None, f"pool {str(tier)[:20]}/{str(split)[:20]}; allowed: a tier of {version} and a split in {SPLITS}"
    tasks = _pool(tier, split, version)
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(tasks):
        return None, f"index {str(index)[:20]}; allowed: 0 to {len(tasks) - 1} ({tier}/{split} holds {len(tasks)})"
    return tasks[index], None


def _result_problem(result: Any, family: str, where: str) -> str | None:
    """Why a family's result is not one (a dict with that family, a score, a schedule of that family or None)."""
    if not isinstance(result, dict):
        return f"{where}: not a result object"
    if result.get("family") != family:
        return f"{where}: a result of family {str(result.get('family'))[:20]!r} filed under {family!r}"
    problem = _score_problem(result.get("score"), f"{where}.score")
    if problem is None and result.get("schedule") is not None:
        try:
            schedule = Schedule.from_dict(result["schedule"])
        except FFSRError as exc:
            return f"{where}.schedule: {str(exc)[:200]}"
        if schedule.family != family:
            return f"{where}.schedule: of family {schedule.family!r}; allowed: {family!r}"
    return problem


def record_problem(record: dict[str, Any], version: str, file_tier: str, file_split: str) -> str | None:
    """Why a search record cannot be assembled (None: it can, once :func:`replay_problem` agrees)."""
    task, problem = _task(record["tier"], record["split"], record["index"], version, file_tier, file_split)
    if problem is not None:
        return problem
    if "task_seed" in record and record["task_seed"] != task.seed:
        return f"task_seed {str(record['task_seed'])[:20]}: pool task {record['index']} is seed {task.seed}"
    unknown = sorted(str(f)[:20] for f in record["families"] if f not in FAMILIES)
    if unknown:
        return f"families {unknown}; allowed: {sorted(FAMILIES)}"
    for family, result in record["families"].items():
        problem = _result_problem(result, family, f"families.{family}")
        if problem is not None:
            return problem
    best = record["best"]
    if best.get("family") not in BEST_FAMILIES:
        return f"best.family {str(best.get('family'))[:20]!r}; allowed: {list(BEST_FAMILIES)}"
    problem = _score_problem(best.get("score"), "best.score")
    if problem is None and best["family"] != "certificate" and (
            best["family"] not in record["families"] or record["families"][best["family"]]["schedule"] is None):
        problem = f"best.family {best['family']!r} has no schedule in the record"
    return problem


def absorbed_problem(line: dict[str, Any], version: str, tier: str, split: str) -> str | None:
    """Why an absorbed line cannot be merged (None: it can; its score is replayed once it wins)."""
    _, problem = _task(tier, split, line["index"], version, tier, split)
    if problem is None and line["family"] not in FAMILIES:
        problem = f"family {line['family'][:20]!r}; allowed: {sorted(FAMILIES)}"
    if problem is None:
        problem = _score_problem(line["score"], "score") or _result_problem(line["result"], line["family"], "result")
    if problem is None and line["result"].get("schedule") is None:
        problem = "result.schedule: missing (an absorbed episode is its schedule)"
    if problem is None and line["result"]["score"] != line["score"]:
        problem = "score differs from result.score"
    return problem


def replay_problem(record: dict[str, Any], version: str, benchmark: Benchmark) -> str | None:
    """Why the record's best score is not what its best replays to (None: it is, to the last bit)."""
    task = _pool(record["tier"], record["split"], version)[record["index"]]
    best = record["best"]
    if best["family"] == "certificate":
        if best["score"] != task.certificate_score:
            return f"best.score {best['score']!r}: the task's certified score is {task.certificate_score!r}"
        return None
    result = record["families"][best["family"]]
    if result["score"] != best["score"]:
        return f"best.score {best['score']!r}: its family's result scores {result['score']!r}"
    scenario = task_scenario(record["tier"], task.seed, benchmark)
    played = replay_schedule(scenario, Schedule.from_dict(result["schedule"]), benchmark)
    if played.score != best["score"]:
        return f"best.score {best['score']!r}: its schedule replays to {played.score!r}"
    return None


def refuse(path: Path, index: Any, problem: str | None) -> None:
    """Raise the named error of one work-file line's ``problem`` (nothing when None)."""
    if problem is not None:
        raise InvalidInputError(f"{path}: record of task {str(index)[:20]}: {problem}; nothing written (mend or remove "
                                "the line)")


def replay_all(tasks: dict[str, dict[str, list]], version: str, target: Path) -> None:
    """Replay every record's best before it is written (:func:`replay_problem`)."""
    benchmark = score_rule(spec_for_version(version)).benchmark
    slots = [record for splits in tasks.values() for slot in splits.values() for record in slot]
    for record in tqdm(slots, desc=f"replay the best of each task for {target.name}", unit="task"):
        problem = replay_problem(record, version, benchmark)
        if problem is not None:
            raise InvalidInputError(f"{record['tier']}/{record['split']} task {record['index']}: {problem}; "
                                    "nothing written")
