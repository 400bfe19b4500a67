"""Build the v1 task pools: apply the tier rule to candidate seeds, in resumable chunks.

``ffsr-gym tasks build --work runs/tasks-v1`` classifies the candidates of each split in chunks
of consecutive seeds. Every finished chunk is written atomically to the work folder, so a killed
build resumes where it stopped and never reruns a finished chunk. When the first ``train_tasks``
(``test_tasks``) candidates of every tier are known, the pools, the label of every candidate
examined and the counts are written to ``envs/benchmark/v1_tasks.json`` (atomically).
"""

from __future__ import annotations

import hashlib
import json
import time
from collections import Counter
from collections.abc import Callable
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

from tqdm.auto import tqdm

from ffsr_gym.exceptions import FFSRError
from ffsr_gym.model.benchmark import Benchmark, load_benchmark
from ffsr_gym.model.resources import envs_dir
from ffsr_gym.provenance import provenance, write_json_atomic
from ffsr_gym.tasks.splits import LABEL_CODES, SEED_RANGES, SPLITS, pool_path
from ffsr_gym.tasks.tiers import REJECTIONS, TIERS, Verdict, classify


def rule_sha256() -> str:
    """Hash of the benchmark definition file (the tier rule's numbers)."""
    return hashlib.sha256((envs_dir() / "benchmark" / "v1.toml").read_bytes()).hexdigest()


def classify_chunk(split: str, start: int, stop: int) -> list[dict[str, Any]]:
    """Verdicts (as dicts) of the candidate seeds [start, stop) (a worker's unit of work)."""
    benchmark = load_benchmark("v1")
    return [classify(seed, benchmark).as_dict() for seed in range(start, stop)]


def _chunk_path(work: Path, split: str, start: int) -> Path:
    return work / split / f"{start:07d}.json"


def _load_chunk(path: Path, sha: str) -> list[Verdict] | None:
    if not path.exists():
        return None
    data = json.loads(path.read_text(encoding="utf-8"))
    if data.get("rule_sha256") != sha:
        raise FFSRError(f"{path} was built with another v1.toml (rule hash {data.get('rule_sha256')}); "
                        "use a new --work folder")
    return [Verdict.from_dict(v) for v in data["verdicts"]]


def _needed(benchmark: Benchmark, split: str) -> int:
    rule = benchmark.tasks
    return int(rule.train_tasks if split == "train" else rule.test_tasks)


def _complete(verdicts: list[Verdict], needed: int) -> bool:
    counts = Counter(v.tier for v in verdicts)
    return all(counts[tier] >= needed for tier in TIERS)


def build_split(work: Path, split: str, *, chunk: int = 100, max_candidates: int = 50_000,
                executor: Executor | None = None, workers: int = 1, progress: bool = True) -> list[Verdict]:
    """Classify the candidates of ``split`` chunk by chunk until every tier's pool is full.

    Returns the verdicts of the consecutive candidates from the split's first seed on.

    Raises:
        FFSRError: a tier is still short after ``max_candidates`` candidates, or a chunk of the
            work folder was built under another rule.
    """
    benchmark, sha = load_benchmark("v1"), rule_sha256()
    needed, first = _needed(benchmark, split), SEED_RANGES[split][0]
    verdicts: list[Verdict] = []
    with tqdm(desc=f"tasks {split}", unit="task", disable=not progress) as bar:
        start = first
        while not _complete(verdicts, needed):
            if start - first >= max_candidates:
                counts = Counter(v.tier for v in verdicts)
                raise FFSRError(f"split {split}: after {max_candidates} candidates the pools hold {dict(counts)}, "
                                f"{needed} needed per tier; raise --max-candidates")
            starts = [start + i * chunk for i in range(max(1, workers))]
            missing = [s for s in starts if not _chunk_path(work, split, s).exists()]
            run: Callable = executor.map if executor is not None else map
            for s, result in zip(missing, run(classify_chunk, [split] * len(missing), missing,
                                              [s + chunk for s in missing])):
                write_json_atomic(_chunk_path(work, split, s), {"split": split, "start": s, "stop": s + chunk,
                                                                "rule_sha256": sha, "verdicts": result})
            for s in starts:
                verdicts += _load_chunk(_chunk_path(work, split, s), sha)
            counts = Counter(v.tier for v in verdicts)
            bar.update(len(starts) * chunk)
            bar.set_postfix({tier: f"{counts[tier]}/{needed}" for tier in TIERS})
            start += len(starts) * chunk
    return verdicts


def summarise_split(verdicts: list[Verdict], needed: int) -> dict[str, Any]:
    """The pools, labels and counts of a split from its consecutive verdicts (trimmed to the last pool seed)."""
    pools: dict[str, list[Verdict]] = {tier: [] for tier in TIERS}
    last = 0
    for i, v in enumerate(verdicts):
        if v.tier is not None and len(pools[v.tier]) < needed:
            pools[v.tier].append(v)
            last = i
    examined = verdicts[:last + 1]
    labels = [v.tier or v.rejection for v in examined]
    rejected = [v for v in examined if v.tier is None]
    counts = Counter(labels)
    return {
        "first_seed": examined[0].seed,
        "candidates": len(examined),
        "labels": "".join(LABEL_CODES[label] for label in labels),
        "tier_counts": {tier: counts[tier] for tier in TIERS},
        "rejection_counts": {cause: counts[cause] for cause in REJECTIONS},
        "rejection_shares": {cause: counts[cause] / max(1, len(rejected)) for cause in REJECTIONS},
        "rejected_but_constant_solvable": sum(v.constant_solvable for v in rejected),
        "default_success_in_pool": {tier: sum(v.default_failure is None for v in pools[tier]) / needed for tier in TIERS},
        "pools": {tier: [{"seed": v.seed, "certificate": v.certificate.as_dict(), "certificate_score": v.certificate_score,
                          "default_failure": v.default_failure} for v in pools[tier]] for tier in TIERS},
    }


def build(work: str | Path, *, out: str | Path | None = None, chunk: int = 100, max_candidates: int = 50_000,
          executor: Executor | None = None, workers: int = 1, progress: bool = True) -> dict[str, Any]:
    """Build both splits (resuming from ``work``) and write the pool file ``out`` (default: the shipped one)."""
    began, work = time.perf_counter(), Path(work)
    benchmark = load_benchmark("v1")
    splits = {}
    for split in SPLITS:
        verdicts = build_split(work, split, chunk=chunk, max_candidates=max_candidates, executor=executor,
                               workers=workers, progress=progress)
        splits[split] = summarise_split(verdicts, _needed(benchmark, split))
    data = {"version": "v1", "rule_sha256": rule_sha256(), "seed_ranges": SEED_RANGES, "label_codes": LABEL_CODES,
            "provenance": provenance(wall_time_s=time.perf_counter() - began), "splits": splits}
    write_json_atomic(pool_path() if out is None else out, data)
    return data


def tier_table(data: dict[str, Any]) -> str:
    """Markdown table of a pool file's counts: candidates, tiers, rejection shares, default success."""
    lines = ["| split | candidates | easy | medium | hard | rejected | rejected, a constant setting solves | "
             + " | ".join(f"`{cause}`" for cause in REJECTIONS) + " |",
             "|---" * (7 + len(REJECTIONS)) + "|"]
    for split in SPLITS:
        s = data["splits"][split]
        rejected = s["candidates"] - sum(s["tier_counts"].values())
        shares = " | ".join(f"{100 * s['rejection_shares'][cause]:.1f} %" for cause in REJECTIONS)
        lines.append(f"| {split} | {s['candidates']} | " + " | ".join(str(s["tier_counts"][t]) for t in TIERS)
                     + f" | {rejected} | {s['rejected_but_constant_solvable']} | {shares} |")
    return "\n".join(lines) + "\n"
