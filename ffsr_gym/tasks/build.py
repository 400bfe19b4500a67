"""Build the v1 task pools: apply the tier rule to candidate seeds, in resumable chunks.

``ffsr-gym tasks build --work runs/tasks-v1`` classifies the candidates of each split in chunks
of consecutive seeds. Every finished chunk is written atomically to the work folder, so a killed
build resumes where it stopped and never reruns a finished chunk. When the first ``train_tasks``
(``test_tasks``) candidates of every tier are known, the pools, the label of every candidate
examined and the counts are written to ``envs/benchmark/v1_tasks.json`` (atomically).

``--tier debris`` (``robust``) builds a perturbed tier the same way, into ``<work>/<tier>`` and
``envs/benchmark/v1_<tier>_tasks.json``; its candidates are the seeds that the v1 pool file
labels easy, medium or hard (:mod:`ffsr_gym.tasks.perturbation`).
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
from ffsr_gym.model.benchmark import load_benchmark
from ffsr_gym.model.resources import envs_dir
from ffsr_gym.provenance import provenance, write_json_atomic
from ffsr_gym.tasks.perturbation import PERTURBED_TIERS, load_perturbed_rule, perturbed_rule_sha256
from ffsr_gym.tasks.splits import LABEL_CODES, SEED_RANGES, SPLITS, expected_count, load_pools, pool_path
from ffsr_gym.tasks.tiers import PERTURBED_REJECTIONS, REJECTIONS, TIERS, Verdict, classify, classify_perturbed

#: The rule file whose tiers the build applies (its hash is the pools' ``rule_sha256``).
RULES = "v1"
#: What ``--tier`` builds: the rule file's tiers together (named after it), or one perturbed tier.
TARGETS = (RULES, *PERTURBED_TIERS)
_ADMITTED = {LABEL_CODES[tier] for tier in TIERS}


def _check_target(target: str) -> None:
    if target not in TARGETS:
        raise FFSRError(f"tier {target!r}; allowed: {list(TARGETS)}")


def rule_sha256(target: str = RULES) -> str:
    """Hash of the rule a pool file was built under (``v1.toml``; a perturbed tier: also ``v1_perturbed.toml``
    and the v1 pool file its candidates come from)."""
    _check_target(target)
    digest = hashlib.sha256((envs_dir() / "benchmark" / f"{RULES}.toml").read_bytes())
    if target in PERTURBED_TIERS:
        digest.update(perturbed_rule_sha256().encode())
        digest.update(pool_path().read_bytes())
    return digest.hexdigest()


def base_admitted(split: str, start: int, stop: int) -> list[bool]:
    """Whether the v1 pool file labels each seed of [start, stop) easy, medium or hard.

    Raises:
        FFSRError: a seed beyond the candidates the v1 pool file labels.
    """
    summary = load_pools()["splits"][split]
    first, labels = int(summary["first_seed"]), summary["labels"]
    if stop - first > len(labels):
        raise FFSRError(f"split {split}: the v1 pool file labels seeds up to {first + len(labels) - 1}; the perturbed "
                        f"tiers need seeds up to {stop - 1} (their candidates are v1 tier tasks)")
    return [labels[seed - first] in _ADMITTED for seed in range(start, stop)]


def classify_chunk(split: str, start: int, stop: int, target: str = RULES) -> list[dict[str, Any]]:
    """Verdicts (as dicts) of the candidate seeds [start, stop) (a worker's unit of work)."""
    benchmark = load_benchmark(RULES)
    if target not in PERTURBED_TIERS:
        return [classify(seed, benchmark).as_dict() for seed in range(start, stop)]
    rule = load_perturbed_rule()
    return [classify_perturbed(target, seed, benchmark, base_admitted=admitted, rule=rule).as_dict()
            for seed, admitted in zip(range(start, stop), base_admitted(split, start, stop))]


def _work_dir(work: Path, target: str) -> Path:
    return work / target if target in PERTURBED_TIERS else work


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


def _tiers(target: str) -> tuple[str, ...]:
    return (target,) if target in PERTURBED_TIERS else TIERS


def _complete(verdicts: list[Verdict], needed: int, tiers: tuple[str, ...]) -> bool:
    counts = Counter(v.tier for v in verdicts)
    return all(counts[tier] >= needed for tier in tiers)


def build_split(work: Path, split: str, *, target: str = RULES, chunk: int = 100, max_candidates: int = 50_000,
                executor: Executor | None = None, workers: int = 1, progress: bool = True) -> list[Verdict]:
    """Classify the candidates of ``split`` chunk by chunk until every tier's pool is full.

    Returns the verdicts of the consecutive candidates from the split's first seed on.

    Raises:
        FFSRError: a tier is still short after ``max_candidates`` candidates, or a chunk of the
            work folder was built under another rule.
    """
    _check_target(target)
    sha, tiers = rule_sha256(target), _tiers(target)
    needed, first, work = expected_count(tiers[0], split), SEED_RANGES[split][0], _work_dir(Path(work), target)
    _check_chunking(work, split, chunk)
    verdicts: list[Verdict] = []
    with tqdm(desc=f"tasks {target} {split}", unit="task", disable=not progress) as bar:
        start = first
        while not _complete(verdicts, needed, tiers):
            if start - first >= max_candidates:
                counts = Counter(v.tier for v in verdicts)
                raise FFSRError(f"split {split}: after {max_candidates} candidates the pools hold {dict(counts)}, "
                                f"{needed} needed per tier; raise --max-candidates")
            starts = [start + i * chunk for i in range(max(1, workers))]
            missing = [s for s in starts if not _chunk_path(work, split, s).exists()]
            run: Callable = executor.map if executor is not None else map
            for s, result in zip(missing, run(classify_chunk, [split] * len(missing), missing,
                                              [s + chunk for s in missing], [target] * len(missing))):
                write_json_atomic(_chunk_path(work, split, s), {"split": split, "start": s, "stop": s + chunk,
                                                                "rule_sha256": sha, "verdicts": result})
            for s in starts:
                verdicts += _load_chunk(_chunk_path(work, split, s), sha)
            counts = Counter(v.tier for v in verdicts)
            bar.update(len(starts) * chunk)
            bar.set_postfix({tier: f"{counts[tier]}/{needed}" for tier in tiers})
            start += len(starts) * chunk
    return verdicts


def _check_chunking(work: Path, split: str, chunk: int) -> None:
    """Refuse to resume a work folder built with another chunk size (its chunks would skip or repeat seeds).

    Raises:
        FFSRError: naming both chunk sizes.
    """
    for path in sorted((work / split).glob("*.json"))[:1]:
        data = json.loads(path.read_text(encoding="utf-8"))
        if data.get("stop", 0) - data.get("start", 0) != chunk:
            raise FFSRError(f"{work}: its chunks hold {data.get('stop', 0) - data.get('start', 0)} candidates each, "
                            f"this run --chunk {chunk}; resume with the same --chunk, or use a new --work folder")


def die_with_parent() -> None:
    """Process-pool initializer: on Linux, the worker is killed when its parent dies (a ``kill -9`` of a build
    leaves no orphaned workers); elsewhere nothing."""
    try:
        import ctypes
        import signal

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def summarise_split(verdicts: list[Verdict], needed: int, target: str = RULES) -> dict[str, Any]:
    """The pools, labels and counts of a split from its consecutive verdicts (trimmed to the last pool seed)."""
    tiers = _tiers(target)
    rejections = PERTURBED_REJECTIONS if target in PERTURBED_TIERS else REJECTIONS
    pools: dict[str, list[Verdict]] = {tier: [] for tier in tiers}
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
        "tier_counts": {tier: counts[tier] for tier in tiers},
        "rejection_counts": {cause: counts[cause] for cause in rejections},
        "rejection_shares": {cause: counts[cause] / max(1, len(rejected)) for cause in rejections},
        "rejected_but_constant_solvable": sum(v.constant_solvable for v in rejected),
        "default_success_in_pool": {tier: sum(v.default_failure is None for v in pools[tier]) / needed
                                    for tier in tiers},
        "pools": {tier: [{"seed": v.seed, "certificate": v.certificate.as_dict(), "certificate_score": v.certificate_score,
                          "default_failure": v.default_failure} for v in pools[tier]] for tier in tiers},
    }


def build(work: str | Path, *, target: str = RULES, out: str | Path | None = None, chunk: int = 100,
          max_candidates: int = 50_000, executor: Executor | None = None, workers: int = 1,
          progress: bool = True) -> dict[str, Any]:
    """Build both splits of ``target`` (``v1``: easy, medium and hard; or a perturbed tier), resuming from
    ``work``, and write the pool file ``out`` (default: the shipped one)."""
    _check_target(target)
    began, work = time.perf_counter(), Path(work)
    splits = {}
    for split in SPLITS:
        verdicts = build_split(work, split, target=target, chunk=chunk, max_candidates=max_candidates,
                               executor=executor, workers=workers, progress=progress)
        splits[split] = summarise_split(verdicts, expected_count(_tiers(target)[0], split), target)
    data = {"version": RULES, "tiers": list(_tiers(target)), "rule_sha256": rule_sha256(target),
            "seed_ranges": SEED_RANGES, "label_codes": LABEL_CODES,
            "provenance": provenance(wall_time_s=time.perf_counter() - began), "splits": splits}
    write_json_atomic(pool_path(_tiers(target)[0]) if out is None else out, data)
    return data


def tier_table(data: dict[str, Any]) -> str:
    """Markdown table of a pool file's counts: candidates, tiers, rejection shares (a perturbed tier:
    the v1 tier tasks perturbed, the share certified and the default planner's success in the pool)."""
    tiers = tuple(data.get("tiers", TIERS))
    if tiers != TIERS:
        return _perturbed_table(data, tiers[0])
    lines = ["| split | candidates | " + " | ".join(tiers) + " | rejected | rejected, a constant setting solves | "
             + " | ".join(f"`{cause}`" for cause in REJECTIONS) + " |",
             "|---" * (4 + len(tiers) + len(REJECTIONS)) + "|"]
    for split in SPLITS:
        s = data["splits"][split]
        rejected = s["candidates"] - sum(s["tier_counts"].values())
        shares = " | ".join(f"{100 * s['rejection_shares'][cause]:.1f} %" for cause in REJECTIONS)
        lines.append(f"| {split} | {s['candidates']} | " + " | ".join(str(s["tier_counts"][t]) for t in tiers)
                     + f" | {rejected} | {s['rejected_but_constant_solvable']} | {shares} |")
    return "\n".join(lines) + "\n"


def _perturbed_table(data: dict[str, Any], tier: str) -> str:
    unsolved = [cause for cause in PERTURBED_REJECTIONS if cause != "base_rejected"]
    lines = ["| split | seeds examined | v1 tier tasks perturbed | certified (in the pool) | certified share | "
             + " | ".join(f"`{cause}`" for cause in unsolved) + " | reference (0.3, 4 s) succeeds, pool |",
             "|---" * (6 + len(unsolved)) + "|"]
    for split in SPLITS:
        s = data["splits"][split]
        counts = s["rejection_counts"]
        perturbed = s["candidates"] - counts["base_rejected"]
        certified = s["tier_counts"][tier]
        lines.append(f"| {split} | {s['candidates']} | {perturbed} | {certified} | "
                     f"{100 * certified / perturbed:.1f} % | "
                     + " | ".join(str(counts[cause]) for cause in unsolved)
                     + f" | {100 * s['default_success_in_pool'][tier]:.1f} % |")
    return "\n".join(lines) + "\n"
