"""The kernel's free-floating multibody dynamics against Pinocchio's ``aba``, ``rnea`` and ``crba``."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ffsr_gym.kernel import dynamics as dy
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.sim.setup import prepare


@pytest.fixture(scope="module")
def models():
    setup = prepare(load_scenario("paper"))
    model = setup.robot.model.copy()
    model.gravity.setZero()  # in orbit; the kernel has no gravity
    return model, model.createData(), setup.assets.kernel, setup.assets.kernel_arrays


def _random_state(model, kernel, rng):
    q = pin.randomConfiguration(model, -3.0 * np.ones(model.nq), 3.0 * np.ones(model.nq))
    v = rng.normal(size=18)
    return q, v, q[kernel.q_index], np.concatenate((v[:6], v[kernel.v_index]))


def _kernel_order(kernel, vector):
    return np.concatenate((vector[:6], vector[kernel.v_index]))


@pytest.mark.parametrize("seed", range(5))
def test_aba_rnea_crba_match_pinocchio(models, seed):
    model, data, kernel, mdl = models
    rng = np.random.default_rng(seed)
    armature = rng.uniform(0.0, 0.3, 12)
    model.armature[:] = 0.0
    model.armature[kernel.v_index] = armature
    q, v, q_k, v_k = _random_state(model, kernel, rng)
    dyn = dy.dynamics_workspace(mdl)
    tau = rng.normal(scale=20.0, size=12)
    tau_pin = np.zeros(18)
    tau_pin[kernel.v_index] = tau
    a = np.zeros(18)
    dy.aba_into(a, mdl, q_k, v_k, tau, armature, dyn)
    expected = _kernel_order(kernel, pin.aba(model, data, q, v, tau_pin))
    assert np.allclose(a, expected, rtol=0.0, atol=1e-9 * max(1.0, np.abs(expected).max()))

    acc = rng.normal(size=18)
    forces = np.zeros(18)
    dy.rnea_into(forces, mdl, q_k, v_k, _kernel_order(kernel, acc), armature, dyn)
    expected = _kernel_order(kernel, pin.rnea(model, data, q, v, acc))
    assert np.allclose(forces, expected, rtol=0.0, atol=1e-9 * max(1.0, np.abs(expected).max()))

    M = np.zeros((18, 18))
    dy.crba_into(M, mdl, q_k, armature, dyn)
    M_pin = pin.crba(model, data, q)
    M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
    order = np.concatenate((np.arange(6), kernel.v_index))
    assert np.allclose(M, M_pin[np.ix_(order, order)], rtol=0.0, atol=1e-9 * np.abs(M_pin).max())
    energy = 0.5 * v @ M_pin @ v
    assert dy.kinetic_energy(mdl, q_k, v_k, armature, dyn) == pytest.approx(energy, rel=1e-12)


def test_aba_inverts_rnea_with_the_base_free(models):
    """Accelerations from ABA, fed to RNEA, give back the joint torques and a zero base wrench."""
    model, data, kernel, mdl = models
    rng = np.random.default_rng(7)
    _, _, q_k, v_k = _random_state(model, kernel, rng)
    armature, tau, dyn = rng.uniform(0.0, 0.3, 12), rng.normal(scale=50.0, size=12), dy.dynamics_workspace(mdl)
    a, forces = np.zeros(18), np.zeros(18)
    dy.aba_into(a, mdl, q_k, v_k, tau, armature, dyn)
    dy.rnea_into(forces, mdl, q_k, v_k, a, armature, dyn)
    assert np.allclose(forces[:6], 0.0, atol=1e-9)
    assert np.allclose(forces[6:], tau, rtol=0.0, atol=1e-9)
