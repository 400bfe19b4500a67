"""The groups and levels of a table, against brute force: every subset (levels) and pairwise joins (groups)."""

import itertools

import numpy as np
import pytest

from ffsr_gym_lab.board.separation import is_random, levels_line, separated_groups, separated_levels


def _entries(bounds, random_index=None):
    out = []
    for i, (lo, hi) in enumerate(bounds):
        extra = {"policy": {"callable": "ffsr_gym.bench.policies:uniform_random_residual"}} if i == random_index else {}
        out.append({"name": f"e{i}", "metrics": {"ci": [lo, hi], "mean": (lo + hi) / 2}, "extra": extra})
    return out


def _overlap(a, b):
    return a[0] <= b[1] and b[0] <= a[1]


def _brute_levels(bounds):
    for size in range(len(bounds), 0, -1):
        for subset in itertools.combinations(bounds, size):
            if all(not _overlap(a, b) for a, b in itertools.combinations(subset, 2)):
                return size
    return 0


def _brute_groups(bounds):
    parent = list(range(len(bounds)))

    def find(i):
        while parent[i] != i:
            i = parent[i]
        return i
    for i, j in itertools.combinations(range(len(bounds)), 2):
        if _overlap(bounds[i], bounds[j]):
            parent[find(i)] = find(j)
    return len({find(i) for i in range(len(bounds))})


@pytest.mark.parametrize("seed", range(40))
def test_levels_and_groups_match_brute_force(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 9))
    lows = np.round(rng.uniform(0, 1, n), 2)  # rounded: touching intervals occur
    bounds = [(float(lo), float(lo + w)) for lo, w in zip(lows, np.round(rng.uniform(0, 0.3, n), 2))]
    entries = _entries(bounds)
    levels = separated_levels(entries, "ci")
    assert len(levels) == _brute_levels(bounds)
    assert all(not _overlap(a["metrics"]["ci"], b["metrics"]["ci"]) for a, b in itertools.combinations(levels, 2))
    groups = separated_groups(entries, "ci")
    assert len(groups) == _brute_groups(bounds)
    assert sorted(e["name"] for g in groups for e in g) == sorted(e["name"] for e in entries)
    for g, h in itertools.combinations(groups, 2):  # no entry of one group meets one of another
        assert all(not _overlap(a["metrics"]["ci"], b["metrics"]["ci"]) for a in g for b in h)
    assert len(levels) >= len(groups)


def test_random_reference_is_left_out_and_one_entry_can_join_two():
    entries = _entries([(0.0, 0.01), (0.2, 0.3), (0.5, 0.6)], random_index=0)
    assert is_random(entries[0]) and not is_random(entries[1])
    assert [[e["name"] for e in g] for g in separated_groups(entries, "ci")] == [["e1"], ["e2"]]
    bridged = entries + _entries([(0.25, 0.55)])[0:1]
    bridged[-1]["name"] = "bridge"
    assert len(separated_groups(bridged, "ci")) == 1 and len(separated_levels(bridged, "ci")) == 2
    line = levels_line(bridged, "ci", "mean", "mean")
    assert "**1**" in line and "**2**" in line and "e0" not in line
