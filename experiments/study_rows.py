"""The resumable loop of a study over pool tasks, and how its result is published (the capture-v1 studies).

A study's rows are keyed by tier and task seed; each finished row is kept in a work file (a run folder), rewritten
atomically after every row, so that a study stopped anywhere resumes where it stopped. Its result is written with
provenance and, when asked, its table into a docs page between the study's markers.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tqdm.auto import tqdm

from ffsr_gym.provenance import save_result, splice_file, write_json_atomic


def resumable_rows(work: str | Path, jobs: list[tuple], compute: Callable[..., dict], desc: str) -> list[dict]:
    """``compute(*job)`` for every job (its first two items: a tier and a task seed, which the row holds as ``tier``
    and ``seed``), in order; the rows ``work`` already holds are kept, not computed again."""
    path = Path(work)
    done = {(r["tier"], r["seed"]): r for r in json.loads(path.read_text())["rows"]} if path.exists() else {}
    for job in tqdm(jobs, desc=desc, unit="task"):
        if tuple(job[:2]) not in done:
            done[tuple(job[:2])] = compute(*job)
            write_json_atomic(path, {"rows": list(done.values())})
    return [done[tuple(job[:2])] for job in jobs]


def publish(out: str | Path, data: dict[str, Any], docs: str | None, markers: tuple[str, str],
            text: Callable[[dict], str]) -> None:
    """Write ``data`` to ``out`` (as read back), its ``text`` between ``markers`` of the page ``docs`` when given, and
    print the text."""
    data = save_result(out, data)
    if docs:
        splice_file(docs, *markers, text(data))
    print(text(data))
