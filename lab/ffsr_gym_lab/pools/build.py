"""Build a benchmark version's task pools: apply the tier rule to candidate seeds, in resumable chunks.

``ffsr-gym tasks build --version v2 --work studies/tasks-v2`` classifies the candidates of each split
in chunks of consecutive seeds. Every finished chunk is written atomically to the work folder, so a
killed build resumes where it stopped and never reruns a finished chunk. When the first
``<split>_tasks`` candidates of every tier are known, the pools, the label of every candidate
examined and the counts are written to ``envs/benchmark/<version>_tasks.json`` (atomically).

With an ensemble whose ``pinocchio`` is set (v2), the pool candidates are then replayed on the
Pinocchio backend in seed order (a second, resumable stage: ``<work>/<split>/pinocchio.json``; the
``servo`` tier, whose plant only the kernel runs, replays them at a finer physics step instead,
:func:`~ffsr_gym.tasks.perturbation.confirmation_member`); a candidate that fails there is
relabelled ``fragile`` and the next candidate of its tier takes its place. The kernel members run for every candidate, the Pinocchio member (about 150 times slower)
for the pool candidates only.

``--tier debris`` (``robust``, ``servo``) builds a perturbed tier the same way, into ``<work>/<tier>`` and
``envs/benchmark/<version>_<tier>_tasks.json``; its candidates are the seeds that the version's
pool file labels easy, medium or hard (:mod:`ffsr_gym.tasks.perturbation`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import time
from collections import Counter
from collections.abc import Callable
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

from tqdm.auto import tqdm

from ffsr_gym.exceptions import FFSRError
from ffsr_gym.model.drives import drives_path
from ffsr_gym.model.resources import envs_dir, robot_dir
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.provenance import provenance, write_json_atomic
from ffsr_gym.tasks.capture_family import CAPTURE_REJECTIONS, CAPTURE_TIERS, classify_capture
from ffsr_gym.tasks.capture_timed import NOMINAL_KEYS, TIMED_REJECTIONS, TIMED_TIERS, classify_timed
from ffsr_gym.tasks.certificate import Certificate, Margins, replay_with_margins
from ffsr_gym.tasks.perturbation import (
    PERTURBED_TIERS,
    confirmation_member,
    load_perturbed_rule,
    perturbed_rule_sha256,
    servo_rule_path,
)
from ffsr_gym.tasks.splits import LABEL_CODES, SEED_RANGES, expected_count, load_pools, pool_path, task_scenario
from ffsr_gym.tasks.tiers import PERTURBED_REJECTIONS, REJECTIONS, TIERS, Verdict, classify, classify_perturbed
from ffsr_gym.versions.registry import load_benchmark

_ADMITTED = {LABEL_CODES[tier] for tier in TIERS}


def targets(version: str) -> tuple[str, ...]:
    """What ``--tier`` builds for ``version``: the rule file's tiers together (named after the version), or one
    perturbed tier; a capture rule file's tiers, one at a time."""
    benchmark = load_benchmark(version)
    if benchmark.tasks.family == "capture_timed":
        return TIMED_TIERS
    if benchmark.capture is not None:
        return CAPTURE_TIERS
    return (version, *PERTURBED_TIERS)


def _one_tier(target: str) -> bool:
    """Whether ``target`` is one tier with a pool file of its own (perturbed or capture)."""
    return target in PERTURBED_TIERS or target in CAPTURE_TIERS or target in TIMED_TIERS


def _check_target(target: str, version: str) -> None:
    if target not in targets(version):
        raise FFSRError(f"tier {target!r}; allowed: {list(targets(version))}")


def rule_sha256(target: str, version: str) -> str:
    """Hash of the rule a pool file was built under (``<version>.toml``; a perturbed tier: also
    ``<version>_perturbed.toml`` and the version's pool file its candidates come from; ``servo``: also
    ``<version>_servo.toml`` and the robot's drive file; a capture v1 tier: also its family's scenario file, whose
    episode and approach it plays)."""
    _check_target(target, version)
    digest = hashlib.sha256((envs_dir() / "benchmark" / f"{version}.toml").read_bytes())
    if target in TIMED_TIERS:
        digest.update((envs_dir() / "scenarios" / f"{load_benchmark(version).tasks.family}.toml").read_bytes())
    if target in PERTURBED_TIERS:
        digest.update(perturbed_rule_sha256(version).encode())
        digest.update(pool_path(version=version).read_bytes())
    if target == "servo":  # its plant settings, and the drives of the family's robot
        digest.update(Path(servo_rule_path(version)).read_bytes())
        digest.update(drives_path(robot_dir(load_scenario(load_benchmark(version).tasks.family).robot)).read_bytes())
    return digest.hexdigest()


def base_admitted(split: str, start: int, stop: int, version: str) -> list[bool]:
    """Whether ``version``'s pool file labels each seed of [start, stop) easy, medium or hard.

    Raises:
        FFSRError: a seed beyond the candidates the pool file labels.
    """
    summary = load_pools(version=version)["splits"][split]
    first, labels = int(summary["first_seed"]), summary["labels"]
    if stop - first > len(labels):
        raise FFSRError(f"split {split}: the {version} pool file labels seeds up to {first + len(labels) - 1}; the "
                        f"perturbed tiers need seeds up to {stop - 1} (their candidates are its tier tasks)")
    return [labels[seed - first] in _ADMITTED for seed in range(start, stop)]


def classify_chunk(split: str, start: int, stop: int, target: str, version: str) -> list[dict[str, Any]]:
    """Verdicts (as dicts) of the candidate seeds [start, stop) (a worker's unit of work)."""
    benchmark = load_benchmark(version)
    if target in CAPTURE_TIERS:
        return [classify_capture(target, seed, benchmark).as_dict() for seed in range(start, stop)]
    if target in TIMED_TIERS:
        return [classify_timed(target, seed, benchmark).as_dict() for seed in range(start, stop)]
    if target not in PERTURBED_TIERS:
        return [classify(seed, benchmark).as_dict() for seed in range(start, stop)]
    rule = load_perturbed_rule(version)
    return [classify_perturbed(target, seed, benchmark, base_admitted=admitted, rule=rule).as_dict()
            for seed, admitted in zip(range(start, stop), base_admitted(split, start, stop, version))]


def confirm(tier: str, seed: int, certificate: dict[str, Any], version: str) -> dict[str, Any]:
    """The ensemble's last member (:func:`~ffsr_gym.tasks.perturbation.confirmation_member`: the Pinocchio
    backend, or a servo task's finer physics step): ``certificate`` replayed there (a worker's unit of work).

    Returns ``{"seed", "success", "margins"}``: success with the ensemble's margins, and that episode's margins.
    """
    benchmark = load_benchmark(version)
    member = confirmation_member(task_scenario(tier, seed, benchmark), version)
    result, margins = replay_with_margins(member.task, Certificate.from_dict(certificate), benchmark,
                                          backend=member.backend)
    return {"seed": int(seed), "success": result.success and margins.short(benchmark) is None,
            "margins": margins.as_dict()}


def _work_dir(work: Path, target: str) -> Path:
    return work / target if _one_tier(target) else work


def _chunk_path(work: Path, split: str, start: int) -> Path:
    return work / split / f"{start:07d}.json"


def _load_chunk(path: Path, sha: str) -> list[Verdict] | None:
    if not path.exists():
        return None
    data = json.loads(path.read_text(encoding="utf-8"))
    if data.get("rule_sha256") != sha:
        raise FFSRError(f"{path} was built under another rule file (rule hash {data.get('rule_sha256')}); "
                        "use a new --work folder")
    return [Verdict.from_dict(v) for v in data["verdicts"]]


def _tiers(target: str) -> tuple[str, ...]:
    return (target,) if _one_tier(target) else TIERS


def _complete(verdicts: list[Verdict], want: dict[str, int]) -> bool:
    counts = Counter(v.tier for v in verdicts)
    return all(counts[tier] >= n for tier, n in want.items())


def build_split(work: Path, split: str, *, version: str, target: str | None = None, chunk: int = 100,
                max_candidates: int = 50_000, executor: Executor | None = None, workers: int = 1,
                progress: bool = True) -> list[Verdict]:
    """Classify the candidates of ``split`` chunk by chunk until every tier's pool is full (and, with a
    Pinocchio ensemble member, confirmed there).

    Returns the verdicts of the consecutive candidates from the split's first seed on; a candidate
    the Pinocchio member fails is relabelled ``fragile``, one it confirms carries the worst margins
    of both stages.

    Raises:
        FFSRError: a tier is still short after ``max_candidates`` candidates, or a chunk of the
            work folder was built under another rule.
    """
    target = version if target is None else target
    _check_target(target, version)
    ensemble = load_benchmark(version).tasks.ensemble
    needed, work = expected_count(_tiers(target)[0], split, version), _work_dir(Path(work), target)
    confirmations = work / split / "pinocchio.json"
    confirmed: dict[int, dict[str, Any]] = {}
    if confirmations.exists():
        confirmed = {row["seed"]: row for row in json.loads(confirmations.read_text(encoding="utf-8"))["rows"]}
    want = dict.fromkeys(_tiers(target), needed)
    while True:
        verdicts = _classified(work, split, version, target, want, chunk, max_candidates, executor, workers, progress)
        if ensemble is None or not ensemble.pinocchio:
            return verdicts
        pending = [v for tier in want for v in [v for v in verdicts if v.tier == tier][:want[tier]]
                   if v.seed not in confirmed]
        if not pending:
            break
        _confirm(pending, confirmed, confirmations, version, executor, workers, progress)
        want = {tier: needed + sum(not confirmed[v.seed]["success"] for v in verdicts if v.tier == tier
                                   and v.seed in confirmed) for tier in want}
    return [_confirmed(v, confirmed.get(v.seed)) for v in verdicts]


def _confirmed(verdict: Verdict, row: dict[str, Any] | None) -> Verdict:
    """``verdict`` after its Pinocchio replay ``row`` (None: not replayed; unchanged)."""
    if row is None or verdict.tier is None:
        return verdict
    if not row["success"]:
        return dataclasses.replace(verdict, tier=None, rejection="fragile", certificate=None, certificate_score=0.0)
    return dataclasses.replace(verdict, margins=verdict.margins.merge(Margins.from_dict(row["margins"])))


def _confirm(pending: list[Verdict], confirmed: dict[int, dict[str, Any]], path: Path, version: str,
             executor: Executor | None, workers: int, progress: bool) -> None:
    """Replay ``pending`` in the ensemble's last member (:func:`confirm`), saving ``confirmed`` atomically after
    every batch."""
    run: Callable = executor.map if executor is not None else map
    batch = max(1, workers) * 4
    with tqdm(total=len(pending), desc=f"last ensemble member, {path.parent.name}", unit="task", disable=not progress) as bar:
        for i in range(0, len(pending), batch):
            part = pending[i:i + batch]
            for row in run(confirm, [v.tier for v in part], [v.seed for v in part],
                           [v.certificate.as_dict() for v in part], [version] * len(part)):
                confirmed[row["seed"]] = row
            write_json_atomic(path, {"rows": sorted(confirmed.values(), key=lambda r: r["seed"])})
            bar.update(len(part))


def _classified(work: Path, split: str, version: str, target: str, want: dict[str, int], chunk: int,
                max_candidates: int, executor: Executor | None, workers: int, progress: bool) -> list[Verdict]:
    """The verdicts of the split's consecutive candidates, classified chunk by chunk until each tier has ``want`` of them."""
    sha, first = rule_sha256(target, version), SEED_RANGES[split][0]
    _check_chunking(work, split, chunk)
    verdicts: list[Verdict] = []
    with tqdm(desc=f"tasks {target} {split}", unit="task", disable=not progress) as bar:
        start = first
        while not _complete(verdicts, want):
            if start - first >= max_candidates:
                counts = Counter(v.tier for v in verdicts)
                raise FFSRError(f"split {split}: after {max_candidates} candidates the pools hold {dict(counts)}, "
                                f"{want} needed; raise --max-candidates")
            starts = [start + i * chunk for i in range(max(1, workers))]
            missing = [s for s in starts if not _chunk_path(work, split, s).exists()]
            run: Callable = executor.map if executor is not None else map
            for s, result in zip(missing, run(classify_chunk, [split] * len(missing), missing,
                                              [s + chunk for s in missing], [target] * len(missing),
                                              [version] * len(missing))):
                write_json_atomic(_chunk_path(work, split, s), {"split": split, "start": s, "stop": s + chunk,
                                                                "rule_sha256": sha, "verdicts": result})
            for s in starts:
                verdicts += _load_chunk(_chunk_path(work, split, s), sha)
            counts = Counter(v.tier for v in verdicts)
            bar.update(len(starts) * chunk)
            bar.set_postfix({tier: f"{counts[tier]}/{n}" for tier, n in want.items()}
                            | {"to go": candidates_to_go(counts, want, len(verdicts))})
            start += len(starts) * chunk
    return verdicts


def candidates_to_go(counts: Counter, want: dict[str, int], examined: int) -> str:
    """About how many more candidates the split needs, at the admission rate of those ``examined`` so far (the
    slowest tier decides; "?" before any is admitted)."""
    left = [(n - counts[tier]) * examined / counts[tier] if counts[tier] else math.inf
            for tier, n in want.items() if counts[tier] < n]
    worst = max(left, default=0.0)
    return "?" if math.isinf(worst) else f"~{round(worst):,}"


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


def summarise_split(verdicts: list[Verdict], needed: int, target: str) -> dict[str, Any]:
    """The pools, labels and counts of a split from its consecutive verdicts (trimmed to the last pool seed)."""
    tiers = _tiers(target)
    rejections = (CAPTURE_REJECTIONS if target in CAPTURE_TIERS else TIMED_REJECTIONS if target in TIMED_TIERS
                  else PERTURBED_REJECTIONS if target in PERTURBED_TIERS else REJECTIONS)
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
        "pool_margins": {tier: _pool_margins(pools[tier]) for tier in tiers},
        "default_failures_in_pool": {tier: dict(Counter(v.default_failure or "none" for v in pools[tier]))
                                     for tier in tiers},
        "pools": {tier: [_pool_entry(v) for v in pools[tier]] for tier in tiers},
    }


def _pool_entry(v: Verdict) -> dict[str, Any]:
    entry = {"seed": v.seed, "certificate": v.certificate.as_dict(), "certificate_score": v.certificate_score,
             "default_failure": v.default_failure}
    if len(v.nominal) == 3:  # screening's measurements of the nominal motion (base tiers)
        entry["nominal"] = {"final_ee_position_error_m": v.nominal[0], "min_balance_sigma": v.nominal[1],
                            "min_self_clearance_m": v.nominal[2]}
    elif v.tier in TIMED_TIERS:  # a capture v1 tier's (capture_timed.classify_timed)
        entry["nominal"] = dict(zip(NOMINAL_KEYS, v.nominal))
    elif v.nominal:  # a capture tier's (capture_family.classify_capture)
        entry["nominal"] = dict(zip(("capture_time_s", "min_mission_sigma", "min_balance_sigma", "min_self_clearance_m",
                                     "peak_rate_deg_s"), v.nominal))
    if v.margins is not None and v.margins.episodes > 1:
        entry["margins"] = v.margins.as_dict()
    return entry


def _pool_margins(pool: list[Verdict]) -> dict[str, Any] | None:
    """Over a pool's certificates: the worst ensemble margins, and the median of each certificate's worst clearance."""
    if not pool or any(v.margins is None for v in pool):
        return None
    worst = pool[0].margins
    for v in pool[1:]:
        worst = worst.merge(v.margins)
    clearances = sorted(v.margins.min_clearance_m for v in pool)
    return {**worst.as_dict(), "median_min_clearance_m": clearances[len(clearances) // 2]}


def build(work: str | Path, *, version: str, target: str | None = None, out: str | Path | None = None,
          chunk: int = 100, max_candidates: int = 50_000, executor: Executor | None = None, workers: int = 1,
          progress: bool = True) -> dict[str, Any]:
    """Build every split of ``target`` (the version's name: easy, medium and hard; or a perturbed tier),
    resuming from ``work``, and write the pool file ``out`` (default: the shipped one)."""
    target = version if target is None else target
    _check_target(target, version)
    began, work, tiers = time.perf_counter(), Path(work), _tiers(target)
    splits = {}
    for split in load_benchmark(version).tasks.splits:
        verdicts = build_split(work, split, version=version, target=target, chunk=chunk, max_candidates=max_candidates,
                               executor=executor, workers=workers, progress=progress)
        splits[split] = summarise_split(verdicts, expected_count(tiers[0], split, version), target)
    data = {"version": version, "tiers": list(tiers), "rule_sha256": rule_sha256(target, version),
            "seed_ranges": {split: SEED_RANGES[split] for split in splits}, "label_codes": LABEL_CODES,
            "provenance": provenance(wall_time_s=time.perf_counter() - began), "splits": splits}
    write_json_atomic(pool_path(tiers[0], version) if out is None else out, data)
    return data


