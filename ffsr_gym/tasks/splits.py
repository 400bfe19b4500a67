"""Train, validation and test pools of a benchmark version's task tiers: seed ranges and pool files.

The candidate seeds of the splits are disjoint ranges (:data:`SEED_RANGES`). Each tier's pool of a
split is the first ``<split>_tasks`` candidates of the split's range that the tier rule
(:mod:`ffsr_gym.tasks.tiers`) puts in that tier, in seed order. ``ffsr-gym tasks build`` applies the
rule and writes ``envs/benchmark/<version>_tasks.json`` (the pools with their certificates, the
label of every candidate examined, and the counts); environments read the pools from there. The
perturbed tiers (:mod:`ffsr_gym.tasks.perturbation`) have one such file each,
``<version>_<tier>_tasks.json``, over the same seed ranges. A rule file without validation tasks
has train and test splits only.

``version`` defaults to the live ranked benchmark (:func:`ffsr_gym.versions.registry.ranked_spec`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.model.benchmark import Benchmark
from ffsr_gym.model.resources import envs_dir
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.tasks.capture_family import CAPTURE_REJECTIONS, CAPTURE_TIERS, draw_capture_task
from ffsr_gym.tasks.capture_timed import TIMED_REJECTIONS, TIMED_TIERS, draw_timed_task
from ffsr_gym.tasks.certificate import Certificate, Margins
from ffsr_gym.tasks.generator import draw_task
from ffsr_gym.tasks.perturbation import PERTURBED_TIERS, load_perturbed_rule, perturbed_task
from ffsr_gym.tasks.tiers import ALL_TIERS, PERTURBED_REJECTIONS, REJECTIONS, TIERS
from ffsr_gym.versions.registry import load_benchmark, ranked_spec

#: Every split a version may have (:attr:`ffsr_gym.model.benchmark.TaskRule.splits`: its own).
SPLITS = ("train", "validation", "test")
#: Candidate seeds of each split: [first, end).
SEED_RANGES = {"train": (0, 1_000_000), "validation": (2_000_000, 3_000_000), "test": (1_000_000, 2_000_000)}
#: One character per candidate label in the pool file.
LABEL_CODES = {"easy": "e", "medium": "m", "hard": "h", "nominal_final_error": "f", "balance_singularity": "b",
               "self_collision": "s", "unsolved_rate_limit": "r", "unsolved_collision": "c", "unsolved_final_error": "t",
               "debris": "D", "robust": "R", "servo": "S", "base_rejected": "x", "draw_failed": "d", "fragile": "g",
               "slow": "L", "fast": "F", "nominal_no_capture": "n", "mission_singularity": "w",
               "unsolved_no_capture": "u", "sweep": "W", "nutation": "N", "no_timing_captures": "o", "unsolved": "U",
               "straight_in_captures": "i"}
assert set(LABEL_CODES) == set(ALL_TIERS + REJECTIONS + PERTURBED_REJECTIONS + CAPTURE_TIERS + CAPTURE_REJECTIONS
                               + TIMED_TIERS + TIMED_REJECTIONS)


@dataclass(frozen=True)
class PoolTask:
    """One task of a pool: its seed, certificate, the certificate's score and (with an ensemble) its worst margins."""

    seed: int
    certificate: Certificate
    certificate_score: float
    margins: Margins | None = None


def live_version(version: str | None = None) -> str:
    """``version``, or the live ranked benchmark's when None."""
    return ranked_spec().rules.version if version is None else version


def version_splits(version: str | None = None) -> tuple[str, ...]:
    """The splits of ``version``'s pools."""
    return load_benchmark(live_version(version)).tasks.splits


def pool_path(tier: str = "easy", version: str | None = None) -> Path:
    """The shipped pool file of ``tier`` (``<version>_tasks.json`` for easy, medium and hard)."""
    version = live_version(version)
    name = f"{version}_tasks.json" if tier in TIERS else f"{version}_{tier}_tasks.json"
    return envs_dir() / "benchmark" / name


def version_tiers(version: str | None = None) -> tuple[str, ...]:
    """The tiers of ``version``'s pools: :data:`ALL_TIERS`, a capture rule file's :data:`CAPTURE_TIERS`, or capture
    v1's :data:`TIMED_TIERS`."""
    benchmark = load_benchmark(live_version(version))
    if benchmark.tasks.family == "capture_timed":
        return TIMED_TIERS
    return CAPTURE_TIERS if benchmark.capture is not None else ALL_TIERS


def check_tier_split(tier: str, split: str, version: str | None = None) -> None:
    """Raise :class:`InvalidInputError` unless ``tier`` is one of ``version``'s tiers and ``split`` one of its splits."""
    tiers = version_tiers(version)
    if tier not in tiers:
        raise InvalidInputError(f"tier {tier!r}; allowed: {list(tiers)}")
    splits = version_splits(version)
    if split not in splits:
        raise InvalidInputError(f"split {split!r}; allowed: {list(splits)}")


def file_tiers(tier: str) -> tuple[str, ...]:
    """The tiers whose pools share ``tier``'s pool file."""
    return TIERS if tier in TIERS else (tier,)


def load_pools(path: str | None = None, tiers: tuple[str, ...] = TIERS, version: str | None = None) -> dict[str, Any]:
    """A pool file (default: ``version``'s shipped one of ``tiers``) as read, after a check of its layout.

    Raises:
        ScenarioError: missing, unreadable or malformed file (naming what is wrong).
    """
    return _load_pools(path, tiers, live_version(version))


@lru_cache(maxsize=8)
def _load_pools(path: str | None, tiers: tuple[str, ...], version: str) -> dict[str, Any]:
    source = pool_path(tiers[0], version) if path is None else Path(path)
    try:
        data = json.loads(source.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ScenarioError(f"{source}: not a readable pool file ({type(exc).__name__}: {str(exc)[:200]}); rebuild it "
                            "with 'ffsr-gym tasks build'") from None
    try:
        for split in version_splits(version):
            for tier in tiers:
                entries = data["splits"][split]["pools"][tier]
                if not isinstance(entries, list) or not entries:
                    raise ScenarioError(f"{source}: splits.{split}.pools.{tier} must be a non-empty list")
    except (KeyError, TypeError) as exc:
        raise ScenarioError(f"{source}: missing key {exc} (expected splits.<train|test>.pools.<tier>)") from None
    return data


def task_scenario(tier: str, seed: int, benchmark: Benchmark) -> Scenario:
    """The scenario of a pool task of ``tier`` (the candidate of ``seed``, perturbed in a perturbed tier).

    Raises:
        ScenarioError: a perturbed or capture tier's seed without an admissible draw (not a pool seed).
    """
    if tier in CAPTURE_TIERS:
        task = draw_capture_task(tier, seed, benchmark)
    elif tier in TIMED_TIERS:
        task = draw_timed_task(tier, seed, benchmark)
    elif tier not in PERTURBED_TIERS:
        return draw_task(seed, benchmark)
    else:
        task = perturbed_task(tier, seed, benchmark)
    if task is None:
        raise ScenarioError(f"{tier} candidate of seed {seed}: no admissible draw (not a pool task)")
    return task


def pool(tier: str, split: str, *, path: str | None = None, version: str | None = None) -> tuple[PoolTask, ...]:
    """The tasks of ``tier``'s ``split`` pool of benchmark ``version``, in seed order.

    Raises:
        InvalidInputError: unknown tier or split.
        ScenarioError: malformed pool file, or a seed outside the split's range.
    """
    version = live_version(version)
    check_tier_split(tier, split, version)
    data = load_pools(path, file_tiers(tier), version)["splits"][split]
    tasks = tuple(_pool_task(entry, tier, split) for entry in data["pools"][tier])
    seeds = [task.seed for task in tasks]
    if len(set(seeds)) != len(seeds):
        raise ScenarioError(f"pool {tier}/{split}: seed {next(s for s in seeds if seeds.count(s) > 1)} is listed twice")
    labels, first = data.get("labels"), data.get("first_seed")
    if isinstance(labels, str) and isinstance(first, int):
        for seed in seeds:
            code = labels[seed - first] if 0 <= seed - first < len(labels) else None
            if code != LABEL_CODES[tier]:
                raise ScenarioError(f"pool {tier}/{split}: seed {seed} is labelled {code!r} in the same file, not "
                                    f"{LABEL_CODES[tier]!r} ({tier})")
    if len(tasks) != expected_count(tier, split, version):
        raise ScenarioError(f"pool {tier}/{split}: {len(tasks)} tasks; the rule asks for "
                            f"{expected_count(tier, split, version)}")
    return tasks


def _pool_task(entry: Any, tier: str, split: str) -> PoolTask:
    """One pool entry, checked: an integer seed in the split's range, a certificate that parses."""
    lo, hi = SEED_RANGES[split]
    try:
        seed = entry["seed"]
        if type(seed) is not int:
            raise TypeError(f"seed {seed!r} is not an integer")
        margins = entry.get("margins")
        task = PoolTask(seed, Certificate.from_dict(entry["certificate"]), float(entry["certificate_score"]),
                        None if margins is None else Margins.from_dict(margins))
    except (KeyError, TypeError, ValueError, InvalidInputError) as exc:
        raise ScenarioError(f"pool {tier}/{split}: malformed entry {str(entry)[:200]} ({exc})") from None
    if not lo <= task.seed < hi:
        raise ScenarioError(f"pool {tier}/{split}: seed {task.seed} outside the split's range [{lo}, {hi})")
    return task


def expected_count(tier: str, split: str, version: str | None = None) -> int:
    """How many tasks ``version``'s rule files ask for in ``tier``'s ``split`` pool."""
    version = live_version(version)
    rule = load_perturbed_rule(version) if tier in PERTURBED_TIERS else load_benchmark(version).tasks
    return rule.tasks_in(split)
