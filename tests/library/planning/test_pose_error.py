"""Attitude-error Jacobians and the desired path against finite differences."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ffsr_gym.model import quaternion as quat
from ffsr_gym.planning.desired_path import DesiredPath, trapezoid
from ffsr_gym.planning.pose_error import attitude_error


def _random_quaternion(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def _rotate(sigma, omega_world, h):
    """σ after rotating for h seconds at world angular velocity ω."""
    return quat.from_rotation(pin.exp3(omega_world * h) @ quat.to_rotation(sigma))


@pytest.mark.parametrize("variant", ["world", "body"])
def test_attitude_error_rate_matches_finite_difference(variant):
    rng = np.random.default_rng(0)
    h = 1e-6
    for _ in range(20):
        sigma, sigma_d = _random_quaternion(rng), _random_quaternion(rng)
        if sigma @ sigma_d < 0.2:
            continue
        omega, omega_d = rng.normal(size=3), rng.normal(size=3)
        err = attitude_error(sigma, sigma_d, variant)
        plus = attitude_error(_rotate(sigma, omega, h), _rotate(sigma_d, omega_d, h), variant).e_o
        minus = attitude_error(_rotate(sigma, omega, -h), _rotate(sigma_d, omega_d, -h), variant).e_o
        rate_fd = (plus - minus) / (2 * h)
        assert np.allclose(err.J_o @ omega - err.J_od @ omega_d, rate_fd, atol=1e-8)
        assert np.linalg.det(err.J_o) == pytest.approx(err.delta_eta / 8, rel=1e-10)


def test_attitude_error_is_sign_invariant_and_zero_at_target():
    rng = np.random.default_rng(1)
    sigma = _random_quaternion(rng)
    assert np.allclose(attitude_error(sigma, sigma).e_o, 0)
    other = _random_quaternion(rng)
    assert np.allclose(attitude_error(-sigma, other).e_o, attitude_error(sigma, other).e_o)


def test_trapezoid_profile_rate_and_end_points():
    t_f, t_a = 10.0, 2.5
    ts = np.linspace(0, 12, 1201)
    s = np.array([trapezoid(t, t_f, t_a)[0] for t in ts])
    s_dot = np.array([trapezoid(t, t_f, t_a)[1] for t in ts])
    assert s[0] == 0 and s[-1] == 1 and np.all(np.diff(s) >= 0)
    assert np.allclose(np.gradient(s, ts)[1:-1], s_dot[1:-1], atol=2e-3)
    assert s_dot.max() == pytest.approx(1 / (t_f - t_a))
    assert trapezoid(5.0, t_f, t_a)[0] == pytest.approx(0.5)  # symmetric profile


def test_desired_twist_matches_finite_difference_of_the_path():
    rng = np.random.default_rng(2)
    target = _random_quaternion(rng)
    path = DesiredPath.between(rng.normal(size=3), _random_quaternion(rng), rng.normal(size=3),
                               target, motion_time=10.0, accel_time=2.5)
    h = 1e-6
    for t in (1.0, 4.0, 8.7):
        p_plus, s_plus, _ = path.at(t + h)
        p_minus, s_minus, _ = path.at(t - h)
        _, _, twist = path.at(t)
        assert np.allclose((p_plus - p_minus) / (2 * h), twist[:3], atol=1e-7)
        omega_fd = pin.log3(quat.to_rotation(s_plus) @ quat.to_rotation(s_minus).T) / (2 * h)
        assert np.allclose(omega_fd, twist[3:], atol=1e-7)
    end_position, end_attitude, end_twist = path.at(11.0)
    assert np.allclose(end_position, path.target_position)
    assert np.allclose(end_twist, 0)
    assert abs(end_attitude @ target) == pytest.approx(1.0, abs=1e-12)
