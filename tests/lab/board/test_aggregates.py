"""Normalised scores and the rliable aggregates: checked against closed forms on hand-made entries."""

from __future__ import annotations

import numpy as np
import pytest

from ffsr_gym.scoring.aggregate import iqm
from ffsr_gym.versions.registry import spec_for_version
from ffsr_gym_lab.board import normalise

rliable = pytest.importorskip("rliable")
from rliable import metrics

from ffsr_gym_lab.board import aggregates

SPEC = spec_for_version("v2")


def test_the_leaderboard_iqm_is_rliables_trimmed_mean():
    rng = np.random.default_rng(3)
    for n in range(1, 41):
        values = rng.uniform(0, 1, n)
        assert iqm(values) == pytest.approx(metrics.aggregate_iqm(values.reshape(1, -1)), rel=1e-12, abs=0), n


def test_the_vectorised_probability_of_improvement_is_rliables():
    rng = np.random.default_rng(1)
    for runs_x, runs_y in ((1, 1), (5, 1), (3, 4)):
        x = rng.integers(0, 4, (runs_x, 30)) / 4.0  # coarse values: many ties
        y = rng.integers(0, 4, (runs_y, 30)) / 4.0
        assert aggregates.improvement(x, y) == pytest.approx(metrics.probability_of_improvement(x, y), abs=1e-12)
    same = rng.uniform(0, 1, (2, 30))
    assert aggregates.improvement(same, same) == metrics.probability_of_improvement(same, same) == 0.5


def _entry(name, tier, scores, seeds=None):
    """A minimal pool entry: rows of (train seed, task index, score)."""
    seeds = seeds or [None]
    rows = []
    for k, seed in enumerate(seeds):
        for i, s in enumerate(scores[k]):
            row = {"seed": i, "task_index": i, "score": float(s)}
            if seed is not None:
                row["train_seed"] = seed
            rows.append(row)
    return {"name": f"{name}_{tier}", "episodes": rows, "extra": {"evaluation_pool": f"{tier}/test"}}


@pytest.fixture
def reference_two(monkeypatch):
    """Every task's reference score is 2 (so a normalised score is half the score); 400 bootstrap resamples instead
    of the published 2,000 (the checks are closed forms, and a CI's width within a factor of 3)."""
    monkeypatch.setattr(normalise.reference, "reference_scores", lambda tier, split, version=None: np.full(100, 2.0))
    monkeypatch.setattr(aggregates, "REPS", 400)


def test_normalised_scores_divide_by_each_tasks_reference_score(reference_two, monkeypatch):
    entry = _entry("x", "easy", [np.linspace(0, 1, 100)])
    assert np.allclose(normalise.normalised_scores(entry, "v2"), np.linspace(0, 1, 100) / 2)
    assert normalise.normalised_mean(entry, "v2") == pytest.approx(0.25)
    monkeypatch.setattr(normalise.reference, "reference_scores", lambda *a, **k: None)  # a pool the reference does not cover: no column
    assert normalise.normalised_mean(entry, "v2") is None
    assert normalise.normalised_mean({"episodes": [], "extra": {"evaluation_pool": "planet/test"}}, "v2") is None


def test_aggregates_match_closed_forms(reference_two):
    """Point estimates against closed forms; CIs by rliable's bootstrap over tasks and runs."""
    rng = np.random.default_rng(0)
    reference = {t: rng.uniform(0, 1, 100) for t in ("easy", "hard")}
    better = {t: np.where(np.arange(100) < 70, reference[t] + 0.1, reference[t]) for t in reference}  # 70 wins, 30 ties
    rl = {t: rng.uniform(0, 1, (5, 100)) for t in reference}
    entries = {t: [_entry("reference_v2_default", t, [reference[t]]), _entry("better", t, [better[t]]),
                   _entry("ppo", t, rl[t], seeds=[0, 1, 2, 3, 4])] for t in reference}
    data = aggregates.compute(entries, SPEC)
    assert data["tiers"] == ["easy", "hard"]
    b, p = data["methods"]["better"], data["methods"]["ppo"]
    assert (b["runs"], b["tasks"], p["runs"], p["tasks"]) == (1, 200, 5, 200)
    # deterministic against deterministic: P = share of tasks won + half the ties
    assert b["probability_of_improvement"] == pytest.approx((140 + 0.5 * 60) / 200, abs=1e-12)
    # tasks are resampled too: the CI of a share of 200 task outcomes, about ±2 standard errors of a proportion
    lo, hi = b["probability_of_improvement_ci95"]
    se = np.sqrt(0.85 * 0.15 / 200)  # the wins (70 %) and half the ties (15 %) as one proportion, roughly
    assert lo < b["probability_of_improvement"] < hi and 2 * se < hi - lo < 6 * se
    # five runs against one: per task, the share of runs above the reference's score (no ties in continuous draws)
    ref_all = np.concatenate([reference["easy"], reference["hard"]]) / 2
    rl_all = np.concatenate([rl["easy"], rl["hard"]], axis=1) / 2
    assert p["probability_of_improvement"] == pytest.approx(np.mean((rl_all > ref_all).mean(axis=0)), abs=1e-12)
    assert p["iqm"] == pytest.approx(iqm(rl_all.ravel()), rel=1e-12)
    assert p["iqm_ci95"][0] < p["iqm"] < p["iqm_ci95"][1]
    taus = np.array(data["taus"])
    assert np.allclose(p["profile"], [(rl_all > t).mean() for t in taus])
    again = aggregates.compute(entries, SPEC)  # seeded: the same numbers every time
    assert {k: v for k, v in again.items() if k != "provenance"} == {k: v for k, v in data.items() if k != "provenance"}


def test_tiers_without_reference_scores_are_left_out(monkeypatch):
    monkeypatch.setattr(normalise.reference, "reference_scores",
                        lambda tier, split, version=None: np.ones(100) if tier == "easy" else None)
    entries = {t: [_entry("reference_v2_default", t, [np.ones(10)]), _entry("b", t, [np.zeros(10)])]
               for t in ("easy", "hard")}
    assert aggregates.compute(entries, SPEC)["tiers"] == ["easy"]


def test_a_methods_numbers_depend_on_its_own_scores_only(reference_two):
    """Seeded per method: the same method's CIs with and without another method on the board, and a stored method
    whose inputs are unchanged is kept as stored (a new entry costs its own bootstraps), a changed one recomputed."""
    rng = np.random.default_rng(5)
    reference = rng.uniform(0, 1, 100)
    mine = [rng.uniform(0, 1, 100)]
    alone = {"easy": [_entry("reference_v2_default", "easy", [reference]), _entry("mine", "easy", mine)]}
    crowded = {"easy": alone["easy"] + [_entry("other", "easy", [rng.uniform(0, 1, 100)])]}
    first, second = aggregates.compute(alone, SPEC), aggregates.compute(crowded, SPEC)
    assert first["methods"]["mine"] == second["methods"]["mine"]
    assert first["methods"]["reference_v2_default"] == second["methods"]["reference_v2_default"]
    marked = {m: v | {"iqm": -1.0} for m, v in second["methods"].items()}  # what a kept method would show
    changed = {"easy": [crowded["easy"][0], crowded["easy"][1], _entry("other", "easy", [rng.uniform(0, 1, 100)])]}
    third = aggregates.compute(changed, SPEC, marked)
    assert third["methods"]["mine"]["iqm"] == -1.0 and third["methods"]["reference_v2_default"]["iqm"] == -1.0
    other = np.array([row["score"] for row in changed["easy"][2]["episodes"]]) / 2  # recomputed, from its new scores
    assert third["methods"]["other"]["iqm"] == pytest.approx(iqm(other), rel=1e-12)
