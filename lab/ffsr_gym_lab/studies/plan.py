"""What a resumed RL study has left (``baselines/rl_study.py --plan``).

Per (algorithm, env id, tier) whose two leaderboard entries are not written yet: the training
seeds already finished and scored (their records in the study folder), the seeds left, and the
core-hours left, estimated as the seeds left times the median wall time of one finished seed of
the same algorithm and env id. The wall times come from the study folder's training records and
from the written entries (``extra.runs``); the tier's own runs are used when there are any, else
every other tier's, and the plan says which (another tier's runs underestimate a tier whose
episodes cost more, such as ``servo``, whose plant takes ten physics steps per planner step).
Nothing is trained or scored here.

The study's entries are written from its five training seeds (``STUDY_SEEDS``) or more: a run
with fewer seeds (``--seeds 0`` to train one piece) records its pieces and writes no entry, and an
entry already written from fewer seeds than asked is refused by name (``check_entry_seeds``), since
the study keeps existing entries and would otherwise publish it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from statistics import median
from typing import Any

from ffsr_gym.bench.entry import entry_name
from ffsr_gym.bench.verify import CHECKPOINTS
from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.optim.rl_study import scored_seed_files, seed_folder
from ffsr_gym.versions.registry import spec_of


@dataclass(frozen=True)
class GroupPlan:
    """One (algorithm, env id, tier) of the study that has no entries yet.

    ``hours_per_seed`` [h of one core]: the median over finished seeds of ``measured_on``
    ("this tier", "other tiers"), or None when no seed of the algorithm and env id has finished.
    """

    algo: str
    env_id: str
    tier: str
    done: tuple[int, ...]
    left: tuple[int, ...]
    hours_per_seed: float | None
    measured_on: str

    @property
    def hours_left(self) -> float | None:
        return None if self.hours_per_seed is None else self.hours_per_seed * len(self.left)


def entry_paths(root: Path, version: str, algo: str, env_id: str, tier: str) -> list[Path]:
    """The group's two entry files (last, best on validation) in the leaderboard ``root``."""
    name = entry_name(algo, spec_of(env_id), env_id, tier)
    return [root / version / tier / f"{name}{suffix}.json" for suffix in CHECKPOINTS.values()]


def entries_written(root: Path, version: str, algo: str, env_id: str, tier: str) -> bool:
    """Whether both entries (last, best on validation) of the group are in the leaderboard ``root``."""
    return all(path.is_file() for path in entry_paths(root, version, algo, env_id, tier))


STUDY_SEEDS = (0, 1, 2, 3, 4)


def writes_entries(seeds: list[int] | tuple[int, ...]) -> bool:
    """Whether a run with these training seeds may write the study's entries (it covers ``STUDY_SEEDS``)."""
    return set(STUDY_SEEDS) <= set(seeds)


def check_entry_seeds(root: Path, version: str, groups: list[tuple[str, str, str]],
                      seeds: list[int] | tuple[int, ...]) -> None:
    """Refuse, by file, an entry of ``groups`` written from fewer training seeds than ``seeds``.

    The study keeps an entry it finds; one written from a subset of the seeds asked for would be
    published in their place. The user deletes it (and its pair) to have it rewritten.
    """
    for group in groups:
        for path in entry_paths(root, version, *group):
            if not path.is_file():
                continue
            written = json.loads(path.read_text(encoding="utf-8")).get("extra", {}).get("training_seeds", [])
            if not set(seeds) <= set(written):
                raise InvalidInputError(
                    f"{path}: extra.training_seeds is {sorted(written)}, but the study asks for seeds {sorted(seeds)}; "
                    f"the study keeps an existing entry, so delete {path.name} and its pair to have them "
                    "rewritten from every seed")


def _wall_times(work: Path, root: Path, version: str, algo: str, env_id: str) -> dict[str, list[float]]:
    """Per tier, the wall times [s] of the finished seeds of ``algo`` on ``env_id`` (records, then entries)."""
    times: dict[str, dict[int, float]] = {}
    for path in sorted(work.glob(f"{algo}_{env_id}_*_seed*/train_record.json")):
        record = json.loads(path.read_text(encoding="utf-8"))
        if record.get("algo") == algo and record.get("env_id") == env_id:
            times.setdefault(record["task"], {})[record["seed"]] = record["wall_time_s"]
    for path in sorted((root / version).glob(f"*/{entry_name(algo, spec_of(env_id), env_id, '*')}.json")):
        entry: dict[str, Any] = json.loads(path.read_text(encoding="utf-8"))
        tier = entry.get("env_kwargs", {}).get("task")
        if entry.get("env_id") != env_id or entry.get("extra", {}).get("checkpoint") != "last" or tier is None:
            continue
        for run in entry["extra"].get("runs", []):
            times.setdefault(tier, {}).setdefault(run["seed"], run["wall_time_s"])
    return {tier: list(by_seed.values()) for tier, by_seed in times.items()}


def plan(groups: list[tuple[str, str, str]], seeds: list[int], work: str | Path, root: str | Path,
         version: str = "v2") -> list[GroupPlan]:
    """The plan of every (algorithm, env id, tier) of ``groups`` whose entries are not written in ``root``."""
    work, root = Path(work), Path(root)
    out, read = [], {}
    for algo, env_id, tier in groups:
        if entries_written(root, version, algo, env_id, tier):
            continue
        done = tuple(s for s in seeds if scored_seed_files(seed_folder(work, algo, env_id, tier, s)))
        if (algo, env_id) not in read:  # the records and entries are read once per algorithm and env id
            read[algo, env_id] = _wall_times(work, root, version, algo, env_id)
        times = read[algo, env_id]
        own = times.get(tier, [])
        others = [t for other, values in times.items() if other != tier for t in values]
        pick, where = (own, "this tier") if own else (others, "other tiers") if others else ([], "none")
        out.append(GroupPlan(algo, env_id, tier, done, tuple(s for s in seeds if s not in done),
                             median(pick) / 3600.0 if pick else None, where))
    return out


def render(plans: list[GroupPlan]) -> str:
    """The plan as a Markdown table, and the total core-hours left (one line when nothing is left)."""
    if not plans:
        return "nothing left: every entry pair asked for is written"
    lines = ["| algorithm | env id | tier | seeds done | seeds left | h per seed (measured on) | h left |",
             "|---|---|---|---|---|---|---|"]
    for p in plans:
        per = "unknown" if p.hours_per_seed is None else f"{p.hours_per_seed:.2f} ({p.measured_on})"
        left = "unknown" if p.hours_left is None else f"{p.hours_left:.1f}"
        lines.append(f"| {p.algo} | {p.env_id} | {p.tier} | {list(p.done)} | {list(p.left)} | {per} | {left} |")
    known = [p.hours_left for p in plans if p.hours_left is not None]
    unknown = sum(p.hours_left is None for p in plans)
    lines.append(f"\n{sum(len(p.left) for p in plans)} seeds left, about {sum(known):.1f} h of one core"
                 + (f" (and {unknown} groups with no finished seed to estimate from)" if unknown else ""))
    return "\n".join(lines)
