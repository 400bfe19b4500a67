"""Paired groups against closed forms: a constant shift, the normal approximation, runs resampled, and a cut that
needs every pair across it."""

import zlib

import numpy as np
import pytest

from ffsr_gym.exceptions import InvalidInputError
from ffsr_gym.scoring.aggregate import bootstrap_ci, iqm
from ffsr_gym_lab.board.paired import difference_ci, paired_groups, paired_line, replicates, score_matrix

RANDOM = {"policy": {"callable": "ffsr_gym.bench.policies:uniform_random_residual"}}


def _entry(name, runs, extra=None, tasks=None):
    """An entry whose run r scores ``runs[r][i]`` on task i (or on ``tasks[i]``)."""
    runs = np.atleast_2d(np.asarray(runs, dtype=float))
    tasks = range(runs.shape[1]) if tasks is None else tasks
    rows = [{"task_index": int(t), "score": float(s), "train_seed": r}
            for r, run in enumerate(runs) for t, s in zip(tasks, run)]
    return {"name": name, "episodes": rows, "extra": extra or {}}


def _spread(n=100, seed=0):
    return np.random.default_rng(seed).uniform(0.0, 0.45, n)  # tasks worth 0 to 0.45, as capture tasks are


def test_a_constant_shift_is_separated_though_the_entries_own_cis_overlap():
    base = _spread()
    a, b = _entry("a", base + 0.01), _entry("b", base)
    result = paired_groups([a, b], "score_mean")
    assert result.groups == [["a"], ["b"]]
    assert result.closest[0][:2] == ("a", "b")
    assert result.closest[0][2] == pytest.approx([0.01, 0.01], abs=1e-12)  # every replicate differs by 0.01
    ci_a, ci_b = bootstrap_ci(base + 0.01, np.mean), bootstrap_ci(base, np.mean)
    assert ci_a[0] < ci_b[1]  # the board's own CIs overlap


def test_equal_entries_are_one_group():
    base = _spread()
    result = paired_groups([_entry("a", base), _entry("b", base.copy())], "score_mean")
    assert result.groups == [["a", "b"]] and result.closest == []


def test_the_difference_ci_has_the_normal_approximation_width():
    n, sigma = 400, 0.05
    base = _spread(n)
    d = np.random.default_rng(1).normal(0.02, sigma, n)
    result = paired_groups([_entry("a", base + d), _entry("b", base)], "score_mean", samples=20000)
    lo, hi = result.closest[0][2]
    half = 1.96 * d.std(ddof=1) / np.sqrt(n)
    assert (lo + hi) / 2 == pytest.approx(d.mean(), abs=0.1 * half)
    assert (hi - lo) / 2 == pytest.approx(half, rel=0.1)


def test_runs_are_resampled():
    """Two runs, one 0.2 above the planner on every task, one 0.1 below: a replicate that draws the bad run twice
    (a quarter of them) is 0.1 below, so the entry is not separated from the planner, though its pooled mean is
    above it on every task."""
    base = _spread()
    trained, planner = _entry("trained", [base + 0.2, base - 0.1]), _entry("planner", base)
    result = paired_groups([trained, planner], "score_mean")
    assert result.groups == [["trained", "planner"]]
    draws = np.random.default_rng(0).integers(0, 100, (2000, 100))
    a = replicates(score_matrix(trained)[1], draws, "trained", "score_mean")
    b = replicates(score_matrix(planner)[1], draws, "planner", "score_mean")
    assert np.unique(np.round(a - b, 12)).tolist() == [-0.1, 0.05, 0.2]
    assert difference_ci(a, b) == pytest.approx([-0.1, 0.2])
    assert np.mean(np.isclose(a - b, -0.1)) == pytest.approx(0.25, abs=0.03)


def test_a_cut_needs_every_pair_across_it():
    """a = b + 0.1 exactly; c lies between them with a noise of its own, apart from neither: no cut holds, although
    a is apart from b."""
    base = _spread(60)
    noise = np.random.default_rng(2).normal(0.0, 0.3, 60)
    a, b, c = _entry("a", base + 0.1), _entry("b", base), _entry("c", base + 0.05 + noise - noise.mean())
    result = paired_groups([a, b, c], "score_mean")
    assert result.names == ["a", "c", "b"]
    assert result.groups == [["a", "c", "b"]]
    assert paired_groups([a, b], "score_mean").groups == [["a"], ["b"]]


def test_an_entrys_draws_do_not_depend_on_the_others():
    base = _spread()
    a, b = _entry("a", [base + 0.03, base + 0.01]), _entry("b", base + np.random.default_rng(3).normal(0, 0.02, 100))
    alone = paired_groups([a, b], "score_mean")
    more = paired_groups([_entry("z", base - 0.3), b, a], "score_mean")
    assert more.groups[:-1] == alone.groups and more.closest[0] == alone.closest[0]


def test_the_iqm_statistic_is_the_iqm_of_the_drawn_episodes():
    runs = np.random.default_rng(4).uniform(0, 1, (3, 40))
    draws = np.random.default_rng(5).integers(0, 40, (7, 40))
    got = replicates(runs, draws, "x", "score_iqm", seed=9)
    run_draws = np.random.default_rng([9, zlib.crc32(b"x")]).integers(0, 3, (7, 3))
    want = [iqm(runs[run_draws[k]][:, draws[k]].ravel()) for k in range(7)]
    assert got == pytest.approx(want, abs=1e-12)


def test_random_and_other_tasks_are_left_out():
    base = _spread()
    entries = [_entry("a", base + 0.1), _entry("b", base), _entry("rnd", base - 0.2, extra=RANDOM),
               _entry("elsewhere", base[:50], tasks=range(100, 150)),
               {"name": "gap", "episodes": _entry("gap", base)["episodes"][:-1], "extra": {}}]
    result = paired_groups(entries, "score_mean")
    assert result.names == ["a", "b"] and result.left_out == ["elsewhere", "gap"]
    line = paired_line(entries, "score_mean", "mean")
    assert "**2**" in line and "`a` over `b` by [+0.100, +0.100]" in line and "`elsewhere`, `gap`" in line
    assert "rnd" not in line
    assert paired_line(entries[:1], "score_mean", "mean") == ""


def test_an_unknown_statistic_is_refused_by_name():
    with pytest.raises(InvalidInputError, match="score_median.*allowed.*score_iqm"):
        paired_groups([_entry("a", _spread())], "score_median")


def test_an_entry_scored_on_seeds_is_not_compared():
    seeded = {"name": "v0", "extra": {}, "episodes": [{"seed": s, "score": 0.1} for s in range(3)]}
    assert score_matrix(seeded) is None
    result = paired_groups([seeded, _entry("a", _spread())], "score_mean")
    assert result.names == ["a"] and result.left_out == ["v0"]
