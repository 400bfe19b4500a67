"""The native articulated-body algorithm (C++) against Pinocchio's ``aba`` (armature included, no gravity) and the
numba kernel's bits. The servo plant that drives it is checked as a whole in test_native_loop (the servo tier)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from test_dynamics import _kernel_order, _random_state, models  # noqa: F401 - the fixture

from ffsr_gym import _native
from ffsr_gym.kernel import dynamics as dy
from ffsr_gym.native.robot import native_robot


@pytest.mark.parametrize("seed", range(5))
def test_aba_is_pinocchios_and_the_numba_kernels_bits(models, seed):  # noqa: F811 - the fixture
    model, data, kernel, mdl = models
    rng = np.random.default_rng(100 + seed)
    armature = rng.uniform(0.0, 0.3, 12)
    model.armature[:] = 0.0
    model.armature[kernel.v_index] = armature
    q, v, q_k, v_k = _random_state(model, kernel, rng)
    tau = rng.normal(scale=20.0, size=12)
    tau_pin = np.zeros(18)
    tau_pin[kernel.v_index] = tau
    a = _native.aba(native_robot(mdl), q_k, v_k, tau, armature)
    expected = _kernel_order(kernel, pin.aba(model, data, q, v, tau_pin))
    assert np.allclose(a, expected, rtol=0.0, atol=1e-9 * max(1.0, np.abs(expected).max()))
    numba = np.zeros(18)
    dy.aba_into(numba, mdl, q_k, v_k, tau, armature, dy.dynamics_workspace(mdl))
    assert np.array_equal(a, numba)
