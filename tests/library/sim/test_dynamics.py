"""The native kernel's free-floating multibody dynamics against Pinocchio's ``aba`` and ``rnea``."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ffsr_gym import _native
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.sim.setup import prepare


@pytest.fixture(scope="module")
def models():
    setup = prepare(load_scenario("paper"))
    model = setup.robot.model.copy()
    model.gravity.setZero()  # in orbit; the kernel has no gravity
    return model, model.createData(), setup.assets.kernel, setup.assets.native


def _random_state(model, kernel, rng):
    q = pin.randomConfiguration(model, -3.0 * np.ones(model.nq), 3.0 * np.ones(model.nq))
    v = rng.normal(size=18)
    return q, v, q[kernel.q_index], np.concatenate((v[:6], v[kernel.v_index]))


def _kernel_order(kernel, vector):
    return np.concatenate((vector[:6], vector[kernel.v_index]))


@pytest.mark.parametrize("seed", range(5))
def test_aba_matches_pinocchio_with_armature(models, seed):
    model, data, kernel, robot = models
    rng = np.random.default_rng(seed)
    armature = rng.uniform(0.0, 0.3, 12)
    model.armature[:] = 0.0
    model.armature[kernel.v_index] = armature
    q, v, q_k, v_k = _random_state(model, kernel, rng)
    tau = rng.normal(scale=20.0, size=12)
    tau_pin = np.zeros(18)
    tau_pin[kernel.v_index] = tau
    a = _native.aba(robot, q_k, v_k, tau, armature)
    expected = _kernel_order(kernel, pin.aba(model, data, q, v, tau_pin))
    assert np.allclose(a, expected, rtol=0.0, atol=1e-9 * max(1.0, np.abs(expected).max()))


def test_aba_accelerations_give_back_the_torques_and_a_free_base(models):
    """The native accelerations, fed to Pinocchio's RNEA, give back the joint torques and a zero base wrench."""
    model, data, kernel, robot = models
    rng = np.random.default_rng(7)
    model.armature[:] = 0.0
    q, v, q_k, v_k = _random_state(model, kernel, rng)
    tau = rng.normal(scale=50.0, size=12)
    a = _native.aba(robot, q_k, v_k, tau, np.zeros(12))
    a_pin = np.zeros(18)
    a_pin[:6], a_pin[kernel.v_index] = a[:6], a[6:]
    forces = _kernel_order(kernel, pin.rnea(model, data, q, v, a_pin))
    assert np.allclose(forces[:6], 0.0, atol=1e-9)
    assert np.allclose(forces[6:], tau, rtol=0.0, atol=1e-9)
