"""The GA: resuming after an interruption gives exactly the uninterrupted result, on any executor."""

from __future__ import annotations

import dataclasses
import math
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from ffsr_gym.bench.evaluation import objective_for_params
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.optim import ga


@pytest.fixture(scope="module")
def short_paper(tmp_path_factory):
    """The paper scenario cut to 12 s (avoidance and convergence included) as a TOML file."""
    path = tmp_path_factory.mktemp("scenario") / "paper_12s.toml"
    text = load_scenario("paper").source
    path.write_text(open(text).read().replace("duration_s = 20.0", "duration_s = 12.0"))
    return str(path)


def _config(scenario: str) -> ga.GAConfig:
    return ga.GAConfig(population=6, generations=4, T_c_fixed=None, seed=3, scenario=scenario)


def _same(a: ga.GAState, b: ga.GAState) -> None:
    assert a.history == b.history
    assert np.array_equal(a.population, b.population)
    assert a.cache == b.cache
    assert a.rng_state == b.rng_state


@pytest.fixture(scope="module")
def uninterrupted(short_paper, tmp_path_factory):
    return ga.run(_config(short_paper), checkpoint=tmp_path_factory.mktemp("a") / "ck.json", progress=False)


def test_resume_after_two_generations_equals_uninterrupted(short_paper, uninterrupted, tmp_path):
    checkpoint = tmp_path / "ck.json"
    partial = ga.run(_config(short_paper), checkpoint=checkpoint, stop_after=2, progress=False)
    assert partial.generation == 2
    with ProcessPoolExecutor(2) as pool:
        resumed = ga.run(None, checkpoint=checkpoint, executor=pool, progress=False)
    _same(resumed, uninterrupted)


def test_resume_with_dask_equals_uninterrupted(short_paper, uninterrupted, tmp_path):
    distributed = pytest.importorskip("distributed")
    checkpoint = tmp_path / "ck.json"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        ga.run(_config(short_paper), checkpoint=checkpoint, executor=client.get_executor(), stop_after=2, progress=False)
        resumed = ga.run(None, checkpoint=checkpoint, executor=client.get_executor(), progress=False)
    _same(resumed, uninterrupted)


def test_ga_optimum_is_feasible_and_beats_the_non_optimised_setting(short_paper, uninterrupted):
    m, T_c, score = ga.best(uninterrupted)
    assert math.isfinite(score)
    assert score == objective_for_params(m, T_c, scenario=short_paper)
    assert score <= objective_for_params(0.1, 2.19, scenario=short_paper)


def test_selection_prefers_lower_B_and_survives_infinity():
    scores = np.array([0.0, 1e-4, 2e-4, math.inf])
    p = ga.selection_probabilities(scores, "inverse")
    assert p[0] > p[1] > p[2] > p[3] == 0.0 and p.sum() == pytest.approx(1.0)
    literal = ga.selection_probabilities(scores, "literal")
    assert literal[2] > literal[1] > literal[0] == 0.0  # eq. (23) as printed favours the worst
    assert np.allclose(ga.selection_probabilities(np.full(4, math.inf), "inverse"), 0.25)


def test_decode_spans_the_bounds():
    config = ga.GAConfig()
    assert ga.decode(np.zeros(32, dtype=np.int8), config) == (0.05, 1.0)
    m, T_c = ga.decode(np.ones(32, dtype=np.int8), config)
    assert m == pytest.approx(0.95) and T_c == pytest.approx(5.0)
    fixed = dataclasses.replace(config, T_c_fixed=2.19)
    assert ga.decode(np.ones(16, dtype=np.int8), fixed)[1] == 2.19
