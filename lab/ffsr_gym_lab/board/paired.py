"""How finely a table ranks when entries are compared on the tasks they share: paired bootstrap groups.

Every entry of a table plays the same test tasks, and the tasks differ far more from each other than good methods
do: one task is worth 0.45 to whoever captures it, another 0.15. An entry's own CI (:mod:`ffsr_gym_lab.board.
separation`) carries that task-to-task spread, so two methods whose scores differ by the same amount on nearly
every task can still have overlapping CIs. Comparing them task by task removes it. Here each bootstrap replicate
draws the tasks once for every entry (with replacement; the test tasks are a sample of the tier's distribution)
and, for an entry with several runs (training seeds), its runs as well, each entry from a generator of its own
name, so that its draws do not depend on which other entries the table holds. The 95 % CI of the difference of
two entries' statistic (the table's: the mean or the IQM of the drawn episodes) is read off the replicates
(percentiles by the inverted CDF, as every board CI).

**Paired groups**: the entries (the uniformly random lower reference left out) in order of their statistic, cut
wherever every entry above the cut lies above every entry below it by a difference CI that excludes zero. A cut is
a claim about all those pairs at once; it holds at the 95 % level when each of them does (an intersection of
tests needs no correction). Entries on different task sets are not compared (left out, and said).

A cut is a verdict of the board, so it is published only for the versions whose cuts were measured against the
time step (:data:`MEASURED_VERSIONS`: ``experiments/paired_groups_dt.py`` replays the deterministic entries at
dt/4); on the others a cut could rest on a difference the step makes (v2's servo tier has one whose CI is
[+0.000, +0.002]).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.scoring.aggregate import BOOTSTRAP_SAMPLES, BOOTSTRAP_SEED, iqm_rows
from ffsr_gym_lab.board.separation import is_random
from ffsr_gym_lab.board.tables import safe

#: The versions whose tables get a paired-groups line (their cuts measured at dt/4).
MEASURED_VERSIONS = ("capture-v1",)
#: The statistic of each ranking metric, over the rows of (replicates x drawn episodes).
STATISTICS = {"score_mean": lambda boots: boots.mean(axis=1), "score_iqm": iqm_rows}


@dataclass(frozen=True)
class Paired:
    """A table's paired comparison.

    Attributes:
        names: the compared entries, best first by the statistic.
        groups: the paired groups, best first (lists of names).
        closest: per cut, best first: (entry above, entry below, difference CI) of the pair across it whose
            CI's lower end is smallest.
        tasks: how many tasks the entries share.
        left_out: entries not compared (their tasks differ from the others', or a run misses a task).
    """

    names: list[str]
    groups: list[list[str]]
    closest: list[tuple[str, str, list[float]]]
    tasks: int
    left_out: list[str]


def score_matrix(entry: dict[str, Any]) -> tuple[tuple[int, ...], np.ndarray] | None:
    """(task indices, scores as runs x tasks) of an entry, runs its ``train_seed`` values in order (one run for a
    deterministic method), or None if a run misses a task or plays one twice, or its rows name no pool task (an
    entry scored on seeds)."""
    rows = entry["episodes"]
    if not rows or any("task_index" not in row for row in rows):
        return None
    runs = sorted({row.get("train_seed", 0) for row in rows})
    tasks = tuple(sorted({row["task_index"] for row in rows}))
    if len(rows) != len(runs) * len(tasks):
        return None
    out = np.full((len(runs), len(tasks)), np.nan)
    run_of, task_of = {r: i for i, r in enumerate(runs)}, {t: i for i, t in enumerate(tasks)}
    for row in rows:
        out[run_of[row.get("train_seed", 0)], task_of[row["task_index"]]] = float(row["score"])
    return (tasks, out) if not np.isnan(out).any() else None


def replicates(scores: np.ndarray, task_draws: np.ndarray, name: str, statistic: str, *,
               seed: int = BOOTSTRAP_SEED) -> np.ndarray:
    """The entry's statistic in each bootstrap replicate: the replicate's tasks (``task_draws``: replicates x
    tasks, shared by every entry) and runs drawn from a generator seeded by ``seed`` and the entry's name."""
    runs = scores.shape[0]
    rng = np.random.default_rng([seed, zlib.crc32(name.encode("utf-8"))])
    run_draws = rng.integers(0, runs, (task_draws.shape[0], runs))
    drawn = scores[run_draws[:, :, None], task_draws[:, None, :]]
    return STATISTICS[statistic](drawn.reshape(task_draws.shape[0], -1))


def difference_ci(a: np.ndarray, b: np.ndarray) -> list[float]:
    """The 95 % CI of (a - b) over paired replicates."""
    d = a - b
    return [float(np.percentile(d, 2.5, method="inverted_cdf")), float(np.percentile(d, 97.5, method="inverted_cdf"))]


def paired_groups(entries: list[dict[str, Any]], statistic: str, *, samples: int = BOOTSTRAP_SAMPLES,
                  seed: int = BOOTSTRAP_SEED) -> Paired:
    """The paired groups of a table's entries (see the module docstring).

    Args:
        entries: the table's verified entries (``name``, ``episodes`` with ``task_index``, ``score`` and, for runs
            of several seeds, ``train_seed``).
        statistic: the table's ranking metric, a key of :data:`STATISTICS`.
        samples: bootstrap replicates.
        seed: the bootstrap's seed (the board's: :data:`~ffsr_gym.scoring.aggregate.BOOTSTRAP_SEED`).

    Raises:
        InvalidInputError: an unknown ``statistic``.
    """
    if statistic not in STATISTICS:
        raise InvalidInputError(f"paired statistic {statistic!r}; allowed: {sorted(STATISTICS)}")
    matrices = {e["name"]: score_matrix(e) for e in entries if not is_random(e)}
    task_sets = [m[0] for m in matrices.values() if m is not None]
    if not task_sets:
        return Paired([], [], [], 0, sorted(matrices))
    common = max(set(task_sets), key=lambda t: (task_sets.count(t), len(t)))
    kept = {n: m[1] for n, m in matrices.items() if m is not None and m[0] == common}
    draws = np.random.default_rng(seed).integers(0, len(common), (samples, len(common)))
    boots = {n: replicates(s, draws, n, statistic, seed=seed) for n, s in kept.items()}
    point = {n: float(STATISTICS[statistic](s.reshape(1, -1))[0]) for n, s in kept.items()}
    names = sorted(kept, key=lambda n: (-point[n], n))
    cis = {(a, b): difference_ci(boots[a], boots[b]) for i, a in enumerate(names) for b in names[i + 1:]}
    groups, closest, start = [], [], 0
    for cut in range(1, len(names)):
        pair = min(((a, b) for a in names[:cut] for b in names[cut:]), key=lambda p: cis[p][0])
        if cis[pair][0] > 0:
            groups.append(names[start:cut])
            closest.append((pair[0], pair[1], cis[pair]))
            start = cut
    if names:
        groups.append(names[start:])
    return Paired(names, groups, closest, len(common), sorted(set(matrices) - set(kept)))


def paired_line(entries: list[dict[str, Any]], statistic: str, label: str) -> str:
    """The table's note on its paired groups (best first), the closest pair across each cut, and what was left
    out; empty when fewer than two entries can be compared."""
    result = paired_groups(entries, statistic)
    if len(result.names) < 2:
        return ""
    cells = []
    for group in result.groups:
        names = [f"`{safe(n)}`" for n in group]
        cells.append("{" + (", ".join(names) if len(names) <= 3 else f"{names[0]} ... {names[-1]}: {len(names)}") + "}")
    cuts = "; ".join(f"`{safe(a)}` over `{safe(b)}` by [{lo:+.3f}, {hi:+.3f}]" for a, b, (lo, hi) in result.closest)
    line = (f"Paired groups (each {label} difference on the {result.tasks} shared tasks, tasks and runs resampled, "
            f"random left out): **{len(result.groups)}**, {' > '.join(cells)}")
    line += f"; closest pair across each cut: {cuts}." if cuts else "."
    if result.left_out:
        line += f" Not compared (other tasks): {', '.join(f'`{safe(n)}`' for n in result.left_out)}."
    return line
