"""How finely a table ranks: the groups no confidence interval joins, and the levels it tells apart.

A table ranks entries by their CIs (:func:`ffsr_gym_lab.board.leaderboard.ranks`). Two measures of how finely:

* **groups**: entries whose CIs overlap are joined, and so is every chain of them; the groups are what is left
  apart (the connected parts of the union of the intervals). Each entry of a group is separated from every entry
  of every other group. One entry between two others can join them.
* **levels**: the largest number of entries whose CIs are pairwise disjoint, whatever lies between them (found
  greedily: take the interval that ends lowest, drop every interval that meets it, repeat; the classical
  interval-scheduling argument shows no set is larger). Never fewer than the groups.

The uniformly random lower reference is left out of both (it stands apart from any table's bottom, which says
nothing of the methods). Intervals that touch (one's upper bound equals another's lower) are joined.
"""

from __future__ import annotations

from typing import Any

from ffsr_gym.bench.policies import BUILTIN_POLICIES
from ffsr_gym_lab.board.tables import safe


def is_random(entry: dict[str, Any]) -> bool:
    """Whether an entry is the package's uniformly random lower reference."""
    policy = entry.get("extra", {}).get("policy") or {}
    return isinstance(policy, dict) and policy.get("callable") in BUILTIN_POLICIES


def separated_levels(entries: list[dict[str, Any]], ci_key: str) -> list[dict[str, Any]]:
    """A largest list of entries (random left out) whose ``metrics[ci_key]`` intervals are pairwise disjoint,
    lowest first. Intervals that touch (one's upper bound equals another's lower) are joined."""
    candidates = sorted((e for e in entries if not is_random(e)),
                        key=lambda e: (e["metrics"][ci_key][1], e["metrics"][ci_key][0], e["name"]))
    chosen: list[dict[str, Any]] = []
    for e in candidates:
        lo = e["metrics"][ci_key][0]
        if not chosen or lo > chosen[-1]["metrics"][ci_key][1]:
            chosen.append(e)
    return chosen


def separated_groups(entries: list[dict[str, Any]], ci_key: str) -> list[list[dict[str, Any]]]:
    """The groups no CI joins (random left out), lowest first, each lowest first by its interval's start."""
    candidates = sorted((e for e in entries if not is_random(e)),
                        key=lambda e: (e["metrics"][ci_key][0], e["metrics"][ci_key][1], e["name"]))
    groups: list[list[dict[str, Any]]] = []
    reach = -float("inf")
    for e in candidates:
        lo, hi = e["metrics"][ci_key]
        if not groups or lo > reach:
            groups.append([])
        groups[-1].append(e)
        reach = max(reach, hi)
    return groups


def levels_line(entries: list[dict[str, Any]], ci_key: str, stat_key: str, label: str) -> str:
    """The table's note: its groups no CI joins, best first (each by its best and worst entry on ``stat_key``, and
    its size), and its levels."""
    groups = separated_groups(entries, ci_key)
    if not groups:
        return ""
    cells = []
    for group in reversed(groups):
        names = [f"`{safe(e['name'])}`" for e in sorted(group, key=lambda e: (-e["metrics"][stat_key], e["name"]))]
        cells.append("{" + (", ".join(names) if len(names) <= 3 else f"{names[0]} ... {names[-1]}: {len(names)}") + "}")
    return (f"Groups no CI joins ({label} CIs, random left out): **{len(groups)}**, {' > '.join(cells)}; levels "
            f"(entries with pairwise disjoint CIs): **{len(separated_levels(entries, ci_key))}**.")
