"""The native planner step (C++, ``ffsr_gym._native.plan``) against the numba kernel's, to the bit, on the scenarios
that exercise each of its branches: ``paper`` (a still obstacle), ``free_space`` (none), drawn tasks of v2's tiers
(hard: obstacles on the path; debris: drifting obstacles; the CDF-threshold law of v0's rule), and a capture-v0
task (a tumbling target's frames and its body in the danger field), at every method, at random states and times;
and a settings object built by name refuses what it cannot hold."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_states

from ffsr_gym import _native
from ffsr_gym.kernel import physics
from ffsr_gym.kernel import planner as numba_planner
from ffsr_gym.kernel import settings as ks
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.model.spec import spec_for_version
from ffsr_gym.native.planner import planner_settings
from ffsr_gym.native.robot import native_robot
from ffsr_gym.planning.planner import METHODS
from ffsr_gym.scoring.rules import score_rule
from ffsr_gym.sim.compiled import KernelRollout, settings_vectors
from ffsr_gym.sim.setup import prepare
from ffsr_gym.sim.simulate import simulate
from ffsr_gym.tasks.splits import pool, task_scenario


def _scenario(name: str):
    if name in ("paper", "free_space"):
        return load_scenario(name)
    version, tier = name.split("/")
    benchmark = score_rule(spec_for_version(version)).benchmark
    return task_scenario(tier, pool(tier, "test", version=version)[0].seed, benchmark)


@pytest.mark.parametrize("name", ["paper", "free_space", "v2/hard", "v2/debris", "capture-v0/slow"])
def test_a_planner_step_is_the_numba_kernels_to_the_bit(name):
    scenario = _scenario(name)
    setup, rollout = prepare(scenario), KernelRollout(scenario)
    mdl, robot = rollout._mdl, native_robot(rollout._mdl)
    ws, rng = physics.workspace(len(mdl.cap_radius)), np.random.default_rng(21)
    trajectory = simulate(scenario, backend="kernel")  # states where the avoidance acts, with their times
    picks = np.linspace(0, len(trajectory.t) - 1, 12).astype(int)
    cases = [(x, float(rng.uniform(0.0, 20.0))) for x in random_states(rng, 3)]
    cases += [(np.concatenate((trajectory.q[k, :7], trajectory.q[k, mdl.q_index])), float(trajectory.t[k]))
              for k in picks]
    compared, avoiding = 0, 0
    for method in METHODS:
        for m, T_c in ((0.3, 4.0), (0.05, 1.0)):
            fp, ip = settings_vectors(setup, method=method, m=m, T_c=T_c)
            settings = planner_settings(setup, method=method, m=m, T_c=T_c)
            if setup.scenario.tumbling_target is not None and m < 0.1:  # the body's field acting on the arms
                fp[ks.F_BODY_DANGER] = settings.body_danger = 2.0
            for x, t in cases:
                out = _native.plan(robot, settings, x, t)
                numba_planner.plan(mdl, x, t, fp, ip, ws)
                for what, expected in (("dq", ws.dq), ("e1", ws.e1), ("e0", ws.e0), ("mu", ws.mu), ("cdf", ws.cdf),
                                       ("smin", ws.smin)):
                    assert np.array_equal(out[what], expected), (method, m, t, what, out[what], expected)
                compared += 1
                avoiding += bool(np.any(out["mu"] < 1.0))
    assert compared == len(METHODS) * 2 * len(cases)
    if name != "free_space":
        assert avoiding > 0  # the danger field's gradient and the blended inverse were compared too


def test_settings_refuse_what_they_cannot_hold():
    settings = _native.PlannerSettings()
    with pytest.raises(ValueError, match=r"obstacles: 9; allowed: at most 8"):
        settings.set_obstacles(np.zeros((9, 3)), np.zeros((9, 3)), np.zeros(9))
    with pytest.raises(ValueError, match=r"velocities: shape \(2, 2\); allowed: \(2, 3\)"):
        settings.set_obstacles(np.zeros((2, 3)), np.zeros((2, 2)), np.zeros(2))
    with pytest.raises(ValueError, match="estimates: allowed at least one row"):
        settings.set_estimates(np.zeros((0, 7)))
    with pytest.raises(ValueError, match="no estimates and no frames"):
        _native.plan(native_robot(KernelRollout(load_scenario("paper"))._mdl), settings, np.zeros(19), 0.0)
    with pytest.raises(ValueError, match="method 'fast'; allowed"):
        planner_settings(prepare(load_scenario("paper")), method="fast", m=0.3, T_c=4.0)
