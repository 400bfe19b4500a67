"""The native kernel's physics (C++, ``ffsr_gym._native``) against Pinocchio (momentum, centre of mass), numpy
(a dense solve, LAPACK's SVD) and the numba kernel it replaces (the same bits: both keep one operation order and
neither contracts to fused multiply-adds)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_states

from ffsr_gym import _native
from ffsr_gym.kernel import physics
from ffsr_gym.kernel.linalg import smallest_singular_value, smallest_singular_values, svd_into
from ffsr_gym.model.robot import load_robot
from ffsr_gym.model.scenario import load_scenario
from ffsr_gym.native.robot import native_robot, robot_arrays
from ffsr_gym.sim.compiled import KernelRollout


@pytest.fixture(scope="module")
def models():
    rollout = KernelRollout(load_scenario("paper"))
    return rollout, rollout._mdl, native_robot(rollout._mdl)


def _pinocchio_q(rollout, x):
    q = np.empty(19)
    q[:7], q[rollout.model.q_index] = x[:7], x[7:]
    return q


def test_kinematics_and_momentum_are_pinocchios_and_the_numba_kernels_bits(models):
    rollout, mdl, robot = models
    reference, ws = load_robot(), physics.workspace(len(mdl.cap_radius))
    for x in random_states(np.random.default_rng(11), 20):
        frames, momentum = _native.kinematics(robot, x), _native.momentum(robot, x)
        physics.kinematics_into(mdl, x, ws)
        physics.momentum_into(mdl, x, ws)
        for name in ("Rj", "pj", "R_b", "Re", "pe", "z"):
            assert np.array_equal(frames[name], getattr(ws, name)), name
        for name in ("H_b", "H_bm", "rg"):
            assert np.array_equal(momentum[name], getattr(ws, name)), name
        q = _pinocchio_q(rollout, x)
        ref = reference.momentum_matrices(q)
        np.testing.assert_allclose(momentum["H_b"], ref.H_b, rtol=0, atol=1e-11 * np.abs(ref.H_b).max())
        np.testing.assert_allclose(momentum["H_bm"], ref.H_bm, rtol=0, atol=1e-11 * np.abs(ref.H_bm).max())
        np.testing.assert_allclose(momentum["rg"], reference.system_com(q), rtol=0, atol=1e-13)


def test_the_base_velocity_solves_the_momentum_balance(models):
    """Against numpy's dense solve of H_b v = [P; L about the base CoM] − H_bm Θ̇ (world frame), turned into the base
    frame; and the numba kernel's bits."""
    _, mdl, robot = models
    ws, rng = physics.workspace(len(mdl.cap_radius)), np.random.default_rng(12)
    for x in random_states(rng, 20):
        dq, h = rng.normal(size=12), rng.normal(size=6)
        v = _native.base_velocity(robot, x, dq, h)
        m, R = _native.momentum(robot, x), _native.kinematics(robot, x)["R_b"]
        d = m["rg"] - x[:3]
        rhs = np.concatenate((h[:3], h[3:] + np.cross(d, h[:3]))) - m["H_bm"][0] @ dq[:6] - m["H_bm"][1] @ dq[6:]
        world = np.linalg.solve(m["H_b"], rhs)
        np.testing.assert_allclose(v, np.concatenate((R.T @ world[:3], R.T @ world[3:])), rtol=0,
                                   atol=1e-12 * max(1.0, np.abs(world).max()))
        physics.kinematics_into(mdl, x, ws)
        physics.momentum_into(mdl, x, ws)
        expected = np.empty(6)
        physics.velocity_into(expected, x, dq, h, ws)
        assert np.array_equal(v, expected)


def test_a_midpoint_step_is_the_numba_kernels_to_the_bit(models):
    """Small and large joint increments (the series and the cosine branch of the kept angles), small and large base
    rotations (the series and the closed form of the SE(3) exponential)."""
    _, mdl, robot = models
    ws, rng = physics.workspace(len(mdl.cap_radius)), np.random.default_rng(13)
    for k, x in enumerate(random_states(rng, 16)):
        dq, h = rng.normal(scale=0.5 if k % 2 else 40.0, size=12), rng.normal(size=6)
        v0 = rng.normal(scale=1e-7 if k % 4 < 2 else 1.0, size=6)
        dt = 0.01
        out = _native.midpoint_step(robot, x, v0, dq, dt, h)
        physics.kinematics_into(mdl, x, ws)
        expected = np.empty(19)
        physics.midpoint_into(expected, mdl, x, v0, dq, dt, h, ws)
        assert np.array_equal(out, expected), k
        assert abs(np.linalg.norm(out[3:7]) - 1.0) < 1e-15


@pytest.mark.parametrize("condition", [1.0, 1e3, 1e8])
def test_the_jacobi_svd_and_sigma_min_match_lapack_and_the_numba_kernel(condition):
    rng = np.random.default_rng(14)
    for _ in range(20):
        U, _, Vt = np.linalg.svd(rng.normal(size=(6, 6)))
        A = U @ np.diag(np.geomspace(1.0, 1.0 / condition, 6)) @ Vt
        Ut, s, Vt_native = _native.svd6(A)
        np.testing.assert_allclose(np.sort(s), np.sort(np.linalg.svd(A, compute_uv=False)), rtol=1e-12 * condition)
        np.testing.assert_allclose(Ut.T @ np.diag(s) @ Vt_native, A, rtol=0, atol=1e-14 * np.abs(A).max())
        Ut_n, s_n, Vt_n = np.empty((6, 6)), np.empty(6), np.empty((6, 6))
        svd_into(A, Ut_n, s_n, Vt_n)
        assert np.array_equal(s, s_n) and np.array_equal(Ut, Ut_n) and np.array_equal(Vt_native, Vt_n)
        fast = _native.smallest_singular_value(A)
        G, tri = np.empty((6, 6)), np.empty((2, 6))
        assert fast == smallest_singular_value(A, G, tri)
        if condition <= 1e3:
            assert fast == pytest.approx(np.linalg.svd(A, compute_uv=False).min(), rel=1e-9)
        B = rng.normal(size=(6, 6))
        assert _native.smallest_singular_values(A, B) == smallest_singular_values(
            A, B, np.empty((6, 6)), np.empty((6, 6)), np.empty((2, 6)), np.empty((2, 6)))


def test_a_singular_matrix_is_declined_by_the_fast_path():
    A = np.zeros((6, 6))
    A[:5, :5] = np.eye(5)
    assert _native.smallest_singular_value(A) == -1.0
    assert np.sort(_native.svd6(A)[1])[0] == 0.0


def test_a_wrong_array_is_refused_naming_its_field(models):
    _, mdl, _ = models
    arrays = robot_arrays(mdl)
    with pytest.raises(ValueError, match=r"mass: shape \(12,\); allowed: \(13,\)"):
        _native.Robot.from_arrays(**(arrays | {"mass": arrays["mass"][:12]}))
    with pytest.raises(ValueError, match=r"parent\[3\] = 7"):
        bad = arrays["parent"].copy()
        bad[3] = 7
        _native.Robot.from_arrays(**(arrays | {"parent": bad}))
    with pytest.raises(ValueError, match="mass"):
        _native.Robot.from_arrays(**(arrays | {"mass": np.zeros(13)}))
    with pytest.raises(ValueError, match=r"x: shape \(18,\); allowed: \(19,\)"):
        _native.kinematics(native_robot(mdl), np.zeros(18))
    assert native_robot(mdl).total_mass == pytest.approx(float(np.sum(mdl.mass)))
