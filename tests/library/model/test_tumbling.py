"""A tumbling target's torque-free motion against independent quantities: conservation laws over a 60 s tumble at
the benchmark's step, the closed-form precession of an axisymmetric body, and the flip about the intermediate axis
against its elliptic-function period (Landau & Lifshitz, Mechanics §37)."""

from __future__ import annotations

import numpy as np
import pytest

from ffsr_gym.model.quaternion import from_axis_angle, to_rotation
from ffsr_gym.model.tumbling import (
    angular_momentum_world,
    kinetic_energy,
    point_motion,
    propagate,
    rotations,
)

DT_S, SECONDS = 0.01, 60.0
STEPS = int(round(SECONDS / DT_S))


def _tumble(inertia, omega, quaternion=(1.0, 0.0, 0.0, 0.0), steps=STEPS, velocity=(0.0, 0.0, 0.0)):
    return propagate(position_m=np.array([1.0, -0.5, 0.2]), velocity_m_s=np.array(velocity),
                     quaternion=np.array(quaternion), omega_body_rad_s=np.array(omega),
                     inertia_kg_m2=np.array(inertia), dt_s=DT_S, steps=steps)


def test_an_asymmetric_tumble_keeps_momentum_energy_and_a_unit_quaternion():
    inertia = [120.0, 180.0, 250.0]
    start = from_axis_angle(np.array([1.0, 2.0, -1.0]) / np.sqrt(6.0), 0.7)
    motion = _tumble(inertia, [0.3, -0.2, 0.5], quaternion=start)
    momentum = angular_momentum_world(motion, inertia)
    energy = kinetic_energy(motion, inertia)
    assert np.abs(momentum - momentum[0]).max() / np.linalg.norm(momentum[0]) < 1e-11
    assert np.abs(energy - energy[0]).max() / energy[0] < 1e-11
    assert np.abs(np.linalg.norm(motion.quaternion, axis=1) - 1.0).max() < 1e-14
    assert np.ptp(motion.omega_body_rad_s, axis=0).min() > 0.04  # it does tumble: every body rate moves


def test_an_axisymmetric_body_precesses_at_the_closed_form_rates():
    it, i3, w_perp, w3 = 200.0, 320.0, 0.2, 0.6
    motion = _tumble([it, it, i3], [w_perp, 0.0, w3])
    # body frame: the rate vector turns about the symmetry axis at (I3 - It) / It * w3
    body_rate = (i3 - it) / it * w3
    t = motion.time_s
    expected = np.column_stack([w_perp * np.cos(body_rate * t), w_perp * np.sin(body_rate * t), np.full_like(t, w3)])
    assert np.abs(motion.omega_body_rad_s - expected).max() < 1e-10
    # world frame: the symmetry axis turns about the fixed angular momentum at |L| / It
    momentum = it * w_perp * np.array([1.0, 0.0, 0.0]) + i3 * w3 * np.array([0.0, 0.0, 1.0])
    axis = rotations(motion.quaternion)[:, :, 2]
    world_rate = np.linalg.norm(momentum) / it
    about = momentum / np.linalg.norm(momentum)
    turned = np.stack([to_rotation(from_axis_angle(about, world_rate * s))[:, 2] for s in t])
    assert np.abs(axis - turned).max() < 1e-9


def test_a_spin_about_the_intermediate_axis_flips_with_the_elliptic_period():
    from scipy.special import ellipk

    inertia = np.array([100.0, 200.0, 300.0])
    omega = np.array([0.01, 0.5, 0.01])
    motion = _tumble(inertia, omega)
    two_energy, momentum_sq = np.sum(inertia * omega ** 2), np.sum(inertia ** 2 * omega ** 2)
    assert momentum_sq > two_energy * inertia[1]  # the branch where w2 ~ sn: it changes sign, w3 ~ dn does not
    rate = np.sqrt((inertia[2] - inertia[1]) * (momentum_sq - two_energy * inertia[0]) / np.prod(inertia))
    modulus = ((inertia[1] - inertia[0]) * (two_energy * inertia[2] - momentum_sq)
               / ((inertia[2] - inertia[1]) * (momentum_sq - two_energy * inertia[0])))
    half_period = 2.0 * ellipk(modulus) / rate
    w2, t = motion.omega_body_rad_s[:, 1], motion.time_s
    at = np.flatnonzero(np.sign(w2[:-1]) != np.sign(w2[1:]))
    crossings = t[at] - w2[at] * DT_S / (w2[at + 1] - w2[at])
    assert len(crossings) >= 2 and np.all(motion.omega_body_rad_s[:, 2] > 0)
    assert np.diff(crossings) == pytest.approx(half_period, rel=1e-6)


def test_a_point_on_the_body_moves_as_its_finite_differences_say():
    motion = _tumble([120.0, 180.0, 250.0], [0.3, -0.2, 0.5], steps=400, velocity=(0.01, -0.02, 0.005))
    position, velocity = point_motion(motion, np.array([0.4, 0.1, -0.3]))
    central = (position[2:] - position[:-2]) / (2 * DT_S)
    assert np.abs(central - velocity[1:-1]).max() < 1e-5  # central differences: O(dt²) of the acceleration
    assert np.allclose(np.linalg.norm(position - motion.position_m, axis=1), np.linalg.norm([0.4, 0.1, -0.3]))


def test_the_kernels_propagation_is_the_models():
    from ffsr_gym import _native

    inertia, omega = np.array([120.0, 180.0, 250.0]), np.array([0.3, -0.2, 0.5])
    start = from_axis_angle(np.array([1.0, 2.0, -1.0]) / np.sqrt(6.0), 0.7)
    motion = _tumble(inertia, omega, quaternion=start, steps=2000)
    out_q, out_w = _native.propagate_tumbling(start, omega, inertia, DT_S, 4, 2000)
    assert np.abs(out_q - motion.quaternion).max() < 1e-13 and np.abs(out_w - motion.omega_body_rad_s).max() < 1e-13


def test_the_written_out_integrator_is_numpys_rk4_to_the_bit():
    """The draws of the capture pools depend on the last bits of the body's motion: the written-out RK4 equals the
    same step assembled from the numpy rates (:func:`quaternion_rate`, :func:`euler_rates`), bit for bit."""
    from ffsr_gym.model import portable
    from ffsr_gym.model.tumbling import euler_rates, quaternion_rate, rk4_step

    rng = np.random.default_rng(17)
    for _ in range(200):
        q, w = rng.normal(size=4), rng.normal(size=3) * rng.choice([0.1, 1.0, 5.0])
        inertia, h = rng.uniform(0.5, 5.0, 3), float(rng.choice([0.0025, -0.0025, 0.01]))
        k1q, k1w = quaternion_rate(q, w), euler_rates(w, inertia)
        k2q, k2w = quaternion_rate(q + 0.5 * h * k1q, w + 0.5 * h * k1w), euler_rates(w + 0.5 * h * k1w, inertia)
        k3q, k3w = quaternion_rate(q + 0.5 * h * k2q, w + 0.5 * h * k2w), euler_rates(w + 0.5 * h * k2w, inertia)
        k4q, k4w = quaternion_rate(q + h * k3q, w + h * k3w), euler_rates(w + h * k3w, inertia)
        q_next = q + h / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q)
        w_next = w + h / 6.0 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w)
        got_q, got_w = rk4_step(q, w, inertia, h)
        assert np.array_equal(got_q, q_next / portable.norm(q_next)) and np.array_equal(got_w, w_next)
