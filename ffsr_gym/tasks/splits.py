"""Train and test pools of the v1 task tiers: the seed ranges, and the shipped pool file.

The candidate seeds of the two splits are disjoint ranges (:data:`SEED_RANGES`). Each tier's
training pool is the first ``train_tasks`` candidates of the train range that the tier rule
(:mod:`ffsr_gym.tasks.tiers`) puts in that tier, in seed order; the test pool the first
``test_tasks`` of the test range. ``ffsr-gym tasks build`` applies the rule and writes
``envs/benchmark/v1_tasks.json`` (the pools with their certificates, the label of every candidate
examined, and the counts); environments read the pools from there. The perturbed tiers
(:mod:`ffsr_gym.tasks.perturbation`) have one such file each, ``v1_<tier>_tasks.json``, over the
same seed ranges.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from ffsr_gym.exceptions import InvalidInputError, ScenarioError
from ffsr_gym.model.benchmark import Benchmark, load_benchmark
from ffsr_gym.model.resources import envs_dir
from ffsr_gym.model.scenario import Scenario
from ffsr_gym.tasks.certificate import Certificate
from ffsr_gym.tasks.generator import draw_task
from ffsr_gym.tasks.perturbation import PERTURBED_TIERS, load_perturbed_rule, perturbed_task
from ffsr_gym.tasks.tiers import ALL_TIERS, PERTURBED_REJECTIONS, REJECTIONS, TIERS

SPLITS = ("train", "test")
#: Candidate seeds of each split: [first, end).
SEED_RANGES = {"train": (0, 1_000_000), "test": (1_000_000, 2_000_000)}
#: One character per candidate label in the pool file.
LABEL_CODES = {"easy": "e", "medium": "m", "hard": "h", "nominal_final_error": "f", "balance_singularity": "b",
               "self_collision": "s", "unsolved_rate_limit": "r", "unsolved_collision": "c", "unsolved_final_error": "t",
               "debris": "D", "robust": "R", "base_rejected": "x", "draw_failed": "d"}
assert set(LABEL_CODES) == set(ALL_TIERS + REJECTIONS + PERTURBED_REJECTIONS)


@dataclass(frozen=True)
class PoolTask:
    """One task of a pool: its seed, certificate and the certificate's v1 score."""

    seed: int
    certificate: Certificate
    certificate_score: float


def pool_path(tier: str = "easy") -> Path:
    """The shipped pool file of ``tier`` (``v1_tasks.json`` for easy, medium and hard)."""
    name = "v1_tasks.json" if tier in TIERS else f"v1_{tier}_tasks.json"
    return envs_dir() / "benchmark" / name


def check_tier_split(tier: str, split: str) -> None:
    """Raise :class:`InvalidInputError` unless ``tier`` is in :data:`ALL_TIERS` and ``split`` in :data:`SPLITS`."""
    if tier not in ALL_TIERS:
        raise InvalidInputError(f"tier {tier!r}; allowed: {list(ALL_TIERS)}")
    if split not in SPLITS:
        raise InvalidInputError(f"split {split!r}; allowed: {list(SPLITS)}")


def file_tiers(tier: str) -> tuple[str, ...]:
    """The tiers whose pools share ``tier``'s pool file."""
    return TIERS if tier in TIERS else (tier,)


@lru_cache(maxsize=4)
def load_pools(path: str | None = None, tiers: tuple[str, ...] = TIERS) -> dict[str, Any]:
    """A pool file (default: the shipped one of ``tiers``) as read, after a check of its layout.

    Raises:
        ScenarioError: missing, unreadable or malformed file (naming what is wrong).
    """
    source = pool_path(tiers[0]) if path is None else Path(path)
    try:
        data = json.loads(source.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise ScenarioError(f"{source}: not a readable pool file ({type(exc).__name__}: {str(exc)[:200]}); rebuild it "
                            "with 'ffsr-gym tasks build'") from None
    try:
        for split in SPLITS:
            for tier in tiers:
                entries = data["splits"][split]["pools"][tier]
                if not isinstance(entries, list) or not entries:
                    raise ScenarioError(f"{source}: splits.{split}.pools.{tier} must be a non-empty list")
    except (KeyError, TypeError) as exc:
        raise ScenarioError(f"{source}: missing key {exc} (expected splits.<train|test>.pools.<tier>)") from None
    return data


def task_scenario(tier: str, seed: int, benchmark: Benchmark) -> Scenario:
    """The scenario of a pool task of ``tier`` (the v1 candidate of ``seed``, perturbed in a perturbed tier).

    Raises:
        ScenarioError: a perturbed tier's seed without an admissible draw (not a pool seed).
    """
    if tier not in PERTURBED_TIERS:
        return draw_task(seed, benchmark)
    task = perturbed_task(tier, seed, benchmark)
    if task is None:
        raise ScenarioError(f"{tier} candidate of seed {seed}: no admissible draw (not a pool task)")
    return task


def pool(tier: str, split: str, *, path: str | None = None) -> tuple[PoolTask, ...]:
    """The tasks of ``tier``'s ``split`` pool, in seed order.

    Raises:
        InvalidInputError: unknown tier or split.
        ScenarioError: malformed pool file, or a seed outside the split's range.
    """
    check_tier_split(tier, split)
    data = load_pools(path, file_tiers(tier))["splits"][split]
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
    if len(tasks) != expected_count(tier, split):
        raise ScenarioError(f"pool {tier}/{split}: {len(tasks)} tasks; the rule asks for {expected_count(tier, split)}")
    return tasks


def _pool_task(entry: Any, tier: str, split: str) -> PoolTask:
    """One pool entry, checked: an integer seed in the split's range, a certificate that parses."""
    lo, hi = SEED_RANGES[split]
    try:
        seed = entry["seed"]
        if type(seed) is not int:
            raise TypeError(f"seed {seed!r} is not an integer")
        task = PoolTask(seed, Certificate.from_dict(entry["certificate"]), float(entry["certificate_score"]))
    except (KeyError, TypeError, ValueError, InvalidInputError) as exc:
        raise ScenarioError(f"pool {tier}/{split}: malformed entry {str(entry)[:200]} ({exc})") from None
    if not lo <= task.seed < hi:
        raise ScenarioError(f"pool {tier}/{split}: seed {task.seed} outside the split's range [{lo}, {hi})")
    return task


def expected_count(tier: str, split: str) -> int:
    """How many tasks the rule file asks for in ``tier``'s ``split`` pool."""
    rule = load_perturbed_rule() if tier in PERTURBED_TIERS else load_benchmark("v1").tasks
    return int(rule.train_tasks if split == "train" else rule.test_tasks)
