"""``ffsr-gym tasks best-known``: the per-task search over whole pools, resumable, and the shipped file.

Each (tier, split) is searched task by task into ``<work>/<tier>_<split>.jsonl`` (one line per
finished task, appended and flushed; a line torn by a kill is ignored and that task searched
again), so a killed run resumes at the task it was on. On a cluster (``executor``), each task is a piece of
its own and this process appends the records as they arrive, so a killed worker loses only its task.
:func:`assemble` writes every finished record into ``envs/benchmark/<version>_best_known.json``
with the search budget, the pool files' hashes and provenance. :func:`convergence` re-runs a sample
of tasks with twice the generations and stores how much the best known scores move (how far from
converged they are).
"""

from __future__ import annotations

import hashlib
import json
import os
import time
import warnings
from concurrent.futures import Executor, as_completed
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from ffsr_gym.exceptions import FFSRError, InvalidInputError
from ffsr_gym.provenance import provenance, write_text_atomic
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.tasks.schedule import FAMILIES, Schedule, replay_schedule, version_families
from ffsr_gym.tasks.splits import pool, pool_path, task_scenario
from ffsr_gym.user_files import nesting_depth, read_text
from ffsr_gym.versions.registry import spec_for_version
from ffsr_gym_lab.best_known import check, search
from ffsr_gym_lab.best_known.records import best_known_path, load_best_known, records

popsize = search.popsize


#: What every search record holds (a line without them is torn or foreign: named, skipped, its task searched again).
RECORD_KEYS = {"tier": str, "split": str, "index": int, "generations": int, "best": dict, "families": dict,
               "wall_time_s": (int, float)}
#: What every absorbed line holds.
ABSORBED_KEYS = {"index": int, "family": str, "score": (int, float), "result": dict}


def read_lines(path: Path, keys: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """The whole records of a jsonl file. A line that is not a JSON object with ``keys`` (default
    :data:`RECORD_KEYS`) of their types, a torn last line among them, is named in a warning and skipped."""
    try:
        text = read_text(path) if path.is_file() else ""
    except FFSRError as exc:
        raise InvalidInputError(f"work file {exc}") from None
    out = []
    keys = RECORD_KEYS if keys is None else keys
    for number, line in enumerate(text.splitlines(), start=1):
        problem = None
        try:
            record = json.loads(line) if nesting_depth(line) <= 16 else None
        except (ValueError, RecursionError):
            record = None
        if not isinstance(record, dict):
            problem = "not a JSON object (a torn or foreign line)"
        else:
            problem = next((f"{key!r} missing or not {kind}" for key, kind in keys.items()
                            if isinstance(record.get(key), bool) or not isinstance(record.get(key), kind)), None)
        if problem is None:
            out.append(record)
        elif line.strip():
            warnings.warn(f"{path}:{number}: {problem}; skipped (its task is searched again)", stacklevel=2)
    return out


def _append(path: Path, record: dict[str, Any]) -> None:
    """Append one record as a line of its own (after a torn last line, on a fresh line) and flush it to disk."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a+b") as handle:
        handle.seek(0, os.SEEK_END)
        fresh = handle.tell() == 0
        if not fresh:
            handle.seek(-1, os.SEEK_END)
            fresh = handle.read(1) == b"\n"
        handle.write((b"" if fresh else b"\n") + (json.dumps(record, allow_nan=False) + "\n").encode("utf-8"))
        handle.flush()
        os.fsync(handle.fileno())


def work_file(work: str | Path, tier: str, split: str) -> Path:
    """Where a run writes one pool's records: ``<work>/<tier>_<split>.jsonl``."""
    return Path(work) / f"{tier}_{split}.jsonl"


def run(tier: str, split: str, work: str | Path, *, version: str = "v2", generations: int = search.GENERATIONS,
        indices: list[int] | None = None, progress: bool = True, executor: Executor | None = None) -> Path:
    """Search every task of ``tier``'s ``split`` pool (or ``indices`` of it) not yet in the pool's work file
    (:func:`work_file`). With ``executor`` (a cluster's, :func:`ffsr_gym.cluster.cluster_executor`), each task is a
    piece of its own, and this process appends the records as they arrive."""
    if Path(work).exists() and not Path(work).is_dir():
        raise InvalidInputError(f"--work {str(work)!r}: not a folder; allowed: a folder (made when missing)")
    benchmark = score_rule(spec_for_version(version)).benchmark
    path = work_file(work, tier, split)
    tasks = pool(tier, split, version=version)
    wanted = list(range(len(tasks))) if indices is None else list(indices)
    done = {r["index"] for r in read_lines(path) if r["generations"] == generations}
    todo = [i for i in wanted if i not in done]
    if not todo:
        return path
    label = f"best known {tier}/{split}"
    if executor is not None:
        pieces = [executor.submit(search.search_task, tier, split, index, version, generations) for index in todo]
        for piece in tqdm(as_completed(pieces), total=len(pieces), desc=label, unit="task", disable=not progress):
            _append(path, piece.result())
        return path
    populations = {family: search.Population(family, tier, split, popsize(family), version)
                   for family in version_families(version)}
    try:
        for index in tqdm(todo, desc=label, unit="task", disable=not progress):
            _append(path, search.best_known(populations, tasks[index], tier, split, index, benchmark, generations))
    finally:
        for population in populations.values():
            population.close()
    return path


def family_env_ids(version: str = "v2") -> dict[str, str]:
    """The registered env id whose actions each schedule family is, in ``version``."""
    ids = spec_for_version(version).ids
    return {family: ids.residual if family == "residual" else ids.parameters for family in version_families(version)}


def budget(version: str = "v2") -> dict[str, Any]:
    """The search budget per task, as the file records it (the env ids: ``version``'s)."""
    families = version_families(version)
    return {"knots": {family: search.knots(family) for family in families} if "timed" in families else search.KNOTS,
            "sigma0": search.SIGMA0, "generations": search.GENERATIONS,
            "popsize": {family: popsize(family) for family in families}, "cma_seed": search.CMA_SEED,
            "tried_in_ensemble": search.TRIED, "env_ids": family_env_ids(version)}


def target_file(work: str | Path, version: str, split: str, *, shipped: bool = False) -> Path:
    """Where :func:`assemble` writes ``split``'s records: the work folder's copy of the best-known file that holds
    them, or (``shipped``) the shipped file itself (:func:`~ffsr_gym_lab.best_known.records.best_known_path`)."""
    path = best_known_path(version, split)
    return path if shipped else Path(work) / path.name


def assemble(work: str | Path, *, version: str = "v2", out: str | Path | None = None, command: str | None = None,
             generations: int = search.GENERATIONS, splits: list[str] | None = None,
             shipped: bool = False) -> list[Path]:
    """Write every finished record of ``generations`` in ``work`` into best-known files: the test and validation
    records into ``<version>_best_known.json`` (keeping its ``convergence``), the training records into
    ``<version>_best_known_train.json``, inside ``work`` (:func:`target_file`), or all of them into ``out``.
    With ``splits``, only the files those splits live in are written. Returns the files written.

    ``shipped`` writes the package's own files instead: an explicit build of each whole file, refused unless the
    package is a source checkout and the work folder holds at least every task the shipped file holds.

    Raises:
        InvalidInputError: ``shipped`` with ``out``, outside a checkout, or from a work folder that would lose
            stored tasks (each named).
    """
    if shipped and out is not None:
        raise InvalidInputError("out= with shipped=True; allowed: one target (the shipped files, or out)")
    wanted = None if splits is None or out is not None else {target_file(work, version, s, shipped=shipped)
                                                             for s in splits}
    files: dict[Path, dict[str, dict[str, list]]] = {}
    cost: dict[Path, list[float]] = {}  # per file: the search's objective evaluations and wall time [s]
    if not Path(work).is_dir():
        raise InvalidInputError(f"--work {str(work)!r}: not a folder; allowed: a best-known work folder")
    for path in sorted(Path(work).glob("*.jsonl")):
        if path.name.startswith(ABSORBED):
            continue
        file_tier, _, file_split = path.name.split(".")[0].rpartition("_")  # <tier>_<split>[.shard<k>of<n>].jsonl
        for record in read_lines(path):
            if record.get("generations") != generations:
                continue
            check.refuse(path, record.get("index"), check.record_problem(record, version, file_tier, file_split))
            target = Path(out) if out is not None else target_file(work, version, record["split"], shipped=shipped)
            if wanted is not None and target not in wanted:
                continue
            slot = files.setdefault(target, {}).setdefault(record["tier"], {}).setdefault(record["split"], [])
            for result in record["families"].values():  # the shortest float32 text of each knot
                if result["schedule"] is not None:
                    result["schedule"] = Schedule.from_dict(result["schedule"]).as_dict()
            if all(r["index"] != record["index"] for r in slot):
                slot.append(record)
                spent = cost.setdefault(target, [0, 0.0])
                spent[0] += sum(f["evaluations"] for f in record["families"].values())
                spent[1] += record["wall_time_s"]
    if shipped:
        _check_whole(files, version)
    provenance_now = provenance(command=command)
    for target, tasks in files.items():
        absorbed = 0
        for tier, splits in tasks.items():
            for split, slot in splits.items():
                slot.sort(key=lambda r: r["index"])
                absorbed_path = _absorbed_path(work, tier, split)
                lines = read_lines(absorbed_path, ABSORBED_KEYS)
                for line in lines:
                    check.refuse(absorbed_path, line["index"], check.absorbed_problem(line, version, tier, split))
                absorbed += sum(_merge_absorbed(record, [a for a in lines if a["index"] == record["index"]])
                                for record in slot)
        check.replay_all(tasks, version, target)
        tiers = sorted(tasks)
        old = load_best_known(version, target) or {}
        data = {"version": version, "budget": budget(version) | {"generations": generations},
                "pool_files_sha256": {t: hashlib.sha256(pool_path(t, version).read_bytes()).hexdigest() for t in tiers},
                "counts": {t: {s: len(v) for s, v in tasks[t].items()} for t in tiers},
                "compute": {"objective_evaluations": cost[target][0], "wall_time_s": cost[target][1], "cores": 1},
                "absorbed": absorbed,
                "provenance": provenance_now, "convergence": old.get("convergence"), "tasks": tasks}
        _write(target, data)
    return sorted(files)


def _check_whole(files: dict[Path, dict[str, dict[str, list]]], version: str) -> None:
    """Refuse to write a shipped file from a work folder that holds fewer tasks of any pool than it stores, or into
    an installed package (a wheel's files are not the build's to change)."""
    from ffsr_gym.provenance import is_source_checkout

    if not is_source_checkout():
        raise InvalidInputError("the shipped best-known files belong to an installed package here; allowed: a build "
                                "from the ffsr-gym source checkout (without --write-shipped the files go to --work)")
    for target, tasks in files.items():
        stored = load_best_known(version, target) or {"tasks": {}}
        for tier, splits in stored["tasks"].items():
            for split, kept in splits.items():
                have = len(tasks.get(tier, {}).get(split, []))
                if have < len(kept):
                    raise InvalidInputError(f"{target.name} stores {len(kept)} {tier}/{split} tasks, the work "
                                            f"folder holds {have}; allowed: a build of the whole file (every stored "
                                            "task)")


#: The work files of :func:`absorb`: ``absorbed_<tier>_<split>.jsonl``.
ABSORBED = "absorbed_"


def _merge_absorbed(record: dict[str, Any], lines: list[dict[str, Any]]) -> bool:
    """Replace a family's result in ``record`` by an absorbed episode of the task (``lines``) that scored higher,
    and re-pick the best; whether anything changed."""
    changed = False
    for line in lines:
        current = record["families"][line["family"]]
        if line["score"] > current["score"]:
            record["families"][line["family"]] = {**line["result"], "searched_best": current["searched_best"]}
            changed = True
    if changed:
        best = max((r for r in record["families"].values() if r["schedule"] is not None), key=lambda r: r["score"])
        if best["score"] > record["best"]["score"]:
            record["best"] = {"family": best["family"], "score": best["score"]}
    return changed


def _absorbed_path(work: str | Path, tier: str, split: str) -> Path:
    return Path(work) / f"{ABSORBED}{tier}_{split}.jsonl"


def _done_path(work: str | Path, tier: str, split: str) -> Path:
    return Path(work) / f"{ABSORBED}{tier}_{split}.done"


def is_absorbed(work: str | Path, tier: str, split: str, key: str) -> bool:
    """Whether a policy with this ``key`` (its origin and a hash of its content) was already played on every stored
    task of the pool: playing it again cannot raise a stored score, since the stored scores only rise."""
    path = _done_path(work, tier, split)
    if not path.exists() and not path.is_symlink():
        return False
    try:
        return key in read_text(path).splitlines()
    except FFSRError as exc:
        raise InvalidInputError(f"work file {exc}") from None


def absorb(policy: Any, env_id: str, tier: str, split: str, work: str | Path, origin: str, *,
           version: str = "v2", progress: bool = True, key: str | None = None) -> int:
    """Play ``policy`` (SB3-style ``predict``, a callable, or a constant action tuple) on every stored task of a pool,
    and keep each episode that beats the stored score of its env's family and passes the certificate test
    (ensemble with margins, and Pinocchio) as that family's schedule: its actions, clipped to [-1, 1] in float32,
    one knot per decision (one knot in all when every action is the same), so the schedule's replay is the episode,
    exactly (checked before it is kept). ``env_id`` is one of ``version``'s two ids. Lines go
    to ``<work>/absorbed_<tier>_<split>.jsonl``; :func:`assemble` merges them. Returns how many tasks improved.

    This makes the best known score at least every absorbed policy's: a closed-loop policy can beat the
    search's open-loop schedules of a few knots. With ``key``, a finished pool is recorded in
    ``<work>/absorbed_<tier>_<split>.done`` (:func:`is_absorbed`), so that an interrupted run of many
    policies resumes at the first one not finished.
    """
    import gymnasium as gym

    from ffsr_gym.bench.entry import actor

    families = {env: family for family, env in family_env_ids(version).items()}
    if env_id not in families:
        raise InvalidInputError(f"env id {env_id!r} is not one of {version}'s; allowed: {sorted(families)}")
    family = families[env_id]
    stored = {r["index"]: r for r in records(tier, split, version)}
    env = gym.make(env_id, task=tier, split=split)
    improved = 0
    for index in tqdm(sorted(stored), desc=f"absorb {origin} {tier}/{split}", unit="task", disable=not progress):
        act = actor(policy)  # one per episode (a recurrent policy's state starts afresh)
        obs, _ = env.reset(seed=0, options={"task_index": index})
        played, done = [], False
        while not done:
            applied = np.clip(np.asarray(act(obs), dtype=np.float32).reshape(-1), -1.0, 1.0)
            played.append(applied)
            obs, _, terminated, truncated, info = env.step(applied)
            done = terminated or truncated
        if not info.get("success") or info["score"] <= stored[index]["families"][family]["score"]:
            continue
        span = Schedule.constant(family, np.zeros(FAMILIES[family]), 1).span(env.unwrapped.scenario)
        knots = played[:span] if any(np.any(row != played[0]) for row in played[:span]) else played[:1]
        schedule = Schedule(family, tuple(tuple(float(x) for x in row) for row in knots))  # a constant: one knot
        improved += offer(schedule, tier, split, index, work, origin, version=version, score=info["score"]) is not None
    env.close()
    if key is not None:
        mark_absorbed(work, tier, split, key)
    return improved


def mark_absorbed(work: str | Path, tier: str, split: str, key: str) -> None:
    """Record that the policy with this ``key`` was played on every stored task of the pool (:func:`is_absorbed`)."""
    with _done_path(work, tier, split).open("a", encoding="utf-8") as handle:
        handle.write(key + "\n")
        handle.flush()
        os.fsync(handle.fileno())


def offer(schedule: Schedule, tier: str, split: str, index: int, work: str | Path, origin: str, *,
          version: str = "v2", score: float | None = None, evaluations: int = 1) -> dict[str, Any] | None:
    """Keep ``schedule`` as its family's result for pool task ``index`` when its episode (the kernel's replay) beats
    the stored score of that family and passes the certificate test (ensemble with margins, and Pinocchio); with
    ``score``, only when the replay scores exactly that (the episode the schedule claims to be); ``evaluations``: the
    episodes it took to find it. The kept line goes to
    ``<work>/absorbed_<tier>_<split>.jsonl`` (:func:`assemble` merges it) and is returned; otherwise None."""
    benchmark = score_rule(spec_for_version(version)).benchmark
    stored = {r["index"]: r for r in records(tier, split, version)}[index]
    task = pool(tier, split, version=version)[index]
    played = replay_schedule(task_scenario(tier, task.seed, benchmark), schedule, benchmark)
    if score is not None and played.score != score:
        return None  # not an exact open-loop replay: kept out rather than stored wrong
    if not played.success or played.score <= stored["families"][schedule.family]["score"]:
        return None
    margins = search.passes(task, tier, schedule, benchmark, pinocchio=True)
    if margins is None:
        return None
    result = {"family": schedule.family, "schedule": schedule.as_dict(), "score": played.score,
              "margins": margins.as_dict(), "origin": origin, "evaluations": evaluations}
    line = {"index": index, "family": schedule.family, "score": played.score, "result": result}
    _append(_absorbed_path(work, tier, split), line)
    return line


def _write(path: Path, data: dict[str, Any]) -> None:
    """The file as compact JSON, one line per task record (it ships in the wheel: small, and diffs by task)."""
    head = {k: v for k, v in data.items() if k != "tasks"}
    lines = [json.dumps(head, allow_nan=False)[:-1] + ', "tasks": {']
    tiers = list(data["tasks"])
    for t, tier in enumerate(tiers):
        splits = list(data["tasks"][tier])
        lines.append(f"{json.dumps(tier)}: {{")
        for k, split in enumerate(splits):
            records = data["tasks"][tier][split]
            lines.append(f"{json.dumps(split)}: [")
            lines += [json.dumps(r, allow_nan=False, separators=(",", ":")) + ("," if i < len(records) - 1 else "")
                      for i, r in enumerate(records)]
            lines.append("]" + ("," if k < len(splits) - 1 else ""))
        lines.append("}" + ("," if t < len(tiers) - 1 else ""))
    lines.append("}}")
    text = "\n".join(lines) + "\n"
    json.loads(text)  # the hand-joined text is one JSON document
    write_text_atomic(path, text)


def convergence(work: str | Path, sample: list[tuple[str, str, int]], *, version: str = "v2",
                out: str | Path | None = None, progress: bool = True) -> dict[str, Any]:
    """Re-run the search with twice the generations on ``sample`` ((tier, split, index) of stored tasks) and
    record, per task, the stored and the doubled-budget best known score (in the ``convergence`` of ``out``: by
    default the work folder's copy of the best-known file, made from the shipped one when it has none)."""
    out = Path(out) if out is not None else target_file(work, version, "test")
    data = load_best_known(version, out) or load_best_known(version)
    doubled = 2 * search.GENERATIONS
    start = time.perf_counter()
    rows = []
    for tier, split, index in tqdm(sample, desc="doubled budget", unit="task", disable=not progress):
        path = run(tier, split, Path(work) / "doubled", version=version, generations=doubled, indices=[index],
                   progress=False)
        again = next(r for r in read_lines(path) if r["index"] == index)
        stored = next(r for r in data["tasks"][tier][split] if r["index"] == index)
        rows.append({"tier": tier, "split": split, "index": index, "stored": stored["best"]["score"],
                     "doubled": again["best"]["score"]})
    gaps = np.array([r["doubled"] - r["stored"] for r in rows])
    rel = np.array([(r["doubled"] - r["stored"]) / r["stored"] for r in rows])
    summary = {"generations": doubled, "tasks": rows, "mean_gap": float(gaps.mean()),
               "median_relative_gap": float(np.median(rel)), "max_relative_gap": float(rel.max()),
               "share_improved": float(np.mean(gaps > 0)), "wall_time_s": time.perf_counter() - start}
    _write(out, data | {"convergence": summary})
    return summary
