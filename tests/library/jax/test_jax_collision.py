"""The JAX collision distances (``ffsr_gym.jax.collision``) against coal through the collision model
(``ffsr_gym.model.collision``), which shares no code with them, where the parts are apart: robot–sphere clearance
and its witness vector, arm–arm and arm–base clearance, at random states that bring the arms close to each other
and to the base. Where parts overlap, coal's penetration depth is not the kernel's signed distance (the kernel's is
the deepest point's, docs/model.md §12), so there they are checked against the kernel's."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jax")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

from ffsr_gym.jax import collision, physics  # noqa: E402
from ffsr_gym.model.collision import SphereObstacle  # noqa: E402
from ffsr_gym.model.quaternion import wxyz_from_xyzw  # noqa: E402
from ffsr_gym.sim.setup import robot_assets  # noqa: E402

ASSETS = robot_assets("ffsr_dual_arm")
MODEL, SHAPES = physics.model_of(ASSETS.kernel), collision.shapes_of(ASSETS.kernel)


@jax.jit
def _clearances(x, p_o, r_o):
    kin = physics.kinematics(MODEL, x)
    A, B = collision.capsule_ends(SHAPES, kin, x)
    clear, rel = collision.obstacle_clearance(SHAPES, kin.R_b, x[:3], A, B, p_o, r_o)
    return clear, rel, collision.self_clearance(SHAPES, kin.R_b, x[:3], A, B)


def _q(x):
    robot = ASSETS.robot
    return robot.configuration(base_position_m=x[:3], base_quaternion_wxyz=wxyz_from_xyzw(x[3:7]), joints_rad=x[7:])


def _kernel(x, p_o, r_o):
    from ffsr_gym import _native

    settings = _native.PlannerSettings()
    settings.set_obstacles(p_o.reshape(1, 3), np.zeros((1, 3)), np.array([r_o]))
    clear, self_c, rel = _native.clearances(ASSETS.native, settings, x, 0.0)
    return clear, rel, self_c


def test_clearances_match_coal_and_the_kernel():
    rng = np.random.default_rng(11)
    self_values, penetrating = [], 0
    for _ in range(40):
        quat = rng.normal(size=4)
        x = np.concatenate((rng.uniform(-0.3, 0.3, 3), quat / np.linalg.norm(quat), rng.uniform(-2.5, 2.5, 12)))
        p_o, r_o = x[:3] + rng.uniform(-1.2, 1.2, 3), float(rng.choice([0.0, 0.05]))
        clear, rel, self_c = _clearances(jnp.asarray(x), jnp.asarray(p_o), r_o)
        q = _q(x)
        kernel_clear, kernel_rel, kernel_self = _kernel(x, p_o, r_o)
        assert float(clear) == pytest.approx(kernel_clear, abs=1e-12)
        np.testing.assert_allclose(rel, kernel_rel, atol=1e-12)
        assert float(self_c) == pytest.approx(kernel_self, abs=1e-12)
        ref = ASSETS.collision.obstacle_proximity(q, [SphereObstacle(p_o, r_o)])
        if ref.distance_m > 1e-3:  # apart: coal's distance and witness points
            assert float(clear) == pytest.approx(ref.distance_m, abs=1e-9)
            np.testing.assert_allclose(rel, ref.witness_points[1] - ref.witness_points[0], atol=1e-8)
        own = ASSETS.collision.self_proximity(q)
        if own.distance_m > 0.0:
            assert float(self_c) == pytest.approx(own.distance_m, abs=1e-9)
        self_values.append(own.distance_m)
        penetrating += own.distance_m < 0.0
    assert min(self_values) < 0.02 and penetrating > 0  # close and touching pairs were compared, not only far ones


def test_segment_box_matches_dense_sampling():
    rng = np.random.default_rng(12)
    half = jnp.array([0.3, 0.2, 0.25])
    for _ in range(50):
        a, b = rng.uniform(-0.6, 0.6, 3), rng.uniform(-0.6, 0.6, 3)
        ts = np.linspace(0.0, 1.0, 20001)
        sampled = collision.box_sdf_local(jnp.asarray(a[None] + ts[:, None] * (b - a)[None]), half).min()
        exact = collision.segment_box(jnp.asarray(a), jnp.asarray(b), jnp.eye(3), jnp.zeros(3), half)
        assert float(exact) <= float(sampled) + 1e-12
        assert float(exact) == pytest.approx(float(sampled), abs=2e-5)
