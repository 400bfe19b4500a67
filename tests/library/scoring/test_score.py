"""The bounded episode score (v2, as v1): closed forms for the smoothness terms, boundedness, ranking, and the
retired v1's documented table on `paper` (kept regenerable: under v2's blend law no setting reaches the target there)."""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
from conftest import retired_v1_rules

import ffsr_gym
from ffsr_gym.scoring.score import bounded_score, score_episode, smoothness_cost, smoothness_terms

#: The score's numbers are v2's; the runs on `paper` are v1's (its blend law and contact test).
BENCH = retired_v1_rules()


@pytest.fixture(scope="module")
def task():
    return BENCH.task(ffsr_gym.load_scenario("paper"))


def test_constant_rate_closed_form():
    dt, n, omega = 0.01, 300, 0.7
    dq = np.zeros((n, 12))
    dq[:, 2] = omega          # mission joint 3
    dq[:, 6:8] = omega / 2    # balance joints 1, 2
    energy, variation = smoothness_terms(dq, dt)
    assert energy == pytest.approx([omega**2 * n * dt, 2 * (omega / 2) ** 2 * n * dt], rel=1e-12)
    assert variation == pytest.approx([omega, math.sqrt(2) * omega / 2], rel=1e-12)  # one jump from rest


def test_sine_rate_converges_to_integrals():
    """E → A²T/2 and V → 4A per period for a sampled sine, as dt → 0."""
    A, T, period = 0.5, 4.0, 1.0
    for dt in (1e-3, 1e-4):
        t = np.arange(0.0, T, dt)
        dq = np.zeros((len(t), 12))
        dq[:, 0] = A * np.sin(2 * np.pi * t / period)
        energy, variation = smoothness_terms(dq, dt)
        assert energy[0] == pytest.approx(A**2 * T / 2, rel=10 * dt)
        assert variation[0] == pytest.approx(4 * A * T / period, rel=10 * dt)
        assert energy[1] == variation[1] == 0.0


def test_chatter_costs_twice_its_amplitude_per_flip():
    n, a = 101, 0.3
    dq = np.zeros((n, 12))
    dq[:, 9] = a * (-1.0) ** np.arange(n)
    energy, variation = smoothness_terms(dq, 0.01)
    assert variation[1] == pytest.approx(a + 2 * a * (n - 1), rel=1e-12)
    assert energy[1] == pytest.approx(a**2 * n * 0.01, rel=1e-12)


def test_chunks_sum_to_the_whole_episode():
    rng = np.random.default_rng(3)
    dq = rng.normal(size=(200, 12))
    whole = np.concatenate(smoothness_terms(dq, 0.01))
    parts, previous = np.zeros(4), None
    for chunk in np.split(dq, 20):
        parts += np.concatenate(smoothness_terms(chunk, 0.01, previous))
        previous = chunk[-1]
    assert parts == pytest.approx(whole, rel=1e-12)


def test_cost_weights_and_references():
    s = BENCH.score
    cost = smoothness_cost(np.array([2.0, 3.0]), np.array([5.0, 7.0]), s)
    expected = s.alpha * (2 / s.rate_energy_ref_rad2_s + 5 / s.rate_variation_ref_rad_s) + \
        s.beta * (3 / s.rate_energy_ref_rad2_s + 7 / s.rate_variation_ref_rad_s)
    assert cost == pytest.approx(expected, rel=1e-14)


def test_score_is_bounded_and_strictly_decreasing_in_cost():
    costs = np.concatenate(([0.0], np.logspace(-6, 6, 50)))
    scores = [bounded_score(True, c) for c in costs]
    assert scores[0] == 1.0 and all(0.0 < s <= 1.0 for s in scores)
    assert all(a > b for a, b in itertools.pairwise(scores))
    assert bounded_score(False, 0.0) == 0.0 and bounded_score(True, math.inf) == 0.0


def test_score_separates_settings_that_b_ties(task):
    """The v0 GA optimum and the CMA-ES optimum both have B = 0; their v1 scores differ."""
    ga = score_episode(ffsr_gym.simulate(task, m=0.2900, T_c=4.187), task, BENCH)
    cmaes = score_episode(ffsr_gym.simulate(task, m=0.2094949105274626, T_c=3.3460938992441087), task, BENCH)
    assert ga.paper_B == cmaes.paper_B == 0.0
    assert ga.success and cmaes.success
    assert ga.score - cmaes.score > 0.05  # 0.538 vs 0.462


def test_failures_are_named_and_score_zero(task):
    default = score_episode(ffsr_gym.simulate(task, m=0.1, T_c=3.0), task, BENCH)
    assert default.failure == "rate_limit" and default.score == 0.0 and default.paper_B == math.inf
    assert default.peak_rate_deg_s[1] == pytest.approx(222.6, abs=0.1)
    no_avoid = score_episode(ffsr_gym.simulate(task, method="no_avoidance", m=0.3, T_c=4.0), task, BENCH)
    assert no_avoid.failure == "collision" and no_avoid.min_clearance_m < 0
    weak = task.replace(planner=dataclasses.replace(task.planner, proportional_gain_per_s=0.5))
    prop = score_episode(ffsr_gym.simulate(weak, method="proportional"), weak, BENCH)
    assert prop.failure == "final_error" and prop.final_ee_position_error_m > BENCH.score.ee_position_tolerance_m


def test_score_is_continuous_over_feasible_settings(task):
    """Neighbouring settings (Δm = 0.005) in the smooth feasible region score within 0.01 of each other."""
    scores = [score_episode(ffsr_gym.simulate(task, m=m, T_c=5.0), task, BENCH) for m in np.arange(0.20, 0.3001, 0.005)]
    assert all(s.success for s in scores)
    steps = np.abs(np.diff([s.score for s in scores]))
    assert steps.max() < 0.01


@pytest.mark.parametrize("m, T_c", [(0.05, 1.0), (0.05, 10.0), (0.35, 2.5), (0.6, 1.0), (0.6, 7.0), (0.6, 10.0)])
def test_success_does_not_depend_on_dt(task, m, T_c):
    """Success at dt = 0.01 s equals success at dt = 0.005 s (corners and chatter of the action box)."""
    runs = [score_episode(ffsr_gym.simulate(task, m=m, T_c=T_c, dt=dt), task, BENCH) for dt in (0.01, 0.005)]
    assert runs[0].failure == runs[1].failure


def test_chattering_radius_is_below_the_tolerance_over_the_action_box():
    """(dt / (2 m T_c))^(1/m) at dt = 0.01 s stays 3x below the 1 mm tolerance on the whole v1 box."""
    (m_lo, m_hi), (t_lo, t_hi) = BENCH.action.m_bounds, BENCH.action.T_c_bounds_s
    worst = max((0.01 / (2 * m * t)) ** (1 / m) for m in np.linspace(m_lo, m_hi, 56) for t in np.linspace(t_lo, t_hi, 19))
    assert worst <= BENCH.score.ee_position_tolerance_m / 2.9


DOC_ROWS = {  # docs/envs.md "Version history" table of v1: row label -> how it was run
    "proportional K = 1/s": ("proportional", 1.0, None, None),
    "proportional K = 2/s": ("proportional", 2.0, None, None),
    "v0 GA optimum (0.29, 4.187 s)": ("predefined_time", None, 0.29, 4.187),
    "v1 default (0.3, 4 s)": ("predefined_time", None, 0.3, 4.0),
    "v0 CMA-ES optimum (0.209, 3.346 s)": ("predefined_time", None, 0.2094949105274626, 3.3460938992441087),
    "paper's optimum (0.2167, 2.19 s)": ("predefined_time", None, 0.2167, 2.19),
    "(0.5, 3 s): chatters after convergence": ("predefined_time", None, 0.5, 3.0),
    "paper's default (0.1, 3 s)": ("predefined_time", None, 0.1, 3.0),
    "proportional K = 0.5/s": ("proportional", 0.5, None, None),
}


def test_docs_table_matches_the_runs(task):
    """v1's table in docs/envs.md is what these runs give (C to 2 decimals or 3 digits, score to 3 decimals)."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[3] / "docs" / "envs.md").read_text(encoding="utf-8")
    rows = {cells[0]: cells for cells in
            ([c.strip() for c in line.strip("|").split("|")] for line in text.splitlines() if line.startswith("| "))}
    for label, (method, gain, m, T_c) in DOC_ROWS.items():
        run_task = task if gain is None else task.replace(planner=dataclasses.replace(task.planner, proportional_gain_per_s=gain))
        result = score_episode(ffsr_gym.simulate(run_task, method=method, m=m, T_c=T_c), run_task, BENCH)
        _, _, success, cost, score = rows[label]
        assert success.startswith("yes") == result.success, label
        assert float(cost) == pytest.approx(result.smoothness_cost, abs=0.0051, rel=0.005), label
        assert float(score) == pytest.approx(result.score, abs=0.00051), label
