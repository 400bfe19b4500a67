"""The JAX physics (``ffsr_gym.jax.physics``) against Pinocchio, which shares no code with it: frames, momentum
matrices, the momentum-conserving base velocity and the midpoint step at random states; its gradients against
central finite differences; and the total momentum along its own rollouts."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jax")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
from conftest import random_states  # noqa: E402

from ffsr_gym.jax import physics  # noqa: E402
from ffsr_gym.model.quaternion import wxyz_from_xyzw  # noqa: E402
from ffsr_gym.sim.setup import robot_assets  # noqa: E402

ASSETS = robot_assets("ffsr_dual_arm")
MODEL = physics.model_of(ASSETS.kernel)
ROBOT = ASSETS.robot


def _q(x):
    return ROBOT.configuration(base_position_m=x[:3], base_quaternion_wxyz=wxyz_from_xyzw(x[3:7]), joints_rad=x[7:])


def _x(q):
    return np.concatenate((q[:7], ROBOT.joint_angles(q)))


def test_frames_match_pinocchio():
    for x in random_states(np.random.default_rng(1), 10):
        kin = physics.kinematics(MODEL, jnp.asarray(x))
        q = _q(x)
        ROBOT.update_kinematics(q)
        for arm in range(2):
            points, axes = ROBOT.joint_points(arm)
            np.testing.assert_allclose(kin.pj[6 * arm:6 * arm + 6], points[:6], rtol=0, atol=1e-13)
            np.testing.assert_allclose(kin.pe[arm], points[6], rtol=0, atol=1e-13)
            np.testing.assert_allclose(kin.z[6 * arm:6 * arm + 6], axes, rtol=0, atol=1e-13)
            np.testing.assert_allclose(kin.Re[arm], ROBOT.transform_ee_to_world(q, arm).rotation, rtol=0, atol=1e-13)


def test_momentum_and_base_velocity_match_pinocchio():
    rng = np.random.default_rng(2)
    for x in random_states(rng, 10):
        xj, q = jnp.asarray(x), _q(x)
        kin = physics.kinematics(MODEL, xj)
        mom = physics.momentum(MODEL, xj, kin)
        ref = ROBOT.momentum_matrices(q)
        np.testing.assert_allclose(mom.H_b, ref.H_b, rtol=0, atol=1e-11 * np.abs(ref.H_b).max())
        np.testing.assert_allclose(mom.H_bm, ref.H_bm, rtol=0, atol=1e-11 * np.abs(ref.H_bm).max())
        np.testing.assert_allclose(mom.com, ROBOT.system_com(q), rtol=0, atol=1e-13)
        dq, h = rng.normal(size=12), rng.normal(size=6)
        v = physics.base_velocity(xj, jnp.asarray(dq), jnp.asarray(h), kin, mom)
        np.testing.assert_allclose(v, ROBOT.velocity(q, dq, h)[:6], rtol=0, atol=1e-10)


def test_the_midpoint_step_matches_pinocchio():
    rng = np.random.default_rng(3)
    step = jax.jit(physics.midpoint, static_argnums=4)
    for x in random_states(rng, 5):
        dq = rng.normal(scale=0.5, size=12)
        x1, v_mid = step(MODEL, jnp.asarray(x), jnp.asarray(dq), jnp.zeros(6), 0.01)
        q1, v_ref = ROBOT.step(_q(x), dq, 0.01)
        np.testing.assert_allclose(x1, _x(q1), rtol=0, atol=1e-13)
        np.testing.assert_allclose(v_mid, v_ref[:6], rtol=0, atol=1e-11)


def _com_drift(x0, dt, seconds=5.0):
    """The largest distance [m] of Pinocchio's system CoM from its start along a JAX rollout at smooth joint rates,
    and the largest quaternion norm error."""
    steps = int(round(seconds / dt))
    t = jnp.arange(steps) * dt
    rates = 0.4 * jnp.sin(t[:, None] * jnp.linspace(0.5, 1.7, 12)[None, :] + jnp.arange(12)[None, :])

    def one(x, dq):
        x1 = physics.midpoint(MODEL, x, dq, jnp.zeros(6), dt)[0]
        return x1, x1

    _, xs = jax.lax.scan(one, x0, rates)
    start = ROBOT.system_com(_q(np.asarray(x0)))
    drift = max(np.linalg.norm(ROBOT.system_com(_q(np.asarray(x))) - start) for x in xs[::max(1, steps // 50)])
    return drift, float(np.abs(np.linalg.norm(xs[:, 3:7], axis=1) - 1.0).max())


def test_a_rollout_keeps_the_centre_of_mass_and_a_unit_quaternion():
    """Zero linear momentum keeps the system CoM still: along 5 s of the JAX physics, Pinocchio's CoM moves by the
    midpoint rule's error only, which shrinks as dt² (second order)."""
    x0 = jnp.asarray(random_states(np.random.default_rng(4), 1)[0])
    coarse, norm_error = _com_drift(x0, 0.02)
    fine, _ = _com_drift(x0, 0.01)
    assert fine < 1e-5 and norm_error < 1e-14
    assert 3.0 < coarse / fine < 5.0, (coarse, fine)


def test_gradients_of_the_step_match_finite_differences():
    """d(x_next)/d(dq) by reverse mode against central differences of the step itself."""
    rng = np.random.default_rng(5)
    x, dq = jnp.asarray(random_states(rng, 1)[0]), jnp.asarray(rng.normal(scale=0.5, size=12))
    weights = jnp.asarray(rng.normal(size=19))

    def f(rates):
        return jnp.dot(weights, physics.midpoint(MODEL, x, rates, jnp.zeros(6), 0.05)[0])

    grad = np.asarray(jax.grad(f)(dq))
    eps, fd = 1e-6, np.empty(12)
    for j in range(12):
        e = jnp.zeros(12).at[j].set(eps)
        fd[j] = (f(dq + e) - f(dq - e)) / (2 * eps)
    np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-9)
