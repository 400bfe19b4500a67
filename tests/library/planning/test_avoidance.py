"""Danger field against quadrature, its gradient against finite differences, and the inverse."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from ffsr_gym.planning.avoidance import blend_factor, danger_field, danger_field_gradient
from ffsr_gym.planning.inverse import filtered_inverse


def _quad_field(points, p_o):
    total = 0.0
    for a, b in zip(points[:-1], points[1:]):
        if np.linalg.norm(b - a) < 1e-12:
            continue
        total += quad(lambda s, a=a, b=b: 1.0 / np.linalg.norm(p_o - (a + s * (b - a))), 0, 1, epsabs=1e-13, epsrel=1e-12,
                      limit=200)[0]
    return total


def test_single_segment_calibration_from_spec():
    """docs/model.md §6: one 0.5 m segment, point 0.2 m from its middle: CDF = 4.19; 0.1 m: 6.59; 0.05 m: 9.25."""
    points = np.array([[0.0, 0, 0], [0.5, 0, 0]])
    for d, expected in ((0.2, 4.19), (0.1, 6.59), (0.05, 9.25)):
        cdf, distance = danger_field(points, np.array([0.25, d, 0.0]))
        assert cdf == pytest.approx(expected, abs=0.01)
        assert distance == pytest.approx(d)


def test_field_matches_quadrature_including_points_on_the_extension(robot, q_paper):
    robot.update_kinematics(q_paper)
    points, _ = robot.joint_points(0)
    rng = np.random.default_rng(0)
    probes = [points.mean(axis=0) + rng.normal(scale=0.3, size=3) for _ in range(20)]
    a, b = points[1], points[2]
    probes += [b + 0.3 * (b - a), a - 1e-3 * (b - a) + 1e-9]  # beyond the ends, almost on the line
    for p_o in probes:
        cdf, distance = danger_field(points, p_o)
        assert cdf == pytest.approx(_quad_field(points, p_o), rel=1e-8)
        segs = [(p, q) for p, q in zip(points[:-1], points[1:]) if np.linalg.norm(q - p) > 0]
        closest = min(np.linalg.norm(p_o - (p + np.clip((p_o - p) @ (q - p) / ((q - p) @ (q - p)), 0, 1) * (q - p)))
                      for p, q in segs)
        assert distance == pytest.approx(closest, abs=1e-12)


def test_gradient_matches_finite_difference_through_forward_kinematics(robot, q_paper):
    rng = np.random.default_rng(1)
    h = 1e-6
    for _ in range(5):
        q = q_paper.copy()
        q[robot.joint_q_index] += rng.normal(scale=0.3, size=12)
        robot.update_kinematics(q)
        points, axes = robot.joint_points(0)
        p_o = points[3] + rng.normal(scale=0.15, size=3)
        grad = danger_field_gradient(points, axes, p_o)
        fd = np.zeros(6)
        for k in range(6):
            dq = np.zeros_like(q)
            dq[robot.arm_q_index[0, k]] = h
            values = []
            for sign in (1, -1):
                robot.update_kinematics(q + sign * dq)
                values.append(danger_field(robot.joint_points(0)[0], p_o)[0])
            fd[k] = (values[0] - values[1]) / (2 * h)
        assert np.allclose(grad, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_blend_factor_laws():
    assert blend_factor(10.0, 0.3, law="cdf", delta=17.25, danger_radius=0.2) == 1.0
    assert blend_factor(34.5, 0.3, law="cdf", delta=17.25, danger_radius=0.2) == pytest.approx(0.5)
    assert blend_factor(0.0, 0.1, law="distance", delta=17.25, danger_radius=0.2) == pytest.approx(0.25)


def test_filtered_inverse_is_the_inverse_when_well_conditioned():
    rng = np.random.default_rng(2)
    J = rng.normal(size=(6, 6))
    J_sharp, P, smin = filtered_inverse(J, lambda_max=0.08, epsilon=0.02)
    assert smin > 0.02
    assert np.allclose(J_sharp, np.linalg.inv(J), atol=1e-10)
    assert np.allclose(P, np.eye(6), atol=1e-10)


def test_filtered_inverse_damps_small_singular_values_continuously():
    U, _ = np.linalg.qr(np.random.default_rng(3).normal(size=(6, 6)))
    V, _ = np.linalg.qr(np.random.default_rng(4).normal(size=(6, 6)))
    gains = []
    for sigma in (0.0, 0.01, 0.02 - 1e-9, 0.02 + 1e-9):
        J = U @ np.diag([2, 1.5, 1, 0.5, 0.3, sigma]) @ V.T
        J_sharp, P, _ = filtered_inverse(J, lambda_max=0.08, epsilon=0.02)
        gains.append(V[:, 5] @ J_sharp @ U[:, 5])
    lam2 = 0.08**2 * (1 - 0.25)
    assert abs(gains[0]) < 1e-12  # an exactly singular direction gets no motion
    assert gains[1] == pytest.approx(0.01 / (0.01**2 + lam2))
    assert gains[2] == pytest.approx(gains[3], rel=1e-5)  # continuous at sigma = epsilon
