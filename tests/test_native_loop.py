"""The native closed loop on the kinematic plant (C++, ``ffsr_gym._native.run``) against the numba kernel's
``loop.run``: whole 20 s episodes, every logged array to the bit and the same status, on the paper scenario, drifting
debris, a robust task (noisy target estimates, a plant whose inertias differ from the planner's model) and a
capture task; a residual that breaks the rate limit ends both at the same step; bad arguments are named."""

from __future__ import annotations

import numpy as np
import pytest
from test_native_planner import _scenario

from ffsr_gym import _native
from ffsr_gym.kernel import loop
from ffsr_gym.native.planner import planner_settings
from ffsr_gym.native.robot import native_plant, native_robot
from ffsr_gym.sim.compiled import LOG_FIELDS, KernelRollout, settings_vectors
from ffsr_gym.sim.setup import prepare

NAMES = {"x": "out_x", "v": "out_v", "dq": "out_dq", "err": "out_err", "clear": "out_clear", "self": "out_self",
         "mu": "out_mu", "cdf": "out_cdf", "smin": "out_smin", "tau": "out_tau"}


def _both(name: str, residual: np.ndarray, k0: int = 0, m: float = 0.3, T_c: float = 4.0):
    scenario = _scenario(name)
    setup, rollout = prepare(scenario), KernelRollout(scenario)
    mdl = rollout._mdl
    fp, ip = settings_vectors(setup, method="predefined_time", m=m, T_c=T_c)
    n = scenario.n_steps
    logs = {key: np.zeros((n - k0, *shape)) for key, shape in LOG_FIELDS.items()}
    x_numba, rows_numba, status_numba = loop.run(mdl, rollout.plant, rollout.x.copy(), k0, n, n, fp, ip, residual,
                                                 True, False, *(logs[key] for key in LOG_FIELDS))
    robot = native_robot(mdl)
    mass, lever, inertia, drive = rollout.plant
    plant = None
    if scenario.physics_substeps > 0 or not (np.array_equal(mass, mdl.mass) and np.array_equal(lever, mdl.lever)
                                             and np.array_equal(inertia, mdl.inertia)):
        plant = native_plant(mdl, rollout.plant)
    settings = planner_settings(setup, method="predefined_time", m=m, T_c=T_c)
    x_native, rows, status, native_logs = _native.run(robot, settings, rollout.x.copy(), k0, n, n, residual,
                                                       plant=plant)
    return (x_numba, rows_numba, status_numba, logs), (x_native, rows, status, native_logs), plant


@pytest.mark.parametrize("name", ["paper", "v2/debris", "v2/robust", "v2/servo", "capture-v0/fast"])
def test_a_whole_episode_is_the_numba_kernels_to_the_bit(name):
    (x_n, rows_n, status_n, logs_n), (x, rows, status, logs), plant = _both(name, np.zeros(12))
    assert (rows, status) == (rows_n, status_n) and rows > 100
    assert np.array_equal(x[:len(x_n)], x_n)
    for key in LOG_FIELDS:
        assert np.array_equal(logs[key][:rows], logs_n[key][:rows]), key
    if name in ("v2/robust", "v2/servo"):
        assert plant is not None  # the plant's inertias differ from the planner's model, or it has drives
    if name == "v2/servo":
        assert np.any(logs["tau"][:rows] != 0.0)  # the drives' torques were logged


def test_a_residual_that_breaks_the_rate_limit_ends_both_at_the_same_step():
    residual = np.full(12, np.radians(150.0))
    (x_n, rows_n, status_n, _), (x, rows, status, _), _ = _both("paper", residual)
    assert status == status_n == 1 and rows == rows_n < 2000 and np.array_equal(x[:len(x_n)], x_n)


def test_bad_arguments_are_named():
    scenario = _scenario("paper")
    setup, rollout = prepare(scenario), KernelRollout(scenario)
    robot, settings = native_robot(rollout._mdl), planner_settings(prepare(scenario), method="no_avoidance", m=0.3,
                                                                     T_c=4.0)
    with pytest.raises(ValueError, match=r"residual: shape \(6,\); allowed: \(12,\)"):
        _native.run(robot, settings, rollout.x.copy(), 0, 10, 10, np.zeros(6))
    with pytest.raises(ValueError, match="allowed 0 <= k0 <= n_total"):
        _native.run(robot, settings, rollout.x.copy(), 11, 10, 10, np.zeros(12))
    with pytest.raises(ValueError, match=r"x: shape \(7,\); allowed: \(19,\) or \(40,\)"):
        _native.run(robot, settings, np.zeros(7), 0, 10, 10, np.zeros(12))
    assert setup.scenario is scenario
